"""Roundabouts (``hdmap.roundabouts``): a one-way ring counter-clockwise in place of a junction
where collectors meet, entries yielding to it in SUMO's net, and the junction still counted
once in the map's density."""

from __future__ import annotations

import numpy as np
import sumolib
from test_hdmap import _graph

import roadweaver_sumo as rw
from roadweaver_sumo.export.map_files import write_map_files
from roadweaver_sumo.hdmap import build_hdmap
from roadweaver_sumo.hdmap.roundabouts import RING_RADIUS
from roadweaver_sumo.metrics import road_node_count, sharp_bends
from roadweaver_sumo.validate.netgraph import load_net, road_graph
from roadweaver_sumo.validate.rule_coverage import rule_coverage


def crossing(road_class: str = "collector"):
    """Four arms of 250 m meeting at node 0, in the middle of a 600 m map."""
    nodes = {0: (300, 300), 1: (300, 550), 2: (550, 300), 3: (300, 50), 4: (50, 300)}
    return _graph(nodes, [(0, k, road_class) for k in (1, 2, 3, 4)], size=600.0)


def test_a_collector_crossing_becomes_a_ring_that_runs_counter_clockwise(tmp_path):
    G = crossing()
    hd = build_hdmap(G, (48.137, 11.575), roundabouts=1)
    ring = sorted(n for n, j in hd.junctions.items() if j.roundabout == 0)
    assert len(ring) == 4 and 0 not in hd.junctions
    for node in ring:
        assert hd.junctions[node].type == "priority"
        assert abs(np.hypot(*np.subtract(hd.junctions[node].xy, (300, 300))) - RING_RADIUS) < 0.01
    ring_roads = [r for r in hd.roads.values() if {r.from_node, r.to_node} <= set(ring)]
    assert len(ring_roads) == 4 and all(r.one_way and not r.lanes("b") for r in ring_roads)
    for road in ring_roads:  # each turns left round the centre: counter-clockwise
        a, b = road.centreline[0] - (300, 300), road.centreline[-1] - (300, 300)
        assert a[0] * b[1] - a[1] * b[0] > 0
        radii = np.hypot(*(road.centreline - (300, 300)).T)
        assert np.allclose(radii, RING_RADIUS, atol=0.01)
    assert road_node_count(hd.graph) == road_node_count(G) == 5  # one junction still

    net = sumolib.net.readNet(str(write_map_files(hd, tmp_path)["sumo"]), withInternal=True)
    (roundabout,) = net.getRoundabouts()
    assert sorted(roundabout.getNodes()) == sorted(f"n{n}" for n in ring)
    states = {}
    for node in roundabout.getNodes():
        for edge in net.getNode(node).getIncoming():
            on_ring = edge.getFromNode().getID() in roundabout.getNodes()
            for conns in edge.getOutgoing().values():
                states.setdefault(on_ring, set()).update(c.getState() for c in conns)
    assert states == {True: {"M"}, False: {"m"}}  # the ring goes first, entries yield
    coverage = rule_coverage(net)
    assert coverage["roundabouts"] == 1 and coverage["junction_controls"] == {}
    assert coverage["roundabout_entries"] == len(ring), "every arm enters the ring"


def test_no_roundabout_where_arterials_meet_or_none_is_asked():
    assert not any(j.roundabout is not None for j in build_hdmap(
        crossing("arterial"), roundabouts=1).junctions.values())
    G = crossing()
    assert build_hdmap(G, roundabouts=0).graph is G


def test_an_arm_ending_inside_the_ring_rules_the_junction_out():
    """An arm shorter than the ring's radius never reaches the ring (its intersection with
    the ring is empty): the junction is no roundabout site, and the map builds (a learned
    mixed map, density 30 seed 6, had such a 13 m arm and failed with a traceback)."""
    nodes = {0: (300, 300), 1: (300, 312.9), 2: (550, 300), 3: (300, 50), 4: (50, 300)}
    G = _graph(nodes, [(0, k, "collector") for k in (1, 2, 3, 4)], size=600.0)
    assert not any(j.roundabout is not None
                   for j in build_hdmap(G, roundabouts=1).junctions.values())


def test_the_default_scenario_asks_for_one_and_older_specs_for_none():
    assert rw.ScenarioSpec(density=30, vehicles=1).roundabouts == 1
    assert rw.ScenarioSpec.from_dict({"density": 30, "vehicles": 1}).roundabouts == 0


def test_a_ring_with_sidewalks_reads_back_without_sharp_bends(tmp_path):
    """netconvert shifts a one-way edge with a sidewalk half the sidewalk sideways: the net's
    road graph puts the shifted ends on their junctions instead of adding a spur to them,
    which on a ring read as bends of over 120 degrees."""
    hd = build_hdmap(crossing(), (48.137, 11.575), roundabouts=1, sidewalks=True)
    net = load_net(write_map_files(hd, tmp_path)["sumo"])
    assert len(net.getRoundabouts()) == 1 and sharp_bends(road_graph(net)) == 0
