"""Stage 3: lane-level HD map construction on small hand-made road graphs."""

from __future__ import annotations

from collections import Counter

import networkx as nx
import numpy as np
import pytest
from shapely.geometry import LineString, Point, Polygon

from roadweaver_sumo.hdmap import LANE_CONFIGS, build_hdmap, hdmap_metrics, lane_reachability
from roadweaver_sumo.hdmap.control import junction_control
from roadweaver_sumo.hdmap.geometry import (
    arc_lengths,
)
from roadweaver_sumo.roadgraph import add_road, new_road_graph


def _graph(nodes: dict, roads: list, size: float = 400.0) -> nx.Graph:
    """RoadGraph from node positions and (u, v, class, *interior points) tuples."""
    G = new_road_graph(size, size)
    for n, xy in nodes.items():
        G.add_node(n, xy=(float(xy[0]), float(xy[1])))
    for u, v, road_class, *interior in roads:
        add_road(G, u, v, [nodes[u], *interior, nodes[v]], road_class)
    return G


def grid_with_arterial_cross() -> nx.Graph:
    """3 x 3 grid, 100 m blocks: the middle row and column are arterials, the other rows
    locals and the other columns collectors; the centre is a four-arterial crossing."""
    nodes = {3 * i + j: (100.0 * (j + 1), 100.0 * (i + 1)) for i in range(3) for j in range(3)}
    roads = []
    for i in range(3):
        for j in range(3):
            a = 3 * i + j
            if j < 2:
                roads.append((a, a + 1, "arterial" if i == 1 else "local"))
            if i < 2:
                roads.append((a, a + 3, "arterial" if j == 1 else "collector"))
    return _graph(nodes, roads)


def t_junction() -> nx.Graph:
    """An arterial running west-east with a local stem to the south; all three arms end in
    dead ends."""
    nodes = {0: (200, 200), 1: (50, 200), 2: (350, 200), 3: (200, 60)}
    return _graph(nodes, [(1, 0, "arterial"), (0, 2, "arterial"), (0, 3, "local")])


def curve_with_degree_two_node() -> nx.Graph:
    """A straight arterial meeting, at a degree-2 node, a collector bending through a quarter
    circle (radius 100 m); both far ends are dead ends."""
    angles = np.linspace(-np.pi / 2, 0.0, 17)[1:-1]
    arc = [(100 + 100 * np.cos(a), 100 + 100 * np.sin(a)) for a in angles]
    nodes = {0: (0, 0), 1: (100, 0), 2: (200, 100)}
    return _graph(nodes, [(0, 1, "arterial"), (1, 2, "collector", *arc)])


def short_road_between_crossings() -> nx.Graph:
    """Two arterial crossings only 12 m apart, joined by a local road."""
    nodes = {0: (100, 100), 1: (112, 100), 2: (100, 20), 3: (100, 180), 4: (112, 20),
             5: (112, 180), 6: (20, 100), 7: (192, 100)}
    roads = [(2, 0, "arterial"), (0, 3, "arterial"), (4, 1, "arterial"), (1, 5, "arterial"),
             (0, 1, "local"), (6, 0, "local"), (1, 7, "local")]
    return _graph(nodes, roads)


def ring() -> nx.Graph:
    """Four arterials in a square, every node of degree 2: no junction allows a way back."""
    nodes = {0: (100, 100), 1: (200, 100), 2: (200, 200), 3: (100, 200)}
    return _graph(nodes, [(i, (i + 1) % 4, "arterial") for i in range(4)])


FIXTURES = [grid_with_arterial_cross, t_junction, curve_with_degree_two_node,
            short_road_between_crossings, ring]


@pytest.fixture(scope="module", params=FIXTURES, ids=lambda f: f.__name__)
def hdmap(request):
    return build_hdmap(request.param())


def test_lane_graph_is_strongly_connected_fully_reachable_and_aligned(hdmap):
    m = hdmap_metrics(hdmap)
    assert set(m) >= {"lane_count", "lane_reachability", "strongly_connected",
                      "alignment_mean_m", "alignment_p95_m", "alignment_max_m"}
    assert m["strongly_connected"] is True
    assert m["lane_reachability"] == 1.0
    assert m["alignment_max_m"] <= 1e-9
    assert m["lane_count"] == len(hdmap.road_lanes())


def test_lanes_follow_their_road_class(hdmap):
    for road in hdmap.roads.values():
        cfg = LANE_CONFIGS[road.road_class]
        for direction in ("f", "b"):
            lanes = [hdmap.lanes[i] for i in road.lanes(direction)]
            bay = road.bay == direction  # a turn bay's road: one lane more (turn_bays)
            assert [lane.index for lane in lanes] == list(range(cfg.lanes + bay))
            assert all(lane.width == cfg.width and lane.speed == cfg.speed for lane in lanes)


def test_lanes_lie_right_of_the_reference_line_at_their_offset(hdmap):
    """Right-hand traffic: lane k of n sits (n - k - 0.5) lane widths right of the reference
    line in its driving direction, at every sample of it and no nearer anywhere (the arcs are
    wider than the road: no lane folds over); boundaries are one lane width apart."""
    for lane in hdmap.road_lanes():
        road = hdmap.roads[lane.road]
        n = LANE_CONFIGS[road.road_class].lanes
        points = road.reference[0]
        line = points if lane.direction == "f" else points[::-1]
        expected = (n - lane.index - 0.5) * lane.width
        assert np.allclose(np.linalg.norm(lane.centre - line, axis=1), expected, atol=1e-9)
        assert LineString(line).distance(LineString(lane.centre)) >= expected - 0.05
        ahead, across = line[1] - line[0], lane.centre[0] - line[0]
        assert ahead[0] * across[1] - ahead[1] * across[0] < 0  # right of the driving direction
        width = np.linalg.norm(lane.left - lane.right, axis=1)
        assert np.allclose(width[[0, -1]], lane.width)


def test_every_lane_has_a_way_in_and_a_way_out(hdmap):
    for lane in hdmap.road_lanes():
        assert lane.successors, lane.id
        assert lane.predecessors, lane.id


def test_connectors_start_and_end_exactly_on_the_lanes_they_join(hdmap):
    for c in hdmap.connectors():
        (pred,), (succ,) = c.predecessors, c.successors
        a, b = hdmap.lanes[pred], hdmap.lanes[succ]
        assert np.array_equal(c.centre[0], a.centre[-1])
        assert np.array_equal(c.centre[-1], b.centre[0])
        assert np.allclose([c.left[0], c.right[0]], [a.left[-1], a.right[-1]], atol=1e-9)
        assert np.allclose([c.left[-1], c.right[-1]], [b.left[0], b.right[0]], atol=1e-9)
        assert c.id in a.successors and c.id in b.predecessors


def test_turns_leave_from_the_outer_lanes(hdmap):
    """With two or more incoming lanes, right turns leave only from the rightmost lane and left
    turns only from the leftmost one; straight movements keep lane order."""
    for c in hdmap.connectors():
        a, b = hdmap.lanes[c.predecessors[0]], hdmap.lanes[c.successors[0]]
        n_in = len(hdmap.roads[a.road].lanes(a.direction))
        n_out = len(hdmap.roads[b.road].lanes(b.direction))
        if c.movement == "right" and n_in >= 2:
            assert a.index == 0, c.id
        if c.movement == "left" and n_in >= 2:
            assert a.index == n_in - 1, c.id
        if c.movement == "straight" and n_in == n_out:
            assert a.index == b.index, c.id


def test_uturns_only_at_dead_ends_or_as_repairs(hdmap):
    """Every dead-end lane turns around; elsewhere a road never connects to itself unless the
    repair pass needed it (only a ring without any real junction does)."""
    needs_repair = all(len(j.roads) == 2 for j in hdmap.junctions.values())
    for c in hdmap.connectors():
        a, b = hdmap.lanes[c.predecessors[0]], hdmap.lanes[c.successors[0]]
        same_road = a.road == b.road
        assert same_road == (c.movement == "uturn")
        if same_road and not needs_repair:
            assert hdmap.junctions[c.junction].type == "dead_end"
    for j in hdmap.junctions.values():
        if j.type == "dead_end":
            arriving = {hdmap.lanes[c].predecessors[0] for c in j.connectors}
            road = hdmap.roads[j.roads[0]]
            direction = "f" if road.to_node == j.id else "b"
            assert arriving == set(road.lanes(direction))


def test_lanes_of_different_roads_do_not_overlap(hdmap):
    polys = {}
    for lane in hdmap.road_lanes():
        shape = Polygon(np.vstack([lane.left, lane.right[::-1]]))
        polys[lane.road] = shape if lane.road not in polys else polys[lane.road].union(shape)
    for j in hdmap.junctions.values():
        for i, r in enumerate(j.roads):
            for s in j.roads[i + 1 :]:
                assert polys[r].intersection(polys[s]).area < 1e-6, (j.id, r, s)


def test_degree_two_node_merges_two_lanes_into_one():
    hd = build_hdmap(curve_with_degree_two_node())
    (arterial,) = [r for r in hd.roads.values() if r.road_class == "arterial"]
    (collector,) = [r for r in hd.roads.values() if r.road_class == "collector"]
    pairs = {(hd.lanes[c].predecessors[0], hd.lanes[c].successors[0])
             for c in hd.junctions[1].connectors}
    assert pairs == {("r0_f_0", "r1_f_0"), ("r0_f_1", "r1_f_0"),
                     ("r1_b_0", "r0_b_0"), ("r1_b_0", "r0_b_1")}
    assert (arterial.id, collector.id) == (0, 1)


def test_short_road_keeps_a_lane_section():
    hd = build_hdmap(short_road_between_crossings())
    (road,) = [r for r in hd.roads.values() if {r.from_node, r.to_node} == {0, 1}]
    section = road.sections[0]
    assert section.s_end - section.s_start >= 0.2 * 12.0 - 1e-9


def test_junction_controls_follow_the_classes_and_the_rules():
    """Lights where arterials cross (every rule set); under ``priority`` rules all else yields;
    ``de``: right-before-left among residential streets, a stop onto an arterial; ``us``:
    all-way stops at minor four-ways, stop signs elsewhere; a road that just goes on through
    a two-arm node and a dead end are never controlled."""
    for rules in ("de", "us", "priority"):
        assert junction_control(["local"], rules) == "dead_end"
        assert junction_control(["local", "local"], rules) == "priority"
        assert junction_control(["arterial", "arterial"], rules) == "priority"
        assert junction_control(["arterial", "arterial", "arterial"], rules) == "traffic_light"
        assert junction_control(["arterial", "arterial", "local", "local"], rules) == \
            "traffic_light"
        assert junction_control(["arterial", "collector", "local", "local"], rules) == \
            "traffic_light"
    cases = (["local"] * 3, ["local"] * 4, ["collector", "collector", "local", "local"],
             ["arterial", "arterial", "local"], ["collector", "collector", "local"])
    expected = {"de": ["right_before_left", "right_before_left", "priority", "priority_stop",
                       "priority"],
                "us": ["priority_stop", "allway_stop", "allway_stop", "priority_stop",
                       "priority_stop"],
                "priority": ["priority"] * 5}
    for rules, controls in expected.items():
        assert [junction_control(classes, rules) for classes in cases] == controls
    assert junction_control(["arterial"] * 4, "us", traffic_lights=False) == "priority_stop"
    hd = build_hdmap(grid_with_arterial_cross(), rules="priority")
    types = {j: hd.junctions[j].type for j in hd.junctions}
    assert types[4] == "traffic_light"
    assert all(types[j] == "priority" for j in types if j != 4)
    hd = build_hdmap(t_junction(), traffic_lights=False, rules="priority")
    assert [hd.junctions[j].type for j in sorted(hd.junctions)] == ["priority"] + ["dead_end"] * 3


def test_ring_is_repaired_with_two_uturns():
    hd = build_hdmap(ring())
    uturns = [c for c in hd.connectors() if c.movement == "uturn"]
    assert len(uturns) == 2
    assert hdmap_metrics(hd)["strongly_connected"]


def _brute_force_reachability(hd) -> float:
    g = nx.DiGraph()
    for lane in hd.lanes.values():
        g.add_node(lane.id)
        for t in lane.successors + [x for x in (lane.left_neighbour, lane.right_neighbour) if x]:
            g.add_edge(lane.id, t)
    road = [lane.id for lane in hd.road_lanes()]
    hits = sum(len(nx.descendants(g, u) & set(road)) for u in road)
    return hits / (len(road) * (len(road) - 1))


def test_lane_reachability_counts_pairs_without_repair():
    hd = build_hdmap(ring())
    for c in [c for c in hd.connectors() if c.movement == "uturn"]:  # undo the repair
        hd.lanes[c.predecessors[0]].successors.remove(c.id)
        hd.lanes[c.successors[0]].predecessors.remove(c.id)
        hd.junctions[c.junction].connectors.remove(c.id)
        del hd.lanes[c.id]
    value = lane_reachability(hd)
    assert value == pytest.approx(_brute_force_reachability(hd))
    assert value == pytest.approx(2 * 8 * 7 / (16 * 15))  # two one-way loops of 8 lanes
    assert hdmap_metrics(hd)["strongly_connected"] is False


def test_build_is_deterministic():
    a, b = build_hdmap(grid_with_arterial_cross()), build_hdmap(grid_with_arterial_cross())
    assert list(a.lanes) == list(b.lanes)
    for lane_id, lane in a.lanes.items():
        other = b.lanes[lane_id]
        assert np.array_equal(lane.centre, other.centre)
        assert (lane.successors, lane.predecessors) == (other.successors, other.predecessors)


def test_generated_lane_ends_point_the_driving_way():
    """A sliver segment at a trimmed lane end used to point backwards and flip the movement
    classification at the junction (left turns from the right lane; seen on radial, density 60,
    seed 3, as a junction collision in SUMO)."""
    from roadweaver_sumo.expand import expand_skeleton
    from roadweaver_sumo.hdmap.geometry import end_tangent, start_tangent
    from roadweaver_sumo.skeleton import make_skeleton
    from roadweaver_sumo.spec import ScenarioSpec

    spec = ScenarioSpec(density=60, vehicles=1, style="radial", seed=3, skeleton="procedural")
    hd = build_hdmap(expand_skeleton(spec, make_skeleton(spec)), spec.geo_origin)
    for lane in hd.road_lanes():
        c = LineString(lane.centre)
        back = np.asarray(c.interpolate(max(c.length - 5.0, 0.0)).coords[0])
        ahead = np.asarray(c.interpolate(min(5.0, c.length)).coords[0])
        assert end_tangent(lane.centre) @ (lane.centre[-1] - back) > 0, lane.id
        assert start_tangent(lane.centre) @ (ahead - lane.centre[0]) > 0, lane.id


def test_inner_boundary_of_a_tight_turn_runs_forwards():
    """A right turn whose curvature radius drops below half the lane width: offsetting by half
    the width would fold the inner boundary back (lanelet2 then reverses the lanelet). The inner
    boundary is pulled in and every step of it runs forwards; both ends stay at half width."""
    from roadweaver_sumo.hdmap.geometry import (
        bezier_controls,
        bezier_sample,
        boundary_offsets,
        offset_along,
    )

    out = np.array([[np.cos(np.radians(-100.0)), np.sin(np.radians(-100.0))]])
    corner = np.array([[5.0, 0.0]])  # a 100 degree right turn, 5 m in, 2.5 m out
    ctrl = bezier_controls(np.zeros((1, 2)), np.array([[1.0, 0.0]]), corner + 2.5 * out, out)
    pts, tangents, curvature = bezier_sample(ctrl)
    half = np.full(curvature.shape, 1.75)
    plain = np.diff(offset_along(pts, tangents, -half)[0], axis=0)
    assert (np.einsum("ij,ij->i", plain[:-1], plain[1:]) < 0).any()  # would fold back
    left_d, right_d = boundary_offsets(curvature, half)
    assert np.array_equal(left_d, half)  # the outer side keeps its width
    assert right_d[0, 0] == right_d[0, -1] == -1.75
    right = offset_along(pts, tangents, right_d)[0]
    steps = np.diff(right, axis=0)
    along = tangents[0, :-1] + tangents[0, 1:]
    assert (np.einsum("ij,ij->i", steps, along) > 0).all()  # forwards along the lane
    assert (np.einsum("ij,ij->i", steps[:-1], steps[1:]) > 0).all()  # no turn of 90 degrees
    assert LineString(right).is_simple


def test_connectors_get_as_many_samples_as_their_curve_needs():
    """A straight connector is two points, a tight turn keeps every sample, and any connector
    sampled more coarsely stays within the tolerance of its Bezier curve."""
    from roadweaver_sumo.hdmap.geometry import (
        BEZIER_SAMPLES,
        BEZIER_TOLERANCE,
        bezier_controls,
        bezier_sample,
        bezier_sample_counts,
    )

    rng = np.random.default_rng(3)
    m = 400
    p0 = rng.uniform(-5, 5, (m, 2))
    angle0 = rng.uniform(-np.pi, np.pi, m)
    angle3 = angle0 + rng.uniform(-1.2, 1.2, m)  # through movements and bends
    t0 = np.column_stack([np.cos(angle0), np.sin(angle0)])
    t3 = np.column_stack([np.cos(angle3), np.sin(angle3)])
    across = np.column_stack([-t0[:, 1], t0[:, 0]])
    p3 = p0 + rng.uniform(8, 30, (m, 1)) * t0 + rng.uniform(-4, 4, (m, 1)) * across
    straight = bezier_controls(np.zeros((1, 2)), np.array([[1.0, 0.0]]),
                               np.array([[20.0, 0.0]]), np.array([[1.0, 0.0]]))
    turn = bezier_controls(np.zeros((1, 2)), np.array([[1.0, 0.0]]),
                           np.array([[8.0, 8.0]]), np.array([[0.0, 1.0]]))
    ctrl = np.concatenate([straight, turn, bezier_controls(p0, t0, p3, t3)])
    counts = bezier_sample_counts(ctrl)
    assert counts[0] == 2 and counts[1] == BEZIER_SAMPLES
    assert (counts < BEZIER_SAMPLES).sum() > 20  # the loop below checks something
    dense, _, _ = bezier_sample(ctrl, 200)
    for k in np.flatnonzero(counts < BEZIER_SAMPLES):
        coarse, _, _ = bezier_sample(ctrl[k : k + 1], int(counts[k]))
        polyline = LineString(coarse[0])
        gap = max(polyline.distance(Point(p)) for p in dense[k])
        assert gap <= BEZIER_TOLERANCE + 1e-9, (k, counts[k], gap)


def test_no_two_lanes_merge_inside_a_junction_where_a_road_turns_off():
    """A two-lane arterial that bends away to the right (a right turn) while a one-lane local
    road carries on straight: the local road is entered from the left lane only, the right
    turn from the right lane only. Both lanes into the one lane would run on converging
    internal lanes, where cars side by side touch (junction collisions in SUMO)."""
    nodes = {0: (200, 200), 1: (50, 200), 2: (350, 200), 3: (300, 60)}
    hd = build_hdmap(_graph(nodes, [(1, 0, "arterial"), (0, 3, "arterial"), (0, 2, "local")]))
    roads = {(r.from_node, r.to_node): r.id for r in hd.roads.values()}
    west, ahead, right = roads[(1, 0)], roads[(0, 2)], roads[(0, 3)]
    pairs = {(hd.lanes[c].predecessors[0], hd.lanes[c].successors[0], hd.lanes[c].movement)
             for c in hd.junctions[0].connectors if hd.lanes[c].predecessors[0].startswith(f"r{west}_f")}
    assert pairs == {(f"r{west}_f_1", f"r{ahead}_f_0", "straight"),
                     (f"r{west}_f_0", f"r{right}_f_0", "right")}
    for name, graph in (("T", t_junction()), ("grid", grid_with_arterial_cross())):
        built = build_hdmap(graph)
        for junction in built.junctions.values():
            if len(junction.roads) < 3:
                continue
            entered = Counter((built.lanes[built.lanes[c].predecessors[0]].edge,
                               built.lanes[c].successors[0]) for c in junction.connectors)
            assert max(entered.values()) == 1, (name, junction.id, entered.most_common(1))


def test_lane_geometry_keeps_widths_arc_lengths_and_curvature():
    """The polyline and Bezier steps lanes are built from (paper Algorithm 1,
    GenerateLaneBoundaries): a miter offset keeps every piece of a bent road parallel at the
    lane's distance; a cut ends at the asked arc lengths; end directions point along the
    road's ends; a connector's Bezier is exact at its ends and, for a quarter turn, close to
    the circle's curvature."""
    from shapely import LineString, Point

    from roadweaver_sumo.hdmap.geometry import (
        bezier_controls,
        bezier_sample,
        cut,
        end_directions,
        offset,
    )

    road = np.array([[0.0, 0.0], [40.0, 0.0], [40.0, 30.0], [10.0, 60.0]])
    for d in (-3.5, 1.75):
        (line,) = offset(road, [d])
        for k in range(len(road) - 1):
            piece, copy = road[k + 1] - road[k], line[k + 1] - line[k]
            assert abs(piece[0] * copy[1] - piece[1] * copy[0]) < 1e-9 * np.dot(piece, piece)
            assert LineString(road[k:k + 2]).distance(Point(*(line[k] + line[k + 1]) / 2)) \
                == pytest.approx(abs(d))
    assert np.array_equal(arc_lengths(road), [0.0, 40.0, 70.0, 70.0 + 30.0 * np.sqrt(2)])
    part = cut(road, 10.0, 55.0)
    assert np.allclose(part[[0, -1]], [[10.0, 0.0], [40.0, 15.0]]) and len(part) == 3
    assert np.allclose(cut(road, 10.0, 40.2)[[0, -1]], [[10.0, 0.0], [40.0, 0.2]])  # vertex dropped
    assert np.allclose(end_directions([road], 5.0), [[1.0, 0.0], [np.sqrt(0.5), -np.sqrt(0.5)]])
    ctrl = bezier_controls(np.array([[0.0, 0.0]]), np.array([[1.0, 0.0]]),
                           np.array([[10.0, 10.0]]), np.array([[0.0, 1.0]]))
    pts, tangents, curvature = bezier_sample(ctrl, 12)
    assert np.array_equal(pts[0, [0, -1]], [[0.0, 0.0], [10.0, 10.0]])
    assert np.allclose(np.linalg.norm(tangents, axis=2), 1.0)
    assert np.allclose(curvature, 0.1, rtol=0.03)
    assert np.allclose(np.linalg.norm(pts[0] - [0.0, 10.0], axis=1), 10.0, rtol=0.002)


def test_no_left_turn_sharper_than_135_degrees_where_there_is_another_way():
    """A local road leaves an arterial 40° from its west arm: from the west it would be a 140°
    left turn beside the oncoming lanes (SUMO put such a left-turner's waiting point 0.7 m from
    the oncoming lane, and a car hit it). That turn is not offered; the road is still entered
    from the east and from every lane of the map."""
    nodes = {0: (200, 200), 1: (50, 200), 2: (350, 200),
             3: (200 + 150 * np.cos(np.radians(140)), 200 + 150 * np.sin(np.radians(140)))}
    hd = build_hdmap(_graph(nodes, [(1, 0, "arterial"), (0, 2, "arterial"), (0, 3, "local")]))
    roads = {(r.from_node, r.to_node): r.id for r in hd.roads.values()}
    into_acute = {hd.lanes[c].predecessors[0].rsplit("_", 1)[0] + "_" + hd.lanes[c].movement
                  for c in hd.junctions[0].connectors
                  if hd.lanes[c].successors[0].startswith(f"r{roads[(0, 3)]}_f")}
    assert into_acute == {f"r{roads[(0, 2)]}_b_right"}
    assert lane_reachability(hd) == 1.0


@pytest.mark.parametrize("angle", [35.0, 50.0, 65.0, 90.0, 120.0])
@pytest.mark.parametrize("classes", [("arterial", "arterial"), ("arterial", "local"),
                                     ("collector", "local")])
def test_right_turns_leave_room_for_their_inner_lane_edge(angle, classes):
    """Two roads meeting at ``angle`` degrees, a third opposite: every turn between them keeps
    a radius of at least half its width, so that a reader offsetting the lane from its centre
    line (OpenDRIVE: CommonRoad, pyxodr) sees no fold; the junction is no larger than that
    needs but for the kerb radius of its corners, which the right turn follows: no tighter
    than a car turns, no wider than the kerb asks."""
    from roadweaver_sumo.hdmap.geometry import bezier_sample
    from roadweaver_sumo.hdmap.junctions import CORNER_RADIUS

    a = np.radians(angle)
    nodes = {0: (200.0, 200.0), 1: (350.0, 200.0),
             2: (200.0 + 150.0 * np.cos(a), 200.0 + 150.0 * np.sin(a)),
             3: (200.0 - 150.0 * np.cos(a / 2), 200.0 - 150.0 * np.sin(a / 2))}
    hd = build_hdmap(_graph(nodes, [(0, 1, classes[0]), (0, 2, classes[1]), (0, 3, "local")]))
    turns = [lane for lane in hd.connectors() if lane.bezier is not None]
    _, _, curvature = bezier_sample(np.array([lane.bezier for lane in turns]))
    half = np.array([max(lane.width, lane.end_width) / 2.0 for lane in turns])
    room = 1.0 / np.abs(curvature).max(axis=1) - half
    assert room.min() > 0.0
    right = [k for k, lane in enumerate(turns) if lane.movement == "right"]
    tightest = (room + half)[right].min()
    assert 4.5 < tightest < CORNER_RADIUS + 2.0


def test_a_junction_grows_until_its_turns_fit_where_a_road_bends_into_it(monkeypatch):
    """A junction of a learned map (grid, 1.5 km, density 32, seed 5008, node 40) whose
    arterial bends 50 degrees within 17 m of it: measured 5 m out, the arterial meets its
    neighbour at another angle than its lane ends do, and the right turn between them folded
    (with square corners: the kerb radius gives this one room now, but not every acute one).
    The junction is widened until no turn folds; without widening one does."""
    from roadweaver_sumo.hdmap import build, junctions
    from roadweaver_sumo.hdmap.junctions import folding_turns

    monkeypatch.setattr(junctions, "CORNER_RADIUS", 0.0)

    arms = [("arterial", [(-4.12, 11.75), (-5.55, 13.6), (-7.27, 15.23), (-9.28, 16.63),
                          (-43.96, 37.34)]),
            ("arterial", [(-59.97, -1.84)]), ("local", [(-10.93, -59.0)]),
            ("arterial", [(58.56, 13.05)])]
    nodes = {0: (100.0, 100.0)} | {k: (100.0 + pts[-1][0], 100.0 + pts[-1][1])
                                   for k, (_, pts) in enumerate(arms, 1)}
    roads = [(0, k, cls, *[(100.0 + x, 100.0 + y) for x, y in pts[:-1]])
             for k, (cls, pts) in enumerate(arms, 1)]
    hd = build_hdmap(_graph(nodes, roads, 200.0))
    assert not folding_turns(hd.connectors())
    monkeypatch.setattr(build, "WIDEN_ROUNDS", 0)
    monkeypatch.setattr(build, "BAN_ROUNDS", 0)
    narrow = build_hdmap(_graph(nodes, roads, 200.0))
    assert {lane.junction for lane in folding_turns(narrow.connectors())} == {0}
    assert hd.junctions[0].radius > narrow.junctions[0].radius


def test_a_graph_without_roads_gives_an_empty_map():
    """Batched steps (road end directions, junction radii) take an empty batch."""
    G = new_road_graph(100.0, 100.0)
    G.add_node(0, xy=(1.0, 2.0))
    hd = build_hdmap(G)
    assert not hd.roads and not hd.junctions and not hd.lanes


def _outline(left: np.ndarray, right: np.ndarray) -> Polygon:
    """A lane's outline, its boundaries joined, at the millimetre a written file keeps (points
    that meet to 1e-13 m are one point there)."""
    return Polygon(np.round(np.vstack([left, right[::-1]]), 3))


def test_dead_end_uturn_outlines_never_cross_themselves():
    """At a dead end the innermost U-turn starts and ends its inner boundary on one centre line
    point; any loop through it makes the outline touch itself (CommonRoad counted such
    lanelets). The lane pivots on that point instead, on a half circle (an OpenDRIVE arc: a
    Bezier, offset by readers, looped round the point), and every connector's outline is a
    valid polygon, the U-turns between outer lanes (arterial arms) included."""
    hd = build_hdmap(t_junction())
    uturns = [lane for lane in hd.connectors() if lane.movement == "uturn"]
    assert {lane.junction for lane in uturns} == {1, 2, 3}  # the three dead ends
    for lane in hd.connectors():
        assert _outline(lane.left, lane.right).is_valid, lane.id
    for lane in uturns:  # a half circle between the lane ends, written as an OpenDRIVE arc
        (arc,) = lane.plan
        radius = np.linalg.norm(lane.centre[-1] - lane.centre[0]) / 2
        assert lane.bezier is None and arc.kind == "arc"
        assert arc.curvature == pytest.approx(1 / radius) and arc.length == pytest.approx(
            np.pi * radius)
        middle = (lane.centre[0] + lane.centre[-1]) / 2
        assert np.allclose(np.linalg.norm(lane.centre - middle, axis=1), radius)
    pivots = [lane for lane in uturns if (lane.left == lane.left[0]).all()]
    assert len(pivots) == 3 < len(uturns)  # the innermost pair of lanes at each dead end
    for lane in pivots:
        before, after = hd.lanes[lane.predecessors[0]], hd.lanes[lane.successors[0]]
        assert np.array_equal(lane.left[0], before.left[-1])
        assert np.allclose(after.left[0], lane.left[0], rtol=0.0, atol=1e-9)
        assert _outline(lane.left, lane.right).area > 0.5 * np.pi * (lane.width / 2) ** 2


def test_a_lane_section_starts_past_a_tight_bend_next_to_its_junction():
    """An arterial that turns 90 degrees on a 3 m radius 10 m from its junction: the junction
    trim lands just before the bend, whose arc at the lane section's start would fold the
    lanes (and read as a sharp turn to netconvert). The section starts past the bend
    instead; the junction's connectors take it, and no arc of the road is tighter than its
    class allows."""
    theta = np.radians(np.arange(0.0, 91.0, 10.0))
    bend = [(210.0 + 3.0 * np.sin(t), 203.0 - 3.0 * np.cos(t)) for t in theta]
    far = (bend[-1][0] + 150.0 * np.cos(theta[-1]), bend[-1][1] + 150.0 * np.sin(theta[-1]))
    nodes = {0: (200.0, 200.0), 1: far, 2: (50.0, 200.0), 3: (200.0, 50.0)}
    hd = build_hdmap(_graph(nodes, [(0, 1, "arterial", *bend), (0, 2, "arterial"),
                                    (0, 3, "local")]))
    road = next(r for r in hd.roads.values() if {r.from_node, r.to_node} == {0, 1})
    least = LANE_CONFIGS["arterial"].min_radius
    assert all(abs(p.curvature) * least <= 1.0 + 1e-9 for p in road.plan)
    start = road.sections[0].s_start if road.from_node == 0 else \
        arc_lengths(road.centreline)[-1] - road.sections[0].s_end
    assert start > 10.0 + 3.0 * np.radians(90.0)
    assert lane_reachability(hd) == 1.0


def test_a_turn_that_still_folds_in_a_junction_as_wide_as_its_roads_allow_is_not_offered(
        monkeypatch):
    """A procedural grid map (1 km, density 22, seed 5012, ring) where an arterial's lane ends 3 m
    short of where a collector's lanes meet it at 42 degrees: the 138-degree right turn
    between them folds however wide the junction (the collector is 31 m long, its trim
    capped). The turn is banned and the arterial lane it entered is entered by the
    neighbouring lane's left turn instead: every road lane still leaves and is entered
    through its junctions (a lane entered from nowhere makes netconvert warn, one ending in
    a junction is a dead end to CARLA). Without the ban the folding turn is there."""
    from roadweaver_sumo.api import generate_map
    from roadweaver_sumo.hdmap import build
    from roadweaver_sumo.hdmap.junctions import folding_turns
    from roadweaver_sumo.spec import ScenarioSpec

    spec = ScenarioSpec(width=1000, height=1000, density=22, style="grid",
                        skeleton="procedural", seed=5012, vehicles=10,
                        boundary="ring")
    hd = generate_map(spec)
    assert folding_turns(hd.connectors()) == []
    assert lane_reachability(hd) == 1.0
    entered = {lane.successors[0] for lane in hd.connectors()}
    left = {lane.predecessors[0] for lane in hd.connectors()}
    for lane in hd.lanes.values():
        if lane.kind != "connector":
            assert lane.id in entered and lane.id in left, lane.id
    monkeypatch.setattr(build, "BAN_ROUNDS", 0)
    assert [lane.movement for lane in folding_turns(generate_map(spec).connectors())] == ["right"]


def test_no_shallow_left_at_a_fork_where_there_is_another_way():
    """A fork: the way ahead bends 40 degrees right, the other branch 45 degrees left. The left
    branch's path would run beside the oncoming traffic's (SUMO let an oncoming car clip a
    left-turner waiting there), so it is left out: the stem goes on to the right branch only,
    and the left branch is still entered, from the right branch."""
    nodes = {0: (200, 200), 1: (50, 200), 2: (200 + 150 * np.cos(-0.7), 200 + 150 * np.sin(-0.7)),
             3: (200 + 150 * np.cos(0.785), 200 + 150 * np.sin(0.785))}
    hd = build_hdmap(_graph(nodes, [(1, 0, "collector"), (0, 2, "collector"), (0, 3, "local")]))
    roads = {frozenset((r.from_node, r.to_node)): r for r in hd.roads.values()}
    stem, right, left = (roads[frozenset(e)].id for e in ((0, 1), (0, 2), (0, 3)))
    moves = {(hd.lanes[c.predecessors[0]].road, hd.lanes[c.successors[0]].road): c.movement
             for c in hd.connectors() if c.junction == 0}
    assert (stem, right) in moves and (stem, left) not in moves
    assert (right, left) in moves
    one_way = _graph(nodes, [(1, 0, "collector"), (0, 2, "collector"), (0, 3, "local")])
    one_way.edges[0, 2]["one_way"] = True  # the right branch only leaves: the left is the
    hd = build_hdmap(one_way)                # last way into the left branch, and is kept
    moves = {(hd.lanes[c.predecessors[0]].road, hd.lanes[c.successors[0]].road): c.movement
             for c in hd.connectors() if c.junction == 0}
    assert moves[(stem, left)] == "left"


def test_turn_lanes_without_a_way_straight_on_go_where_there_is_room_for_them():
    """Three lanes arrive where the road ends at a T (no way straight on): a one-lane road to
    the right, a two-lane road and a one-lane road to the left. Two lanes turn left, each
    into its own lane of the two-lane road, and only the leftmost into the one-lane road:
    both into one lane would merge inside the junction, where two cars turning side by side
    touch (a SUMO junction collision at a learned map's traffic light)."""
    from roadweaver_sumo.hdmap.movements import Approach, lane_plan

    def approach(road, lanes):
        return Approach(road, lanes, np.array([1.0, 0.0]))

    arrival = approach(0, ["a0", "a1", "a2"])
    moves = [(approach(1, ["r0"]), "right"), (approach(2, ["w0", "w1"]), "left"),
             (approach(3, ["n0"]), "left")]
    plan = lane_plan(arrival, moves)
    assert sorted((a, b) for a, b, _ in plan) == [
        ("a0", "r0"), ("a1", "w0"), ("a2", "n0"), ("a2", "w1")]
    assert max(Counter(b for _, b, _ in plan).values()) == 1
