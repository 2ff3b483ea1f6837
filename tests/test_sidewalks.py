"""Sidewalks, crossings and pedestrians (``--sidewalks``, ``--persons``): a sidewalk lane 0
beside every driving direction in the HD map, SUMO and OpenDRIVE; a crossing over every road
at junctions of three or more roads; walks that SUMO routes and completes."""

from __future__ import annotations

import json

import numpy as np
import pytest
from lxml import etree
from shapely.geometry import LineString, Point, Polygon
from test_one_way import local_grid

from roadweaver_sumo.cli import main
from roadweaver_sumo.export.map_files import write_map_files
from roadweaver_sumo.hdmap import build_hdmap, hdmap_metrics
from roadweaver_sumo.hdmap.lanes import LANE_CONFIGS, SIDEWALK_WIDTH
from roadweaver_sumo.spec import DEFAULT_PERSONS, ScenarioSpec
from roadweaver_sumo.validate.lanelet2_check import check_lanelet2, lanelet2_failures
from roadweaver_sumo.validate.netgraph import load_net


@pytest.fixture(scope="module")
def hd():
    return build_hdmap(local_grid(), (48.137, 11.575), one_way_share=0.4, sidewalks=True)


@pytest.fixture(scope="module")
def files(hd, tmp_path_factory):
    return write_map_files(hd, tmp_path_factory.mktemp("sidewalks"))


def test_every_driving_direction_has_a_sidewalk_outside_its_lanes(hd):
    assert hdmap_metrics(hd)["strongly_connected"], "the vehicles' lane graph is untouched"
    for road in hd.roads.values():
        n = LANE_CONFIGS[road.road_class].lanes
        for direction in ("f", "b"):
            lanes = road.lanes(direction)
            if not lanes:
                assert f"r{road.id}_{direction}_0" not in hd.sidewalks  # a one-way road
                continue
            assert [hd.lanes[lane].index for lane in lanes] == list(range(1, n + 1))
            walk = hd.sidewalks[f"r{road.id}_{direction}_0"]
            assert walk.kind == "sidewalk" and walk.width == SIDEWALK_WIDTH
            outer = hd.lanes[lanes[0]]
            assert np.allclose(walk.left, outer.right), "the sidewalk adjoins the outer lane"
            gap = LineString(walk.centre).distance(LineString(outer.centre))
            assert gap == pytest.approx((outer.width + walk.width) / 2, abs=0.01)


def test_sumo_has_the_sidewalks_crossings_and_walking_areas(hd, files):
    net = load_net(files["sumo"])
    for lane_id, walk in hd.sidewalks.items():
        lane = net.getLane(lane_id)
        assert lane.getPermissions() == {"pedestrian"}
        assert lane.getWidth() == pytest.approx(walk.width)
    root = etree.parse(str(files["sumo"])).getroot()
    crossings = {e.get("id").split("_")[0][1:] for e in root.iter("edge")
                 if e.get("function") == "crossing"}
    busy = {f"n{j.id}" for j in hd.junctions.values() if len(j.roads) >= 3}
    assert crossings == busy
    walking = {e.get("id").split("_")[0][1:] for e in root.iter("edge")
               if e.get("function") == "walkingarea"}
    assert busy < walking, "walking areas join sidewalks at two-road nodes too"


def test_sumo_lanes_end_where_the_hd_map_ends_them(hd, files):
    """Junction outlines come from the HD map, crossings and corners included: netconvert's
    own made roads between close junctions centimetres long in SUMO only. Along each road,
    every SUMO lane starts and ends within 0.1 m of its HD map lane."""
    net = load_net(files["sumo"])
    for lane in list(hd.road_lanes()) + list(hd.sidewalks.values()):
        road = LineString(hd.roads[lane.road].centreline)
        sumo = net.getLane(lane.id).getShape()
        for ours, theirs in ((lane.centre[0], sumo[0]), (lane.centre[-1], sumo[-1])):
            assert road.project(Point(theirs)) == pytest.approx(road.project(Point(ours)),
                                                                 abs=0.1), lane.id


def test_opendrive_carries_the_sidewalks_carla_finds_them(hd, files):
    root = etree.parse(str(files["opendrive"])).getroot()
    sidewalks = [lane for lane in root.iter("lane") if lane.get("type") == "sidewalk"]
    assert len(sidewalks) == len(hd.sidewalks)
    carla = pytest.importorskip("carla")
    carla_map = carla.Map("sidewalks", files["opendrive"].read_text())
    for walk in list(hd.sidewalks.values())[:20]:
        x, y = walk.centre[len(walk.centre) // 2]
        w = carla_map.get_waypoint(carla.Location(x, -y, 0.0), lane_type=carla.LaneType.Sidewalk)
        assert w.lane_type == carla.LaneType.Sidewalk
        assert w.transform.location.distance(carla.Location(x, -y, 0.0)) < walk.width / 2


def test_opendrive_crosswalks_are_sumos_crossings_and_carla_reads_them(hd, files):
    root = etree.parse(str(files["sumo"])).getroot()
    crossings = {}
    for edge in root.iter("edge"):
        if edge.get("function") == "crossing":
            lane = edge.find("lane")
            crossings[edge.get("id")] = (LineString([tuple(map(float, p.split(",")))
                                                     for p in lane.get("shape").split()]),
                                         float(lane.get("width")))
    objects = {o.get("id"): o for o in etree.parse(str(files["opendrive"])).getroot()
               .iter("object") if o.get("type") == "crosswalk"}
    assert set(objects) == set(crossings) and crossings
    for cid, obj in objects.items():
        road = obj.getparent().getparent()
        crossed = root.find(f"edge[@id='{cid}']").get("crossingEdges").split()
        assert {f"r{road.get('id')}_{d}" for d in "fb"} >= set(crossed)
    carla = pytest.importorskip("carla")
    points = carla.Map("sidewalks", files["opendrive"].read_text()).get_crosswalks()
    assert len(points) == 4 * len(crossings)
    expected = {}  # object id -> (true centre, CARLA's offset from it)
    for cid, obj in objects.items():
        road = hd.roads[int(obj.getparent().getparent().get("id"))]
        # CARLA 0.9.16 places objects from the lane-offset line, not from the reference line
        # (OpenDRIVE 1.7, "Objects": t is measured from the reference line): on a one-way
        # road, half its cross-section off (docs/opendrive.md)
        half = road.lane_width * len(road.lanes("f")) / 2  # the laneOffset
        expected[cid] = (crossings[cid][0].centroid, half if road.one_way else 0.0)
    shifted = 0
    for k in range(0, len(points), 4):
        corners = [(p.x, -p.y) for p in points[k:k + 4]]  # CARLA's y runs the other way
        centre = Polygon(corners).centroid
        cid = min(expected, key=lambda c: abs(expected[c][0].distance(centre) - expected[c][1]))
        true, offset = expected.pop(cid)
        assert true.distance(centre) == pytest.approx(offset, abs=0.01)
        shifted += offset > 0
        line, width = crossings[cid]
        for corner in corners:  # each corner half the crossing's width from its centre line
            assert line.distance(Point(corner)) == pytest.approx(width / 2, abs=0.01) or offset
    assert not expected
    assert shifted < len(crossings) / 2


def test_lanelet2_has_walkways_and_crosswalks_that_lanelet2_routes_pedestrians_on(hd, files):
    result = check_lanelet2(files["lanelet2"], hd.geo_origin, pairs=300)
    assert lanelet2_failures(result) == []
    assert result["sidewalks"] == len(hd.sidewalks)
    assert result["crosswalks"] == len(hd.crosswalks) > 0
    assert result["pedestrian_route_success"] == 1.0 and result["route_success"] == 1.0


def test_pedestrians_walk_on_them_to_their_end(tmp_path):
    out = tmp_path / "walk"
    code = main(["make-scenario", "--density", "30", "--vehicles", "60", "--size", "800",
                 "--duration", "600", "--skeleton", "procedural", "--sidewalks", "--persons",
                 "40", "--out", str(out)])
    report = json.loads((out / "report.json").read_text())
    sim = report["simulation"]
    assert (sim["persons_loaded"], sim["persons_arrived"]) == (40, 40)
    assert sim["persons_arrived_ratio"] == 1.0 and sim["persons_jammed"] == 0
    assert 0 < sim["persons_time_loss_s"] < 600  # waiting at crossings and lights, per walk
    assert code == (0 if report["passed"] else 1)
    people = etree.parse(str(out / "persons.rou.xml")).getroot().findall("person")
    assert [p.get("id") for p in people] == [f"ped{i}" for i in range(40)]
    # people step out of doors along a street, not onto a crossing at its end
    assert all(float(p.get("departPos")) > 0 and float(p.find("walk").get("arrivalPos")) > 0
               for p in people)
    assert "persons.rou.xml" in (out / "scenario.sumocfg").read_text()
    assert not [p.name for p in out.iterdir() if ".tmp" in p.name]  # no routing leftovers


def test_persons_without_sidewalks_is_a_one_line_error(tmp_path, capsys):
    assert main(["make-scenario", "--density", "30", "--vehicles", "10", "--persons", "5",
                 "--no-sidewalks", "--out", str(tmp_path / "x")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--persons needs sidewalks" in err[0]


def test_a_walking_area_turn_between_ends_that_cross_each_other_loads_as_written():
    """At a tight corner SUMO's walking area can join two sidewalk ends that cross each other
    (an X, here taken from a learned 1 km map): one lanelet between them is twisted, and a
    middle edge at the middle of the two is too (lanelet2 turns a bound of one half round, and
    the sidewalk is cut off for pedestrian routing). The middle edge goes aside until both
    halves pass lanelet2's own orientation test."""
    from roadweaver_sumo.export.lanelet2_walks import _aligned_points, _middle_edges

    left, right, left_end, right_end = np.array(X_CORNER)
    assert not _aligned_points(left, right, left_end, right_end)
    [middle] = _middle_edges(*np.array(X_CORNER)[:, None])
    assert _aligned_points(left, right, *middle) and _aligned_points(*middle, left_end, right_end)


X_CORNER = [(543.49, 625.67), (545.49, 625.86), (545.06, 628.11), (543.78, 626.57)]
WIDE_CORNER = [(1171.79, 1050.75), (1172.10, 1052.72), (1168.47, 1053.29), (1168.43, 1051.29)]


def test_a_walking_area_lanelet_whose_bounds_would_cross_goes_round_by_a_middle_edge():
    """Two sidewalk ends at a wide corner (taken from the main job's map with sidewalks): a
    lanelet straight from one to the other passes lanelet2's orientation test, but its left
    and right bounds cross, a bow-tie outline that CommonRoad and shapely reject. It is split
    at a middle edge whose two halves are simple four-sided lanelets."""
    from shapely.geometry import Polygon

    from roadweaver_sumo.export.lanelet2_walks import _aligned_points, _middle_edges

    la, ra, lb, rb = np.array(WIDE_CORNER)
    assert not Polygon([la, lb, rb, ra]).is_valid, "the straight lanelet is a bow-tie"
    assert not _aligned_points(la, ra, lb, rb)
    [(ml, mr)] = _middle_edges(*np.array(WIDE_CORNER)[:, None])
    assert Polygon([la, ml, mr, ra]).is_valid and Polygon([ml, lb, rb, mr]).is_valid
    assert _aligned_points(la, ra, ml, mr) and _aligned_points(ml, mr, lb, rb)


def test_middle_edges_of_many_lanelets_are_each_ones_own():
    """The middle edges are searched for many lanelets at once: each lanelet gets the one it
    gets alone, and a lanelet lanelet2 reads as written gets none."""
    from roadweaver_sumo.export.lanelet2_walks import _middle_edges

    straight = [(0.0, 0.0), (0.0, -2.0), (10.0, 0.0), (10.0, -2.0)]
    lanelets = np.array([WIDE_CORNER, straight, X_CORNER]).transpose(1, 0, 2)
    together = _middle_edges(*lanelets)
    assert together[1] is None
    for k in (0, 2):
        [alone] = _middle_edges(*lanelets[:, k:k + 1])
        assert np.array_equal(together[k], alone)


def test_sidewalks_and_walkers_are_the_default_and_can_be_left_out(tmp_path):
    """Issue 36: the default scenario has sidewalks, crossings and DEFAULT_PERSONS walkers;
    --no-sidewalks leaves out both, and --persons 0 keeps sidewalks without walkers."""
    assert (ScenarioSpec(density=30, vehicles=10).sidewalks,
            ScenarioSpec(density=30, vehicles=10).persons) == (True, DEFAULT_PERSONS)
    assert ScenarioSpec(density=30, vehicles=10, sidewalks=False).persons == 0
    base = ["make-scenario", "--density", "30", "--vehicles", "10", "--size", "800",
            "--no-validate"]
    for extra, expected in (([], (True, DEFAULT_PERSONS)), (["--no-sidewalks"], (False, 0)),
                            (["--persons", "0"], (True, 0))):
        out = tmp_path / "-".join(extra or ["default"])
        assert main([*base, *extra, "--out", str(out)]) == 0
        spec = ScenarioSpec.from_json_file(out / "spec.json")
        assert (spec.sidewalks, spec.persons) == expected
        assert (out / "persons.rou.xml").exists() == bool(expected[1])
    walks = etree.parse(str(tmp_path / "default" / "persons.rou.xml")).getroot()
    assert {p.get("type") for p in walks.iter("person")} == {
        t.get("id") for t in walks.iter("vType") if t.get("vClass") == "pedestrian"}


@pytest.mark.parametrize("local_lanes", [1, 2])
def test_sumo_lanes_lie_where_the_hd_map_lays_them(local_lanes, tmp_path):
    """SUMO spreads a one-way edge's lanes about its shape without its sidewalk; the HD map
    lays them out alike, or SUMO's cars drove a metre off the OpenDRIVE lane. Every SUMO lane
    lies within 0.05 m of its HD map lane's centre line, one-way streets included."""
    hd = build_hdmap(local_grid(), (48.137, 11.575), one_way_share=0.4, sidewalks=True,
                     lanes={"local": local_lanes})
    assert any(road.one_way for road in hd.roads.values())
    net = load_net(write_map_files(hd, tmp_path)["sumo"])
    for lane in list(hd.road_lanes()) + list(hd.sidewalks.values()):
        ours = LineString(lane.centre)
        for point in net.getLane(lane.id).getShape():
            assert ours.distance(Point(point)) < 0.05, lane.id
