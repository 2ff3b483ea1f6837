"""The written ``.xodr`` read by CARLA's map code (PyPI ``carla``, no server needed) and by
pyxodr: readers that share no code with the generator.

CARLA routes over ``Map.get_topology()``, a graph of lane starts, and lets a vehicle move on
with ``Waypoint.next()``; both must see the lane graph of the HD map. Skipped where the
wheels are not installed.
"""

from __future__ import annotations

import networkx as nx
import pytest
from lxml import etree
from test_opendrive import town

from roadweaver_sumo.expand import expand_skeleton
from roadweaver_sumo.export.map_files import write_map_files
from roadweaver_sumo.export.opendrive import connecting_road_ids, xodr_lane_id
from roadweaver_sumo.hdmap import build_hdmap, lane_reachability
from roadweaver_sumo.skeleton import make_skeleton
from roadweaver_sumo.spec import ScenarioSpec

carla = pytest.importorskip("carla")

END = 0.01  # m: how far inside a lane its end waypoint is taken


def _generated(style: str, skeleton: str, seed: int):
    spec = ScenarioSpec(density=30, vehicles=1, width=1000, height=1000, style=style, seed=seed,
                        skeleton=skeleton)
    return expand_skeleton(spec, make_skeleton(spec))


MAPS = {"town": town, "grid-learned": lambda: _generated("grid", "learned", 3),
        "organic-procedural": lambda: _generated("organic", "procedural", 4)}


@pytest.fixture(scope="module", params=sorted(MAPS))
def loaded(request, tmp_path_factory):
    """HD map, written file and CARLA map of each test map."""
    hd = build_hdmap(MAPS[request.param](), (48.137, 11.575))
    path = write_map_files(hd, tmp_path_factory.mktemp(request.param))["opendrive"]
    return hd, path, carla.Map(request.param, path.read_text())


def _xodr_lane(hd, lane_id: str, connecting: dict[str, int]) -> tuple[int, int]:
    """(road id, lane id) of an HD map lane in the written file."""
    lane = hd.lanes[lane_id]
    road = connecting[lane_id] if lane.kind == "connector" else lane.road
    return road, xodr_lane_id(hd, lane)


def test_every_lane_end_continues_where_the_lane_graph_goes(loaded):
    """At the end of every road lane, ``next()`` leads onto exactly the connecting roads of
    the lane's connectors."""
    hd, path, m = loaded
    connecting = connecting_road_ids(hd)
    lengths = {int(r.get("id")): float(r.get("length"))
               for r in etree.parse(str(path)).getroot().iter("road")}
    checked = 0
    for lane in hd.lanes.values():
        if lane.kind != "road" or not lane.successors:
            continue
        road, lane_id = _xodr_lane(hd, lane.id, connecting)
        s = lengths[road] - END if lane_id < 0 else END  # right lanes: along the reference line
        end = m.get_waypoint_xodr(road, lane_id, s)
        assert end is not None, lane.id
        assert not end.is_junction
        ahead = {(w.road_id, w.lane_id) for w in end.next(2 * END)}
        assert ahead == {_xodr_lane(hd, c, connecting) for c in lane.successors}, lane.id
        assert all(w.is_junction for w in end.next(2 * END))
        checked += 1
    assert checked == sum(1 for lane in hd.lanes.values() if lane.kind == "road")


def topology_graph(m) -> nx.DiGraph:
    """CARLA's topology as a graph over (road, section, lane), plus lane changes between
    neighbouring lanes of one road section that drive the same way (lane ids of one sign)."""
    graph = nx.DiGraph()
    key = lambda w: (w.road_id, w.section_id, w.lane_id)
    for a, b in m.get_topology():
        graph.add_edge(key(a), key(b))
    for road, section, lane in list(graph.nodes):
        beside = (road, section, lane + (1 if lane > 0 else -1))
        if beside in graph:
            graph.add_edge((road, section, lane), beside)
            graph.add_edge(beside, (road, section, lane))
    return graph


def test_topology_routes_through_every_junction(loaded):
    """CARLA's lane graph holds every HD map lane, each connecting road between the lanes it
    joins, and every lane reaches every other one as in the HD map."""
    hd, _, m = loaded
    graph = topology_graph(m)
    connecting = connecting_road_ids(hd)
    lanes = {}  # HD map lane -> (road, section, lane): one lane section per road
    for lane_id in hd.lanes:
        road, xodr_lane = _xodr_lane(hd, lane_id, connecting)
        lanes[lane_id] = (road, 0, xodr_lane)
    assert set(graph.nodes) == set(lanes.values())
    for connector in hd.connectors():
        for before in connector.predecessors:
            assert graph.has_edge(lanes[before], lanes[connector.id])
        for after in connector.successors:
            assert graph.has_edge(lanes[connector.id], lanes[after])
    assert lane_reachability(hd) == 1.0
    assert nx.is_strongly_connected(graph)


def test_a_junction_id_shared_with_a_road_id_is_noticed(loaded, tmp_path):
    """The checks above fail on a file whose junction ids are road ids (as CARLA reads it)."""
    _, path, _ = loaded
    root = etree.parse(str(path)).getroot()
    road_ids = sorted(int(r.get("id")) for r in root.iter("road"))
    renumber = {j.get("id"): str(road_ids[k]) for k, j in enumerate(root.iter("junction"))}
    for road in root.iter("road"):
        if road.get("junction") != "-1":
            road.set("junction", renumber[road.get("junction")])
        for link in road.iterfind("link/*[@elementType='junction']"):
            link.set("elementId", renumber[link.get("elementId")])
    for junction in root.iter("junction"):
        junction.set("id", renumber[junction.get("id")])
    broken = carla.Map("broken", etree.tostring(root).decode())
    assert not nx.is_strongly_connected(topology_graph(broken))


def test_pyxodr_reads_every_lane(loaded):
    """pyxodr samples every lane (its arcs fail on pieces much tighter than a lane)."""
    pyxodr = pytest.importorskip("pyxodr.road_objects.network")
    hd, path, _ = loaded
    network = pyxodr.RoadNetwork(str(path))
    lanes = 0
    for road in network.get_roads():
        for section in road.lane_sections:
            for lane in section.lanes:
                assert len(lane.centre_line) >= 2
                lanes += 1
    assert lanes == len(hd.lanes)
