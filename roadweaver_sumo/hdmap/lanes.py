"""Lane configurations by road class and directional road lanes (paper Algorithm 1: RefineRoadGraph,
AssignLaneConfig, GenerateLaneBoundaries, ConstructDirectionalLanes).

Right-hand traffic: lanes driving along the reference line lie right of it, the others left of
it; a two-way road has its class's lane count in both directions but for a left-turn bay
(``turn_bays``: one lane more on the direction arriving at a light), a one-way road
(``one_way``) its lanes centred on the reference line. A road with sidewalks has one right of
each driving direction, lane index 0 as in SUMO; its driving lanes are then 1..n.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from functools import cache

import networkx as nx
import numpy as np

from .geometry import arc_lengths, cut, dedupe, offset_along, unit_tangent
from .model import Lane, LaneSection, Road, road_lane_id
from .reference import Piece, fillet_plans, plan_points


@dataclass(frozen=True)
class LaneConfig:
    """Lanes per driving direction, lane width (m), speed limit (m/s) and SUMO edge priority."""

    lanes: int
    width: float
    speed: float
    priority: int

    @property
    def half_width(self) -> float:
        """Distance from the reference line to the road's outer edge, metres."""
        return self.lanes * self.width

    @property
    def min_radius(self) -> float:
        """The tightest arc of the reference line, metres (:func:`bend_radius`)."""
        return bend_radius(self.half_width)


def bend_radius(half_width: float) -> float:
    """The tightest arc of a reference line whose lanes reach ``half_width`` from it, metres:
    the outer lane edge on the inside of a bend keeps ``BEND_MARGIN`` of radius (no lane folds
    over), and no arc is tighter than ``MIN_TURN_RADIUS``."""
    return max(MIN_TURN_RADIUS, half_width + BEND_MARGIN)


LANE_CONFIGS: dict[str, LaneConfig] = {
    "arterial": LaneConfig(lanes=2, width=3.5, speed=13.89, priority=3),
    "collector": LaneConfig(lanes=1, width=3.25, speed=11.11, priority=2),
    "local": LaneConfig(lanes=1, width=3.0, speed=8.33, priority=1),
}

SIDEWALK_WIDTH = 2.0  # m, SUMO's default sidewalk width
MIN_TURN_RADIUS = 5.0  # m: cars turn on 5 m or more (pyxodr fails on arcs under ~1.5 m)
BEND_MARGIN = 1.0  # m: radius left to a lane edge on the inside of the tightest bend

# Junction trims never take more than this share of a road from each end, so that short roads
# between wide junctions keep a lane section of at least MIN_SECTION_SHARE of their length.
MAX_TRIM_SHARE = 0.4
MIN_SECTION_SHARE = 1.0 - 2 * MAX_TRIM_SHARE

# m: a lane section starts and ends straight for this far. Where a junction trim cuts a road
# just before one of its bends, the stub of a few decimetres before the bend would become, in
# the OpenDRIVE plan view, a bend too tight for any reader (netconvert warns of "sharp turns"
# of 1-7 m radius); the road graph's bends turn at most ~30 degrees a vertex, whose 5 m fillet
# and 1 m end line (``reference.fillet_plans``) need 2.4 m.
END_STRAIGHT = 3.0
#: m: a bend too tight for the road's class this close to a lane section's end moves the end
#: past it (``_past_end_bends``).
END_BEND = 10.0


def make_roads(G: nx.Graph, sidewalk_width: float = 0.0,
               speeds: dict[str, float] | None = None) -> dict[int, Road]:
    """One road per RoadGraph edge with its class's lane configuration (AssignLaneConfig; its own
    lane count where ``hdmap.lane_counts`` gave it one), sidewalks ``sidewalk_width`` wide
    (0: none) and the speed limit of its class, or of ``speeds`` (km/h by class) where
    given.

    Roads are numbered in sorted node-pair order so ids do not depend on insertion order;
    centrelines lose zero-length segments (RefineRoadGraph: geometric regularisation).
    """
    roads: dict[int, Road] = {}
    for rid, (u, v) in enumerate(sorted(tuple(sorted(e)) for e in G.edges)):
        data = G.edges[u, v]
        start = data["start"]
        cfg = LANE_CONFIGS[data["road_class"]]
        to_node = v if start == u else u
        roads[rid] = Road(
            id=rid,
            from_node=start,
            to_node=to_node,
            centreline=dedupe(data["coords"]),
            road_class=data["road_class"],
            priority=cfg.priority,
            speed=speeds[data["road_class"]] / 3.6 if data["road_class"] in (speeds or {})
            else cfg.speed,
            lane_width=cfg.width,
            lane_count=lanes_of(data),
            sections=[],
            sidewalk_width=sidewalk_width,
            bay=None if "bay_to" not in data else "f" if data["bay_to"] == to_node else "b",
            one_way=bool(data.get("one_way")),  # a roundabout's ring; one_way picks streets
        )
    return roads


def lanes_of(data: dict) -> int:
    """Driving lanes per direction of a road graph edge: its own (``--lanes``,
    ``hdmap.lane_counts``) or its class's."""
    return data.get("lanes", LANE_CONFIGS[data["road_class"]].lanes)


def lane_count(road: Road, direction: str) -> int:
    """Driving lanes of one direction of ``road``: its own, one more with a turn bay."""
    return road.lane_count + (road.bay == direction)


def half_width(road: Road) -> float:
    """Distance from the reference line to the outer edge of the road's wider side, metres."""
    return road.lane_width * (road.lane_count + (road.bay is not None))


def plan_reference_lines(roads: list[Road], trims: list[tuple[float, float]]) -> None:
    """Give each road its lane section between its junction trims (``trims``: at its start and
    end node) and its reference line there as lines and arcs (``road.plan``, paper Algorithm 1:
    RefineRoadGraph), all roads in one batch. The centreline is cut back by the trims, with
    no vertex within ``END_STRAIGHT`` of a cut end, and its corners filleted with arcs of at
    least the class's ``min_radius``."""
    radii = [bend_radius(half_width(road)) + road.sidewalk_width for road in roads]
    cuts = []
    for road, (trim_start, trim_end) in zip(roads, trims, strict=True):
        length = float(arc_lengths(road.centreline)[-1])
        cuts.append((min(trim_start, MAX_TRIM_SHARE * length),
                     length - min(trim_end, MAX_TRIM_SHARE * length), length))
    plans, lines = _filleted(roads, cuts, radii)
    moved = []
    for k, (plan, (s0, s1, length)) in enumerate(zip(plans, cuts, strict=True)):
        ends = _past_end_bends(plan, radii[k], s0, s1, length)
        if ends != (s0, s1):
            cuts[k] = (*ends, length)
            moved.append(k)
    if moved:
        again, again_lines = _filleted([roads[k] for k in moved], [cuts[k] for k in moved],
                                       [radii[k] for k in moved])
        for k, plan, line in zip(moved, again, again_lines, strict=True):
            plans[k], lines[k] = plan, line
    for road, (s0, s1, _), line, plan in zip(roads, cuts, lines, plans, strict=True):
        first = _first_lane(road)
        ids = {d: [road_lane_id(road.id, d, first + k) for k in range(lane_count(road, d))]
               for d in _directions(road)}
        ids.setdefault("b", [])
        road.sections = [LaneSection(s0, s1, ids["f"], ids["b"])]
        road.plan = plan
        road.reference = plan_points(plan, line[0], line[-1])


def _filleted(roads: list[Road], cuts: list[tuple[float, float, float]], radii: list[float]):
    """The plans and cut centrelines of ``roads`` between their ``cuts`` (start, end, length)."""
    lines = [cut(road.centreline, s0, s1, gap=END_STRAIGHT)
             for road, (s0, s1, _) in zip(roads, cuts, strict=True)]
    return fillet_plans(lines, radii), lines


def _past_end_bends(plan: list[Piece], least: float, s0: float, s1: float,
                    length: float) -> tuple[float, float]:
    """The lane section's ends moved past the bends tighter than ``least`` that begin (end)
    within ``END_BEND`` of them (into the junction, whose connectors take the bend), as far as
    a lane section of ``MIN_SECTION_SHARE`` of the road is left. Such a bend is what is left of
    a road-graph bend that the junction trim cut into; at a lane section's end it folds the
    lanes and reads as a sharp turn to netconvert. The trims' own cap (``MAX_TRIM_SHARE``) may
    be passed at one end: on a short road whose bend lies next to one junction, that junction
    takes it."""
    tight = [p for p in plan if p.kind == "arc" and abs(p.curvature) * least > 1.0 + 1e-9]
    if not tight:
        return s0, s1
    total = plan[-1].s + plan[-1].length
    keep = MIN_SECTION_SHARE * length
    near_start = [p for p in tight if p.s < END_BEND]
    if near_start:
        s0 = max(s0, min(s0 + near_start[-1].s + near_start[-1].length, s1 - keep))
    near_end = [p for p in tight if total - p.s - p.length < END_BEND]
    if near_end:
        s1 = min(s1, max(s1 - (total - near_end[0].s), s0 + keep))
    return s0, s1


def build_road_lanes(road: Road) -> tuple[list[Lane], list[Lane]]:
    """Offset a road's reference line (:func:`plan_reference_lines`) into lane boundaries and
    build the directional lanes of its driving directions, and its sidewalks (one right of
    each direction, if the road has them)."""
    points, tangents = road.reference
    counts = tuple(lane_count(road, d) for d in _directions(road))
    offsets = _lane_offsets(road.road_class, road.one_way, road.sidewalk_width, counts)
    lines = offset_along(points, tangents, offsets[:, None])
    lanes, sidewalks = [], []
    first = 0
    for d, n in zip(_directions(road), counts, strict=True):
        size = 2 * n + 1 + 2 * bool(road.sidewalk_width)  # lines of this direction
        part = lines[first : first + size]
        first += size
        if d == "b":  # offset left of the reference line: reversed into driving direction
            part = part[:, ::-1]
        lanes += _directional_lanes(road, d, part[: n + 1], part[n + 1 : 2 * n + 1])
        if road.sidewalk_width:
            sidewalks.append(_sidewalk(road, d, inner=part[0], outer=part[2 * n + 1],
                                       centre=part[2 * n + 2]))
    return lanes, sidewalks


def _directions(road: Road) -> str:
    return "f" if road.one_way else "fb"


def _first_lane(road: Road) -> int:
    """Index of a driving direction's outermost driving lane: 1 beside a sidewalk (index 0,
    as SUMO numbers an edge's lanes), else 0."""
    return 1 if road.sidewalk_width else 0


@cache
def _lane_offsets(road_class: str, one_way: bool, sidewalk: float,
                  counts: tuple[int, ...]) -> np.ndarray:
    """Left offsets of a road's lines from its reference line: first those of its ``f`` lanes
    (boundaries, centres, then the sidewalk's outer edge and centre), then the same to the
    left for its ``b`` lanes (one array for one offsetting call); ``counts``: the lanes of
    each direction. A one-way road has no ``b`` lanes; its driving lanes are centred on the
    reference line, its sidewalk right of them, as SUMO lays out an edge of
    ``spreadType="center"`` (centred with its sidewalk, SUMO's cars drove a metre off the
    OpenDRIVE lane)."""
    w = LANE_CONFIGS[road_class].width

    def right_of(n: int) -> np.ndarray:
        # how far right of the driving direction the cross-section's left edge lies: the
        # reference line itself, or half the driving lanes left of it on a one-way road
        start = -n * w / 2.0 if one_way else 0.0
        # boundary j at (n - j) lane widths right of that edge (j = 0 the outermost), then
        # lane k's centre at (n - k - 0.5) widths
        right = start + w * np.concatenate([np.arange(n, -1, -1), np.arange(n, 0, -1) - 0.5])
        if sidewalk:
            right = np.concatenate([right, start + n * w + np.array([sidewalk, sidewalk / 2.0])])
        return right

    if one_way:
        return -right_of(counts[0])
    return np.concatenate([-right_of(counts[0]), right_of(counts[1])])


def _directional_lanes(road: Road, direction: str, bounds: np.ndarray, centres: np.ndarray):
    """The lanes of one driving direction, the outermost first, from their boundaries and
    centres (all in driving direction), with neighbour links between them."""
    cfg = LANE_CONFIGS[road.road_class]
    n, w = lane_count(road, direction), cfg.width
    first = _first_lane(road)
    ids = [road_lane_id(road.id, direction, first + k) for k in range(n)]
    return [
        Lane(
            id=ids[k],
            kind="road",
            road_class=road.road_class,
            width=w,
            end_width=w,
            speed=road.speed,
            centre=centres[k],
            left=bounds[k + 1],
            right=bounds[k],
            road=road.id,
            direction=direction,
            index=first + k,
            left_neighbour=ids[k + 1] if k + 1 < n else None,
            right_neighbour=ids[k - 1] if k > 0 else None,
        )
        for k in range(n)
    ]


def _sidewalk(road: Road, direction: str, inner: np.ndarray, outer: np.ndarray,
              centre: np.ndarray) -> Lane:
    """The sidewalk right of a driving direction: lane index 0, beside the outermost lane."""
    return Lane(id=road_lane_id(road.id, direction, 0), kind="sidewalk",
                road_class=road.road_class, width=road.sidewalk_width,
                end_width=road.sidewalk_width, speed=road.speed, centre=centre, left=inner,
                right=outer, road=road.id, direction=direction, index=0)


@dataclass
class LaneEnds:
    """First and last points of lane centres and the unit driving directions there, one row
    per lane (``row`` maps lane ids to rows). Junction planning and connectors read every
    lane end; one batch costs far less than thousands of two-point numpy calls, and gives the
    same bits as ``geometry.start_tangent`` / ``end_tangent`` of each centre."""

    row: dict[str, int]
    start: np.ndarray  # (m, 2)
    start_tangent: np.ndarray  # (m, 2)
    end: np.ndarray  # (m, 2)
    end_tangent: np.ndarray  # (m, 2)


def lane_ends(lanes: Iterable[Lane]) -> LaneEnds:
    """The :class:`LaneEnds` of ``lanes``, in their order."""
    lanes = list(lanes)
    first = np.array([lane.centre[:2] for lane in lanes]).reshape(-1, 2, 2)
    last = np.array([lane.centre[-2:] for lane in lanes]).reshape(-1, 2, 2)
    return LaneEnds(
        row={lane.id: i for i, lane in enumerate(lanes)},
        start=first[:, 0],
        start_tangent=unit_tangent(first[:, 1] - first[:, 0]),
        end=last[:, 1],
        end_tangent=unit_tangent(last[:, 1] - last[:, 0]),
    )
