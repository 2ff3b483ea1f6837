"""Where a road gains or loses lanes: left-turn bays on the approaches to traffic lights
(``hdmap.turn_bays``) and zipper merges (``hdmap.control``), in the HD map, in SUMO's net as
netconvert builds it, and in the report's rule coverage."""

from __future__ import annotations

import numpy as np
import pytest
import sumolib
from test_hdmap import _graph

from roadweaver_sumo.export.map_files import write_map_files
from roadweaver_sumo.hdmap import build_hdmap
from roadweaver_sumo.hdmap.turn_bays import BAY_LENGTH, TAPER_LENGTH
from roadweaver_sumo.metrics import road_node_count
from roadweaver_sumo.validate.rule_coverage import rule_coverage


def arterial_crossing():
    """Two arterials crossing at node 0 (a light): arms of 250 m to the north, south and west,
    and one of 120 m to the east, too short for a bay."""
    nodes = {0: (300, 300), 1: (300, 550), 2: (300, 50), 3: (50, 300), 4: (420, 300)}
    return _graph(nodes, [(0, k, "arterial") for k in (1, 2, 3, 4)], size=600.0)


@pytest.fixture(scope="module")
def hd():
    return build_hdmap(arterial_crossing(), (48.137, 11.575))


def _arriving(road, node) -> str:
    return "f" if road.to_node == node else "b"


def test_long_approaches_to_a_light_end_in_a_bay_whose_lane_alone_turns_left(hd):
    assert hd.junctions[0].type == "traffic_light"
    bays = [road for road in hd.roads.values() if road.bay]
    assert sorted(road.from_node if road.to_node == 0 else road.to_node for road in bays) \
        == [5, 6, 7]  # the taper nodes on the north, south and west arms; none to the east
    for road in bays:
        assert road.bay == _arriving(road, 0)
        arriving = road.lanes(road.bay)
        leaving = road.lanes("b" if road.bay == "f" else "f")
        assert len(arriving) == 3 and len(leaving) == 2
        turns = {lane: {hd.lanes[c].movement for c in hd.lanes[lane].successors}
                 for lane in arriving}
        assert turns[arriving[-1]] == {"left"}  # the bay, leftmost
        assert all("left" not in turns[lane] for lane in arriving[:-1])
        assert float(np.hypot(*np.subtract(hd.junctions[0].xy, _far_end(road)))) \
            == pytest.approx(BAY_LENGTH, abs=0.01)


def _far_end(road):
    return road.centreline[0] if road.to_node == 0 else road.centreline[-1]


def test_at_the_taper_the_bay_goes_on_from_the_leftmost_lane_and_the_others_move_aside(hd):
    for node in (5, 6, 7):
        junction = hd.junctions[node]
        assert junction.taper and len(junction.roads) == 2
        assert junction.radius == pytest.approx(TAPER_LENGTH / 2)
        into_bay = [hd.lanes[c] for c in junction.connectors
                    if hd.roads[hd.lanes[hd.lanes[c].successors[0]].road].bay]
        bay_road = hd.roads[hd.lanes[into_bay[0].successors[0]].road]
        width = bay_road.lane_width
        shifts = {hd.lanes[c.successors[0]].index: float(np.hypot(*(c.centre[-1] - c.centre[0])))
                  for c in into_bay}
        assert sorted(shifts) == [0, 1, 2]
        straight = np.hypot(TAPER_LENGTH, 0.0)
        assert shifts[2] == pytest.approx(straight, abs=0.05)  # the bay: straight on
        for index in (0, 1):  # the through lanes: one lane width to the right
            assert shifts[index] == pytest.approx(np.hypot(TAPER_LENGTH, width), abs=0.05)
        assert {hd.lanes[c.predecessors[0]].index for c in into_bay if
                hd.lanes[c.successors[0]].index == 2} == {1}  # from the leftmost lane


def test_bays_change_no_road_node_count_and_need_a_light(hd):
    G = arterial_crossing()
    assert road_node_count(hd.graph) == road_node_count(G) == 5
    assert hd.graph.number_of_nodes() == G.number_of_nodes() + 3
    plain = build_hdmap(G, (48.137, 11.575), traffic_lights=False)
    assert plain.graph is G and not any(road.bay for road in plain.roads.values())


def test_sumo_builds_the_bays_with_the_hd_maps_tapers_and_protected_lefts(hd, tmp_path):
    files = write_map_files(hd, tmp_path)
    net = sumolib.net.readNet(str(files["sumo"]), withInternal=True, withPrograms=True)
    coverage = rule_coverage(net)
    assert coverage["turn_bays"] == 3
    states = [phase.state for program in net.getTLS("n0").getPrograms().values()
              for phase in program.getPhases()]
    protected = {into.getID() for into, _, index in net.getTLS("n0").getConnections()
                 if any(state[index] == "G" for state in states)}
    for road in (r for r in hd.roads.values() if r.bay):  # netconvert's own left phase
        assert f"r{road.id}_{road.bay}_2" in protected
    assert coverage["protected_lefts"] >= 3
    for node in (5, 6, 7):
        internal = [net.getLane(c.getViaLaneID()) for edge in net.getNode(f"n{node}").getIncoming()
                    for conns in edge.getOutgoing().values() for c in conns if c.getViaLaneID()]
        assert len(internal) == 5  # 2 + 1 lanes into the bay road, 2 out of it
        assert all(lane.getLength() > 0.8 * TAPER_LENGTH for lane in internal)
    for road in (r for r in hd.roads.values() if r.bay):
        edge = net.getEdge(f"r{road.id}_{road.bay}")
        left = edge.getLanes()[-1]
        assert {c.getDirection() for c in left.getOutgoing()} == {"l"}


def test_a_road_that_loses_a_lane_at_a_two_arm_node_is_a_zipper_merge(tmp_path):
    """An arterial going on as a collector: its two lanes take turns into one (SUMO's zipper
    links, ``Z``, each yielding to the other), counted as a zipper junction."""
    G = _graph({0: (50, 300), 1: (300, 300), 2: (550, 300)},
               [(0, 1, "arterial"), (1, 2, "collector")], size=600.0)
    hd = build_hdmap(G, (48.137, 11.575))
    assert hd.junctions[1].type == "zipper"
    net = sumolib.net.readNet(str(write_map_files(hd, tmp_path)["sumo"]), withInternal=True)
    merging = [c for lane in net.getEdge("r0_f").getLanes() for c in lane.getOutgoing()]
    assert sorted((c.getFromLane().getIndex(), c.getToLane().getIndex(), c.getState())
                  for c in merging) == [(0, 0, "Z"), (1, 0, "Z")]
    assert {c.link_state for c in hd.connectors() if c.junction == 1} == {"Z", "M"}
    assert rule_coverage(net)["junction_controls"] == {"zipper": 1}
