"""Roads that cross or overlap without a junction (issue 33): the clean-up keeps every road out
of its neighbours' clearance, the report's check finds overlapping lanes in a SUMO net, and an
independent check (``crossing_check``: centrelines and lane outlines of ``map.net.xml`` read
with sumolib) agrees with it on real maps and on a hand-made overlap."""

import subprocess

import numpy as np
import pytest
import sumolib
from crossing_check import crossings

from roadweaver_sumo.clearance import clearance, roads_too_close
from roadweaver_sumo.expand import BORDER_MARGIN, MIN_ANGLE, MIN_EDGE
from roadweaver_sumo.expand.cleanup import clean
from roadweaver_sumo.expand.planar import build_planar_graph
from roadweaver_sumo.pipeline import make_scenario
from roadweaver_sumo.spec import ScenarioSpec
from roadweaver_sumo.sumo_tools import binary
from roadweaver_sumo.validate.overlaps import net_overlaps


def _graph(*roads):
    return build_planar_graph([(np.array(c, float), cls) for c, cls in roads], 1000, 1000)


def test_clearance_is_the_two_half_widths_two_sidewalks_and_a_margin():
    assert clearance("arterial", "local") == pytest.approx(7.0 + 3.0 + 2 * 2.0 + 1.0)


@pytest.mark.parametrize("gap, close", [(5.0, True), (12.0, True), (16.0, False)])
def test_parallel_roads_closer_than_their_clearance_are_found(gap, close):
    G = _graph(([(100, 500), (900, 500)], "arterial"), ([(100, 500 + gap), (900, 500 + gap)], "local"))
    assert bool(roads_too_close(G)) is close


def test_a_dead_end_inside_another_roads_lanes_is_found():
    G = _graph(([(100, 500), (900, 500)], "collector"), ([(500, 800), (500, 503)], "local"))
    assert roads_too_close(G) != []


@pytest.mark.parametrize("angle, length, close", [(33, 20, True), (33, 60, False),
                                                   (90, 20, False), (90, 8, True)])
def test_a_dead_end_on_the_lanes_of_a_road_at_its_own_junction_is_found(angle, length, close):
    """A road cut off by the map edge ``length`` m from the junction where it leaves an
    arterial at ``angle`` degrees: within that junction's area, yet a dead end no junction
    shape covers (learned grid density 20 seed 8: 20 m at 33 degrees, SUMO's net had the two
    roads' lanes on top of each other)."""
    a = np.radians(angle)
    G = _graph(([(300, 500), (500, 500), (900, 500)], "arterial"),
               ([(500, 500), (500, 100)], "local"),
               ([(500, 500), (500 + length * np.cos(a), 500 + length * np.sin(a))], "arterial"))
    assert bool(roads_too_close(G)) is close


def test_roads_meeting_at_a_junction_are_not_too_close():
    G = _graph(([(100, 500), (900, 500)], "arterial"), ([(500, 500), (500, 900)], "arterial"),
               ([(500, 500), (800, 700)], "collector"))  # 34° from the first arm
    assert roads_too_close(G) == []


def test_roads_leaving_a_junction_side_by_side_are_too_close():
    G = _graph(([(100, 500), (900, 500)], "arterial"),
               ([(500, 500), (520, 512), (900, 512)], "arterial"))  # then parallel 12 m off
    assert roads_too_close(G) != []


def test_a_bend_node_of_one_road_is_no_junction_of_another():
    """An arterial bends (a node of degree 2) 8 m from a collector it never meets."""
    G = _graph(([(15, 100), (15, 900)], "collector"), ([(200, 300), (23, 500)], "arterial"),
               ([(23, 500), (200, 700)], "arterial"))
    assert roads_too_close(G) != []


def test_a_road_may_not_pass_close_to_another_beside_its_own_junction():
    """A junction 11 m from a collector it does not join; an arterial leaves it and runs
    9.4 m from the collector (their clearance is 15.25 m) 12.5 m from the junction: the
    junction's area covers one clearance around it, not two (learned 2.5 km mixed density
    41 seed 5179)."""
    G = _graph(([(0, 500), (1000, 500)], "collector"),
               ([(500, 489), (487.6, 490.6), (465.6, 482.1), (420, 440)], "arterial"),
               ([(500, 489), (500, 300)], "local"), ([(500, 489), (700, 330)], "local"))
    assert roads_too_close(G) != []


def test_pairs_asked_among_some_roads_are_those_of_all_pairs_with_them():
    """Two pairs of parallel roads too close; asked among one road of a pair, only that pair
    comes back, as the full check names it (edges as sorted node pairs)."""
    G = _graph(([(100, 200), (900, 200)], "arterial"), ([(100, 205), (900, 205)], "local"),
               ([(100, 700), (900, 700)], "arterial"), ([(100, 706), (900, 706)], "local"))
    everything = roads_too_close(G)
    assert len(everything) == 2
    for pair in everything:
        assert all(edge == tuple(sorted(edge)) for edge in pair)
        for edge in pair:
            assert roads_too_close(G, among={edge}) == [pair]


def test_clean_up_removes_the_lesser_of_two_roads_too_close():
    G = _graph(([(100, 300), (900, 300)], "arterial"), ([(100, 305), (900, 305)], "local"),
               ([(100, 300), (100, 700), (900, 700), (900, 300)], "collector"))
    clean(G, MIN_EDGE, MIN_ANGLE, stub=MIN_EDGE, margin=BORDER_MARGIN)
    assert roads_too_close(G) == []
    assert {d["road_class"] for *_, d in G.edges(data=True)} == {"arterial", "collector"}


def _two_edge_net(tmp_path, gap: float):
    """A net of two parallel one-lane roads ``gap`` metres apart, made by netconvert."""
    (tmp_path / "n.nod.xml").write_text(
        '<nodes><node id="a" x="0" y="0"/><node id="b" x="200" y="0"/>'
        f'<node id="c" x="0" y="{gap}"/><node id="d" x="200" y="{gap}"/></nodes>')
    (tmp_path / "e.edg.xml").write_text(
        '<edges><edge id="ab" from="a" to="b" numLanes="1"/>'
        '<edge id="cd" from="c" to="d" numLanes="1"/></edges>')
    subprocess.run([binary("netconvert"), "-n", "n.nod.xml", "-e", "e.edg.xml",
                    "-o", "o.net.xml"], cwd=tmp_path, check=True, capture_output=True)
    return tmp_path / "o.net.xml"


@pytest.mark.parametrize("gap, overlap", [(2.0, True), (20.0, False)])
def test_the_reports_check_and_the_independent_one_agree_on_lanes_over_each_other(
        tmp_path, gap, overlap):
    net_path = _two_edge_net(tmp_path, gap)
    ours = net_overlaps(sumolib.net.readNet(str(net_path), withInternal=True))
    assert (ours == [("ab", "cd")]) is overlap
    assert bool(crossings(net_path, lanes=True)) is overlap


@pytest.mark.parametrize("seed, style", [(827, "organic"), (821, "grid")])
def test_maps_that_hid_overlapping_roads_have_none(tmp_path, seed, style):
    """Two learned 2 km maps whose nets had roads running on top of each other for tens of
    metres (a road inside the ring road's lanes, a dead end inside another road)."""
    spec = ScenarioSpec(density=30, vehicles=10, seed=seed, style=style)
    result = make_scenario(spec, tmp_path / "s", validate=False)
    report = result.out_dir / "report.json"
    assert '"lane_overlaps": 0' in report.read_text()
    net_path = result.out_dir / "map.net.xml"
    assert net_overlaps(sumolib.net.readNet(str(net_path), withInternal=True)) == []
    assert crossings(net_path) == [] and crossings(net_path, lanes=True) == []
