"""Reference lines as lines and arcs (``hdmap.reference``): arcs no tighter than a car turns
nor than a road's lanes need, plans that keep the polyline's ends, and lanes offset from them
that never fold over."""

import itertools
import math

import numpy as np
import pytest
import shapely

from roadweaver_sumo.hdmap.lanes import (
    LANE_CONFIGS,
    MAX_TRIM_SHARE,
    MIN_SECTION_SHARE,
    MIN_TURN_RADIUS,
    plan_reference_lines,
)
from roadweaver_sumo.hdmap.model import Road
from roadweaver_sumo.hdmap.reference import (
    ARC_STEP,
    END_LINE,
    MAX_DEVIATION,
    Piece,
    fillet_plans,
    plan_points,
)


def _end_pose(piece) -> tuple[float, float, float]:
    """Position and heading at the end of a line or arc piece."""
    if piece.kind == "line":
        return (piece.x + piece.length * math.cos(piece.hdg),
                piece.y + piece.length * math.sin(piece.hdg), piece.hdg)
    k, hdg = piece.curvature, piece.hdg + piece.length * piece.curvature
    return (piece.x + (math.sin(hdg) - math.sin(piece.hdg)) / k,
            piece.y - (math.cos(hdg) - math.cos(piece.hdg)) / k, hdg)


def _tight_lines() -> list[np.ndarray]:
    """Reference lines with the corners that gave arcs of decimetres: a bend of 20 cm steps
    (radius 1 m); a curve cut 0.3 m before a vertex at both ends (as the lane section's cut
    leaves them); a 0.3 m jog on a gentle bend; and, last, one corner 0.4 m from
    the end, which no easing within tolerance can widen."""
    bend = [(30.0 + math.sin(a), 1.0 - math.cos(a)) for a in np.linspace(0.0, math.pi / 2, 9)]
    curve = [(0.3 + 40.0 * math.sin(a), 40.0 - 40.0 * math.cos(a))
             for a in np.radians(np.arange(0.0, 50.0, 7.0))]
    end = np.array(curve[-1]) + 0.3 * np.array([math.cos(np.radians(49.0)),
                                                math.sin(np.radians(49.0))])
    return [np.array([(0.0, 0.0), *bend, (31.0, 30.0)]),
            np.array([(0.0, 0.0), *curve, tuple(end)]),
            np.array([(0.0, 0.0), (10.0, 0.5), (20.0, 0.5), (20.5, 0.8), (30.0, 0.8),
                      (40.0, 0.3)]),
            np.array([(0.0, 0.0), (0.4, 0.0), (30.0, 5.0)])]


def test_fillets_are_no_tighter_than_a_car_turns_and_keep_the_ends():
    """pyxodr fails on arcs of under ~1.5 m radius, and netconvert reads a sharp turn where a
    road ends in an arc: every arc that easing can widen is at least MIN_TURN_RADIUS, every plan
    starts and ends with a line, and the plan is G1 from the first vertex along the first
    segment to the last vertex along the last segment (lane ends stay where the HD map has
    them)."""
    lines = _tight_lines()
    plans = fillet_plans(lines, MIN_TURN_RADIUS)
    for plan in plans[:-1]:
        assert all(abs(p.curvature) <= 1.0 / MIN_TURN_RADIUS + 1e-12 for p in plan)
    assert max(abs(p.curvature) for p in plans[-1]) > 1.0 / MIN_TURN_RADIUS  # as tight as it was
    for line, plan in zip(lines, plans, strict=True):
        assert plan[0].kind == plan[-1].kind == "line"
        assert (plan[0].x, plan[0].y) == tuple(line[0])
        first, last = np.diff(line[:2], axis=0)[0], np.diff(line[-2:], axis=0)[0]
        assert plan[0].hdg == pytest.approx(math.atan2(first[1], first[0]), abs=1e-12)
        for before, after in itertools.pairwise(plan):
            x, y, hdg = _end_pose(before)
            assert (after.x, after.y) == pytest.approx((x, y), abs=1e-9)
            assert math.remainder(after.hdg - hdg, math.tau) == pytest.approx(0.0, abs=1e-9)
            assert after.s == pytest.approx(before.s + before.length, abs=1e-9)
        x, y, hdg = _end_pose(plan[-1])
        assert (x, y) == pytest.approx(tuple(line[-1]), abs=1e-9)
        assert math.remainder(hdg - math.atan2(last[1], last[0]), math.tau) == pytest.approx(
            0.0, abs=1e-9)
    (bend,) = fillet_plans(lines[:1], MIN_TURN_RADIUS)  # the bend still turns by a quarter turn, on arcs
    assert sum(p.length * p.curvature for p in bend) == pytest.approx(math.pi / 2)


def test_fillets_end_straight_and_stay_near_the_corner():
    """A road ends with END_LINE of line where its last segment is long enough, and an arc
    between long segments stays within MAX_DEVIATION of the corner it replaces."""
    (short_end,) = fillet_plans([np.array([(0.0, 0.0), (50.0, 0.0), (52.0, 2.0)])], 5.0)
    assert [p.kind for p in short_end] == ["line", "arc", "line"]
    assert short_end[-1].length == pytest.approx(END_LINE)
    (gentle,) = fillet_plans([np.array([(0.0, 0.0), (120.0, 0.0), (240.0, 30.0)])], 5.0)
    arc = gentle[1]
    radius, half_turn = 1.0 / arc.curvature, arc.length * arc.curvature / 2.0
    assert radius * (1.0 / math.cos(half_turn) - 1.0) == pytest.approx(MAX_DEVIATION)


def test_each_road_class_gets_arcs_wider_than_its_half_width():
    """A bend of 20 cm steps (radius 1 m): an arterial's plan turns on arcs of its class's
    least radius, wider than its 7 m half width, a local road's on 5 m arcs; both still turn by
    a quarter turn."""
    (line,) = _tight_lines()[:1]
    radii = [LANE_CONFIGS[c].min_radius for c in ("arterial", "local")]
    assert radii[0] > LANE_CONFIGS["arterial"].half_width and radii[1] == MIN_TURN_RADIUS
    for plan, least in zip(fillet_plans([line, line], radii), radii, strict=True):
        assert min(1.0 / abs(p.curvature) for p in plan if p.kind == "arc") >= least - 1e-9
        assert sum(p.length * p.curvature for p in plan) == pytest.approx(math.pi / 2)


def test_lanes_offset_from_a_sampled_plan_never_fold():
    """The outer lane edges of an arterial (7 m each side) offset along the sampled plan's
    normals form a simple outline on every test line that easing can widen, and the samples
    keep the polyline's end points exactly."""
    half = LANE_CONFIGS["arterial"].half_width
    lines = _tight_lines()[:-1]
    plans = fillet_plans(lines, LANE_CONFIGS["arterial"].min_radius)
    for line, plan in zip(lines, plans, strict=True):
        points, tangents = plan_points(plan, line[0], line[-1])
        assert (points[0] == line[0]).all() and (points[-1] == line[-1]).all()
        normal = np.column_stack([-tangents[:, 1], tangents[:, 0]])
        outline = np.vstack([points + half * normal, (points - half * normal)[::-1]])
        assert shapely.Polygon(outline).is_valid


def test_a_short_road_bending_next_to_its_junction_leaves_the_bend_to_the_junction():
    """A 34 m collector (learned grid 2.5 km d99 s5192, road 170): 9 m out of its junction it
    turns a quarter turn on a 6 m curve of 1 m steps, then runs 14 m to the next junction. The
    junction trim cuts into the curve; what is left of it fits no 5 m arc within the first
    ``END_BEND``, and a lane section that started there read to netconvert as a sharp turn of
    8.55 m. The lane section starts past the bend, even beyond the trims' usual cap, and
    keeps a fifth of the road."""
    line = np.array([(418.14, 2148.25), (415.9, 2139.76), (415.64, 2138.56), (415.53, 2137.48),
                     (415.56, 2136.53), (415.75, 2135.7), (416.09, 2134.99), (416.57, 2134.41),
                     (417.2, 2133.95), (417.99, 2133.62), (418.92, 2133.41), (420.0, 2133.32),
                     (421.23, 2133.36), (435.04, 2134.41)])
    cfg = LANE_CONFIGS["collector"]
    road = Road(id=0, from_node=0, to_node=1, centreline=line, road_class="collector",
                priority=cfg.priority, speed=cfg.speed, lane_width=cfg.width,
                lane_count=cfg.lanes, sections=[])
    plan_reference_lines([road], [(6.09, 4.59)])
    length = float(np.hypot(*np.diff(line, axis=0).T).sum())
    (section,) = road.sections
    radii = [1.0 / abs(p.curvature) for p in road.plan if p.kind == "arc"]
    assert min(radii, default=math.inf) >= cfg.min_radius - 1e-9
    assert section.s_start > MAX_TRIM_SHARE * length
    assert section.s_end - section.s_start >= MIN_SECTION_SHARE * length - 1e-9


@pytest.mark.parametrize("noise", [-1e-13, 0.0, 1e-13])
def test_a_half_circle_gets_the_same_samples_whatever_its_last_bits(noise):
    """A dead end's U-turn turns exactly 36 steps of 5 degrees; another CPU's rounding puts
    its turn a last bit either side of that, and its lanelet2 bounds must not gain a point."""
    radius = 3.5
    start, end = np.array([0.0, 0.0]), np.array([0.0, 2 * radius])
    arc = Piece("arc", 0.0, 0.0, 0.0, 0.0, math.pi * radius * (1 + noise), curvature=1 / radius)
    points, _ = plan_points([arc], start, end)
    assert round(math.pi / ARC_STEP) == 36
    assert len(points) == 37
