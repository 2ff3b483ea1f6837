"""OpenDRIVE export: the written ``.xodr`` read back with lxml against the HD map it came from.

Two maps: a generated one (traffic lights) and a hand-made town with a dead end (U-turn
connector), a degree-2 node and bent roads. XSD and ASAM checks need their own venv and run in
``bench/check_opendrive.py`` (see docs/opendrive.md).
"""

from __future__ import annotations

import math
import re

import networkx as nx
import pytest
from lxml import etree
from scipy.integrate import quad

from roadweaver_sumo.expand import expand_skeleton
from roadweaver_sumo.export.map_files import write_map_files
from roadweaver_sumo.export.opendrive import CURVATURE_DECIMALS, _num, write_opendrive
from roadweaver_sumo.export.opendrive_geometry import DECIMALS
from roadweaver_sumo.hdmap import build_hdmap, lane_reachability
from roadweaver_sumo.metrics import road_node_count
from roadweaver_sumo.roadgraph import add_road, new_road_graph
from roadweaver_sumo.skeleton import make_skeleton
from roadweaver_sumo.spec import ScenarioSpec
from roadweaver_sumo.sumo_tools import binary, run
from roadweaver_sumo.validate.net_metrics import lane_reachability as net_lane_reachability
from roadweaver_sumo.validate.netgraph import lane_graph, load_net, road_graph
from roadweaver_sumo.validate.xodr_alignment import read_roads, reference_pose, xodr_alignment


def town() -> nx.Graph:
    """A T of arterials (traffic light), a bent collector with a degree-2 node where it turns
    local, a dead end, and a local loop back to the arterial."""
    xy = {0: (200, 200), 1: (40, 200), 2: (360, 210), 3: (220, 330), 4: (330, 390),
          5: (120, 60)}
    G = new_road_graph(400, 400)
    for n, p in xy.items():
        G.add_node(n, xy=(float(p[0]), float(p[1])))
    for u, v, road_class, *inner in [(1, 0, "arterial", (120, 195)), (0, 2, "arterial"),
                                     (0, 3, "collector", (240, 250), (235, 290)),
                                     (3, 4, "local", (280, 340)), (1, 5, "local", (60, 90)),
                                     (5, 0, "local", (180, 110))]:
        add_road(G, u, v, [xy[u], *inner, xy[v]], road_class)
    return G


def generated() -> nx.Graph:
    spec = ScenarioSpec(density=30, vehicles=1, width=600, height=600, style="organic", seed=0,
                        skeleton="procedural")
    return expand_skeleton(spec, make_skeleton(spec))


@pytest.fixture(scope="module", params=["generated", "town"])
def exported(request, tmp_path_factory):
    G = generated() if request.param == "generated" else town()
    hd = build_hdmap(G, (48.137, 11.575))
    path = write_map_files(hd, tmp_path_factory.mktemp(request.param))["opendrive"]
    return hd, path, etree.parse(str(path)).getroot()


def _roads(root) -> dict[str, etree._Element]:
    return {r.get("name"): r for r in root.iter("road")}


def _hd_lane(hd, road: etree._Element, xodr_lane: int) -> str:
    """HD map lane id of an OpenDRIVE lane of road ``r<id>`` or connecting road ``j<n>_<k>``:
    right lanes drive along the reference line (``f``), lane -1/1 is the innermost."""
    name = road.get("name")
    if name.startswith("j"):
        return name
    rid = int(name[1:])
    direction = "f" if xodr_lane < 0 else "b"
    index = len(hd.roads[rid].lanes(direction)) - abs(xodr_lane)
    return f"r{rid}_{direction}_{index}"


def _links(hd, root) -> set[tuple[str, str]]:
    """(lane, next lane) pairs the file states: junction laneLinks (incoming lane ->
    connector) and connecting-road lane successors (connector -> outgoing lane)."""
    by_id = {r.get("id"): r for r in root.iter("road")}
    found = set()
    for conn in root.iter("connection"):
        incoming, connecting = by_id[conn.get("incomingRoad")], by_id[conn.get("connectingRoad")]
        for link in conn.iter("laneLink"):
            found.add((_hd_lane(hd, incoming, int(link.get("from"))),
                       _hd_lane(hd, connecting, int(link.get("to")))))
    for road in by_id.values():
        succ = road.find("link/successor")
        if road.get("junction") == "-1" or succ is None:
            continue
        for lane in road.iterfind("lanes/laneSection/right/lane"):
            for s in lane.iterfind("link/successor"):
                found.add((road.get("name"), _hd_lane(hd, by_id[succ.get("elementId")],
                                                      int(s.get("id")))))
    return found


def test_every_road_and_connector_is_a_road(exported):
    hd, _, root = exported
    expected = {f"r{r}" for r in hd.roads} | {c.id for c in hd.connectors()}
    assert set(_roads(root)) == expected
    assert len(list(root.iter("road"))) == len(expected)


def test_junction_ids_are_apart_from_road_ids(exported):
    """CARLA tells a connecting road by looking its ``junction`` id up among road ids: a
    junction id that is also a road id leaves the lanes ending there without successors."""
    hd, _, root = exported
    junctions = {j.get("name"): j.get("id") for j in root.iter("junction")}
    assert set(junctions) == {f"n{j}" for j in hd.junctions}
    assert len(set(junctions.values())) == len(junctions)
    assert not {r.get("id") for r in root.iter("road")} & set(junctions.values())
    for road in root.iter("road"):
        if road.get("junction") != "-1":
            assert road.get("junction") == junctions[f"n{hd.lanes[road.get('name')].junction}"]
        for link in road.iterfind("link/*[@elementType='junction']"):
            assert link.get("elementId") in junctions.values()


def test_road_types_are_the_classic_set_with_the_class_as_user_data(exported):
    """opendrive2lanelet and other pre-1.7 readers know only the 1.4 road types."""
    hd, _, root = exported
    for road in root.iter("road"):
        (kind,) = road.iterfind("type")
        assert kind.get("type") == "town"
        name = road.get("name")
        road_class = (hd.lanes[name] if name.startswith("j") else hd.roads[int(name[1:])]).road_class
        assert kind.find("userData[@code='roadClass']").get("value") == road_class


def test_lane_links_are_exactly_the_lane_graph(exported):
    hd, path, root = exported
    expected = {(p, c.id) for c in hd.connectors() for p in c.predecessors}
    expected |= {(c.id, s) for c in hd.connectors() for s in c.successors}
    assert _links(hd, root) == expected
    root = etree.parse(str(path)).getroot()  # a fresh copy: the fixture's root is shared
    link = next(root.iter("laneLink"))  # a lost link must show
    link.getparent().remove(link)
    assert _links(hd, root) != expected


def test_connecting_roads_link_both_ways(exported):
    hd, _, root = exported
    by_id = {r.get("id"): r for r in root.iter("road")}
    for conn in root.iter("connection"):
        road = by_id[conn.get("connectingRoad")]
        lane = hd.lanes[road.get("name")]
        pred, succ = road.find("link/predecessor"), road.find("link/successor")
        assert by_id[pred.get("elementId")].get("name") == f"r{hd.lanes[lane.predecessors[0]].road}"
        assert by_id[succ.get("elementId")].get("name") == f"r{hd.lanes[lane.successors[0]].road}"
        assert pred.get("elementId") == conn.get("incomingRoad")
        (xodr_lane,) = road.iterfind("lanes/laneSection/right/lane")
        assert xodr_lane.find("link/predecessor") is not None
        assert xodr_lane.find("link/successor") is not None


def test_lane_widths_are_the_hdmap_widths(exported):
    hd, _, root = exported
    for road in _roads(root).values():
        length = float(road.get("length"))
        for lane in road.iterfind("lanes/laneSection/*/lane[@id!='0']"):
            (width,) = lane.iterfind("width")
            a, b = float(width.get("a")), float(width.get("b"))
            hd_lane = hd.lanes[_hd_lane(hd, road, int(lane.get("id")))]
            assert a == pytest.approx(hd_lane.width, abs=1e-9)
            assert a + b * length == pytest.approx(hd_lane.end_width, abs=1e-6)
            assert float(width.get("c")) == float(width.get("d")) == 0.0


def _speed(poly: etree._Element, p: float) -> float:
    du = [float(poly.get(f"{c}U")) for c in "bcd"]
    dv = [float(poly.get(f"{c}V")) for c in "bcd"]
    return math.hypot(du[0] + 2 * du[1] * p + 3 * du[2] * p * p,
                      dv[0] + 2 * dv[1] * p + 3 * dv[2] * p * p)


def test_geometry_lengths_are_true_lengths(exported):
    """paramPoly3 lengths match numerical integration; line and arc pieces chain without
    gaps; every road's plan view runs exactly from its HD map reference line's start to end."""
    hd, path, root = exported
    for poly in root.iter("paramPoly3"):
        length = float(poly.getparent().get("length"))
        assert quad(lambda p, e=poly: _speed(e, p), 0.0, 1.0, epsabs=1e-10)[0] == \
            pytest.approx(length, abs=1e-3)
    roads, _ = read_roads(path)
    for name, road in _roads(root).items():
        xr = roads[road.get("id")]
        assert xr.length == pytest.approx(sum(float(g.get("length")) for g in xr.geometries))
        for prev, nxt in zip(xr.geometries, xr.geometries[1:]):
            end = reference_pose(xr, float(nxt.get("s")) - 1e-12)
            assert math.dist(end[:2], (float(nxt.get("x")), float(nxt.get("y")))) < 1e-6
        line = hd.roads[int(name[1:])].reference[0] if name.startswith("r") \
            else hd.lanes[name].centre[[0, -1]]
        assert math.dist(reference_pose(xr, 0.0)[:2], line[0]) < 1e-6
        assert math.dist(reference_pose(xr, xr.length)[:2], line[-1]) < 1e-6


def test_linked_lane_ends_meet(exported):
    hd, path, _ = exported
    alignment = xodr_alignment(path)
    assert alignment["count"] == 2 * len(hd.connectors())  # in and out of every connector
    assert alignment["mean"] <= 0.01
    assert alignment["max"] <= 0.05


def test_alignment_sees_a_shifted_connecting_road(exported, tmp_path):
    _, path, _ = exported
    root = etree.parse(str(path)).getroot()  # a fresh copy: the fixture's root is shared
    geometry = next(r for r in root.iter("road") if r.get("junction") != "-1").find(
        "planView/geometry")
    geometry.set("x", str(float(geometry.get("x")) + 0.1))
    etree.ElementTree(root).write(str(tmp_path / "shifted.xodr"))
    assert xodr_alignment(tmp_path / "shifted.xodr")["max"] == pytest.approx(0.1, abs=1e-6)


def test_output_is_byte_identical(exported, tmp_path):
    hd, path, _ = exported
    again = write_opendrive(hd, tmp_path / "again.xodr")
    assert again.read_bytes() == path.read_bytes()


def test_header_and_traffic_lights(exported):
    hd, _, root = exported
    header = root.find("header")
    assert (header.get("revMajor"), header.get("revMinor")) == ("1", "7")
    assert "+proj=tmerc +lat_0=48.137 +lon_0=11.575" in header.findtext("geoReference")
    signals = {s.get("id"): s for s in root.iter("signal") if s.get("type") == "1000001"}
    lights = [j for j in hd.junctions.values() if j.type == "traffic_light"]
    assert lights, "the test maps have traffic lights"
    controllers = {c.get("id"): c for c in root.iterfind("controller")}
    assert set(controllers) == {str(j.id) for j in lights}
    assert len(signals) == sum(len(j.roads) for j in lights)  # one per arriving direction
    for junction in lights:
        controlled = [signals[c.get("signalId")] for c in controllers[str(junction.id)]]
        roads = {s.getparent().getparent().get("name") for s in controlled}
        assert roads == {f"r{r}" for r in junction.roads}


def test_netconvert_imports_the_same_network(exported, tmp_path):
    hd, path, _ = exported
    run([binary("netconvert"), "--opendrive-files", str(path), "-o", "net.xml"], cwd=tmp_path,
        what="netconvert")
    net = load_net(tmp_path / "net.xml")
    hd_nodes = sum(1 for j in hd.junctions.values() if len(j.roads) != 2)
    assert road_node_count(road_graph(net)) == hd_nodes
    assert net_lane_reachability(lane_graph(net)) == pytest.approx(lane_reachability(hd))


def test_numbers_are_written_with_fixed_decimals(exported):
    """Every number with a fraction has DECIMALS decimals (an arc's curvature
    CURVATURE_DECIMALS): the bytes do not depend on how a float happens to print."""
    _, _, root = exported
    numbers = [(element.tag, key, value) for element in root.iter()
               for key, value in element.attrib.items()
               if re.fullmatch(r"-?\d+\.\d+", value) and key != "version"]  # header's "1.0"
    assert len(numbers) > 1000
    for tag, key, value in numbers:
        decimals = CURVATURE_DECIMALS if key == "curvature" else DECIMALS
        assert len(value.split(".")[1]) == decimals, (tag, key, value)


def test_a_number_that_rounds_to_zero_is_written_without_a_sign():
    assert [_num(x) for x in (-0.0, -4e-10, 4e-10, -6e-10)] == [
        "0.000000000", "0.000000000", "0.000000000", "-0.000000001"]
    assert _num(-1e-16, CURVATURE_DECIMALS) == "0.000000000000000"
