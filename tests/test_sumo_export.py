"""Stage 4: SUMO plain XML export and netconvert, checked on the resulting ``.net.xml``."""

from __future__ import annotations

import hashlib
import shutil

import networkx as nx
import numpy as np
import pytest
from lxml import etree
from shapely.geometry import LineString, Point

from roadweaver_sumo.errors import RoadweaverError
from roadweaver_sumo.export import map_files
from roadweaver_sumo.export.netconvert import available_templates, run_netconvert
from roadweaver_sumo.export.sumo_plain import _num, _points, lane_connections, write_plain
from roadweaver_sumo.hdmap import build_hdmap
from roadweaver_sumo.roadgraph import add_road, new_road_graph

GEO_ORIGIN = (52.52, 13.405)


def town() -> nx.Graph:
    """A small town: a four-way arterial crossing (traffic light), a T-junction, a curved
    collector, a bent local loop, degree-2 nodes (class changes) and three dead ends."""
    xy = {0: (200, 200), 1: (60, 200), 2: (340, 200), 3: (220, 330), 4: (320, 380),
          5: (200, 70), 6: (60, 330), 7: (60, 70)}
    G = new_road_graph(400, 400)
    for n, p in xy.items():
        G.add_node(n, xy=(float(p[0]), float(p[1])))
    bend = [(240, 250), (235, 290)]
    loop = [(100, 40), (150, 45)]
    for u, v, road_class, *inner in [(1, 0, "arterial"), (0, 2, "arterial"),
                                     (0, 3, "collector", *bend), (3, 4, "local"),
                                     (0, 5, "local"), (1, 6, "collector"),
                                     (7, 1, "collector"), (7, 5, "local", *loop)]:
        add_road(G, u, v, [xy[u], *inner, xy[v]], road_class)
    return G


def _export(out, template="urban", **build):
    hd = build_hdmap(town(), GEO_ORIGIN, **build)
    write_plain(hd, out / "plain")
    return hd, run_netconvert(out, template)


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    out = tmp_path_factory.mktemp("urban")
    hd, net = _export(out)
    return hd, out, net


def _read_net(net):
    root = etree.parse(str(net)).getroot()
    shapes = {lane.get("id"): np.array([p.split(",") for p in lane.get("shape").split()],
                                       dtype=float) for lane in root.iter("lane")}
    return root, root.findall("connection"), shapes


def _external(connections) -> set:
    """(from, to, fromLane, toLane) of the connections between real edges."""
    return {(c.get("from"), c.get("to"), int(c.get("fromLane")), int(c.get("toLane")))
            for c in connections if not c.get("from").startswith(":")}


def test_net_has_exactly_the_hdmap_connections(built):
    hd, _, net = built
    _, connections, _ = _read_net(net)
    assert _external(connections) == set(lane_connections(hd))


def _gaps(connections, shapes) -> np.ndarray:
    """Distances lane end -> internal lane start -> ... -> internal end -> next lane start."""
    after = {(c.get("from"), c.get("fromLane")): c for c in connections}
    gaps = []
    for c in connections:
        if c.get("from").startswith(":"):
            continue
        end = shapes[f"{c.get('from')}_{c.get('fromLane')}"][-1]
        via = c.get("via")
        while via:
            gaps.append(np.linalg.norm(shapes[via][0] - end))
            end = shapes[via][-1]
            via = after[tuple(via.rsplit("_", 1))].get("via")
        gaps.append(np.linalg.norm(shapes[f"{c.get('to')}_{c.get('toLane')}"][0] - end))
    return np.array(gaps)


def test_net_lane_ends_meet_internal_lanes(built):
    _, _, net = built
    _, connections, shapes = _read_net(net)
    gaps = _gaps(connections, shapes)
    assert len(gaps) > len(_external(connections))  # every connection has an internal lane
    assert gaps.mean() <= 0.05
    assert gaps.max() <= 0.05


def test_sumo_lanes_are_the_hdmap_lanes(built):
    """Same ids, widths and places: the middle of each HD map lane lies on its SUMO lane."""
    hd, _, net = built
    _, _, shapes = _read_net(net)
    road_lanes = {k for k in shapes if not k.startswith(":")}
    assert road_lanes == {lane.id for lane in hd.road_lanes()}
    for lane in hd.road_lanes():
        middle = LineString(lane.centre).interpolate(0.5, normalized=True)
        assert LineString(shapes[lane.id]).distance(Point(middle)) < 0.05, lane.id


def test_traffic_lights_dead_ends_and_geo_origin(built):
    hd, _, net = built
    root, _, _ = _read_net(net)
    lights = sorted(f"n{j.id}" for j in hd.junctions.values() if j.type == "traffic_light")
    assert lights == ["n0"]
    assert sorted(t.get("id") for t in root.iter("tlLogic")) == lights
    assert sorted(t.get("type") for t in root.iter("tlLogic")) == ["static"]
    # Every yellow is followed by an all-red clearance phase (SUMO's stranded left-turner).
    states = [p.get("state") for p in root.find("tlLogic").iter("phase")]
    for state, following in zip(states, states[1:] + states[:1]):
        if "y" in state:
            assert set(following) == {"r"}, states
    location = root.find("location")
    assert "+lat_0=52.52 +lon_0=13.405" in location.get("projParameter")
    assert location.get("netOffset") == "0.00,0.00"


def test_net_is_byte_identical_across_runs(built, tmp_path):
    _, out, _ = built
    _export(tmp_path)
    for name in ("map.net.xml", "netconvert.netccfg", "plain/map.nod.xml",
                 "plain/map.edg.xml", "plain/map.con.xml"):
        assert (tmp_path / name).read_bytes() == (out / name).read_bytes(), name
    assert not (out / "map.net.xml").read_text().count("generated on")


def test_edge_without_lane_connections_gets_none_from_netconvert(tmp_path):
    """netconvert guesses connections for edges that have none in the connection file; the
    exporter declares such edges empty so the net keeps exactly the lane graph's topology."""
    hd = build_hdmap(town())
    for lane_id in hd.roads[0].lanes("f"):
        hd.lanes[lane_id].successors.clear()
    write_plain(hd, tmp_path / "plain")
    assert '<connection from="r0_f"/>' in (tmp_path / "plain/map.con.xml").read_text()
    _, connections, _ = _read_net(run_netconvert(tmp_path))
    assert _external(connections) == set(lane_connections(hd))
    assert not any(c[0] == "r0_f" for c in _external(connections))


def test_suburban_template_without_traffic_lights(tmp_path):
    hd, net = _export(tmp_path, "suburban", traffic_lights=False)
    root, connections, _ = _read_net(net)
    assert root.find("tlLogic") is None
    assert _external(connections) == set(lane_connections(hd))
    assert 'value="suburban' not in (tmp_path / "netconvert.netccfg").read_text()


def test_failed_netconvert_raises_one_line_error(built, tmp_path):
    _, out, _ = built
    shutil.copytree(out / "plain", tmp_path / "plain")
    edges = tmp_path / "plain/map.edg.xml"
    edges.write_text(edges.read_text().replace('to="n2"', 'to="n999"', 1))
    with pytest.raises(RoadweaverError, match=r"^netconvert failed: .*'n999' is not known") as err:
        run_netconvert(tmp_path)
    assert "\n" not in str(err.value)
    assert not (tmp_path / "map.net.xml").exists()


def test_bad_template_or_missing_input_raises(tmp_path):
    assert available_templates() == ["suburban", "urban"]
    with pytest.raises(RoadweaverError, match="does not exist"):
        run_netconvert(tmp_path)
    write_plain(build_hdmap(town()), tmp_path / "plain")
    with pytest.raises(RoadweaverError, match=r"unknown netconvert template 'rural'.*urban"):
        run_netconvert(tmp_path, "rural")


def test_no_lane_changes_inside_junctions(built):
    """Parallel connections share one multi-lane internal edge; cars must not change lanes on
    it (a car stuck in a junction would shift into crossing traffic), single lanes need no rule."""
    _, _, net = built
    root, _, _ = _read_net(net)
    internal = [e for e in root.iter("edge") if e.get("function") == "internal"]
    multi = [lane for e in internal if len(e.findall("lane")) > 1 for lane in e.iter("lane")]
    assert multi, "the town's arterial crossing has two-lane straight connections"
    for lane in multi:
        assert (lane.get("changeLeft"), lane.get("changeRight")) == ("emergency", "emergency")
    for e in internal:
        if len(e.findall("lane")) == 1:
            assert e.find("lane").get("changeLeft") is None

def _digests(folder):
    return {str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(folder.rglob("*")) if p.is_file()}


def test_the_map_files_are_written_into_a_new_folder(tmp_path):
    map_files.write_map_files(build_hdmap(town(), GEO_ORIGIN), tmp_path / "new" / "folder")
    assert sorted(_digests(tmp_path / "new" / "folder")) == [
        "lanelet2_map.osm", "map.net.xml", "map.xodr", "netconvert.netccfg",
        "plain/map.con.xml", "plain/map.edg.xml", "plain/map.nod.xml"]


def test_shapes_write_every_number_as_single_numbers_are_written():
    """Shapes are formatted a line at a time; each number must read as ``_num`` writes it,
    ``-0.00`` never (SUMO would read it fine, but the bytes of every net would change)."""
    edge = [0.0, -0.0, -0.005, 0.005, -0.004999, 0.125, -0.125, 2.675, -2.675, 1e-300,
            -1e-300, 0.995, 9999.995, -0.0051]
    rng = np.random.default_rng(0)
    lines = [np.array(np.meshgrid(edge, edge)).reshape(2, -1).T]
    lines += [rng.normal(0, scale, (20, 2)) for scale in (0.01, 1.0, 5000.0)]
    for line in lines:
        assert _points(line) == [f"{_num(x)},{_num(y)}" for x, y in line]
    assert "-0.00," not in " ".join(_points(lines[0])) and "0.00,0.00" in _points(lines[0])
