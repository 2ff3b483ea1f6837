"""The pedestrian network of a lanelet2 map (maps with sidewalks): walkway lanelets on the
sidewalks, crosswalk lanelets on SUMO's crossings, and walkway lanelets across each walking
area joining the ends SUMO joins there (``hdmap.crossings``), so that lanelet2's router for
pedestrians finds the walks SUMO's pedestrians take.

lanelet2 links lanelets by shared end points: a lanelet follows another where the other's end
points are its start points, and pedestrians may walk a lanelet either way (``one_way=no``),
so a lanelet across a walking area runs from one end it joins to the other, starting on the
points where the first lanelet is left and ending on those where the second is entered.
"""

from __future__ import annotations

from dataclasses import dataclass
from itertools import combinations

import numpy as np

from ..hdmap.model import HDMap

KERB = (("type", "curbstone"), ("subtype", "low"))  # a sidewalk's road-side edge
EDGE = (("type", "road_border"),)  # a sidewalk's outer edge
VIRTUAL = (("type", "virtual"),)
ZEBRA = (("type", "zebra_marking"),)
MIDDLE_HALF_WIDTH = 1.0  # m: the middle edge of a lanelet pair across a sharp turn
TURNS = 16  # directions tried for that edge
MIDDLE_REACH = (1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 8.0)  # m: how far from the middle it may be moved
MIN_BOUND_M = 0.05
CHUNK = 512  # lanelets whose middle edges are searched together


@dataclass
class WalkLanelet:
    """A pedestrian lanelet: its id, subtype, bound ways and its id in the source map."""

    id: int
    subtype: str
    left: int
    right: int
    source: str


def walk_elements(hd: HDMap, ids) -> tuple[dict[int, tuple], list[WalkLanelet]]:
    """The ways (way id -> (node ids, tags)) and lanelets of ``hd``'s pedestrian network;
    ``ids`` is the file's id counter (``export.lanelet2._Ids``)."""
    ways: dict[int, tuple] = {}
    ends: dict[tuple[str, str], tuple[int, int]] = {}  # (lanelet, end) -> (left, right) node
    lanelets = []

    def way(points, tags) -> tuple[int, list[int]]:
        first = ids.nodes(points)
        nodes = list(range(first, first + len(points)))
        wid = ids.new()
        ways[wid] = (nodes, tags)
        return wid, nodes

    def lanelet(source, subtype, left_points, right_points, left_tags, right_tags) -> None:
        left, left_nodes = way(left_points, left_tags)
        right, right_nodes = way(right_points, right_tags)
        ends[source, "start"] = (left_nodes[0], right_nodes[0])
        ends[source, "end"] = (left_nodes[-1], right_nodes[-1])
        lanelets.append(WalkLanelet(ids.new(), subtype, left, right, source))

    for lane_id in sorted(hd.sidewalks):
        walk = hd.sidewalks[lane_id]
        lanelet(lane_id, "walkway", walk.left, walk.right, KERB, EDGE)
    for crossing in hd.crosswalks:
        a, b = crossing.centre[0], crossing.centre[-1]
        ahead = (b - a) / np.hypot(*(b - a))
        side = np.array([-ahead[1], ahead[0]]) * crossing.width / 2
        lanelet(crossing.id, "crosswalk", [a + side, b + side], [a - side, b - side],
                ZEBRA, ZEBRA)
    def connector(source: str, start: tuple[int, int], end: tuple[int, int]) -> None:
        wids = []
        for nodes in ([start[0], end[0]], [start[1], end[1]]):
            wid = ids.new()
            ways[wid] = (nodes, VIRTUAL)
            wids.append(wid)
        lanelets.append(WalkLanelet(ids.new(), "walkway", *wids, source))

    pairs = []  # every two ends a walking area joins: (source, start, end)
    for area, ports in hd.walking_areas.items():
        known = [(kind, source, end) for kind, source, end in ports if (source, end) in ends]
        for k, (first, second) in enumerate(combinations(known, 2)):
            pairs.append((f"{area}_{k}", _leaving(ends, first), _entering(ends, second)))
    points = np.array([[ids.xy(n) for n in (*start, *end)] for _, start, end in pairs])
    middles = _middle_edges(*points.reshape(-1, 4, 2).transpose(1, 0, 2))
    for (source, start, end), middle in zip(pairs, middles):
        if middle is None:
            connector(source, start, end)
            continue
        middle = (ids.node(middle[0]), ids.node(middle[1]))  # a turn too sharp for one lanelet
        connector(f"{source}a", start, middle)
        connector(f"{source}b", middle, end)
    return ways, lanelets


def _middle_edges(la, ra, lb, rb) -> list:
    """For lanelets from edges (la, ra) to edges (lb, rb) (arrays of shape (n, 2)): None
    where lanelet2 reads the lanelet as written (its loader turns a bound round where the
    bounds' ends lie closer crosswise than pairwise, and a lanelet so turned follows
    nothing), else the (left, right) points of a middle edge ``MIDDLE_HALF_WIDTH`` either side
    of a point near the middle of the two edges, turned so that lanelet2 reads both halves as
    written: the first turn that does at the middle, else at points ``MIDDLE_REACH`` m from it,
    the nearest first (two edges that cross each other, at a tight corner, need the middle
    edge off to one side, and the ends of a wide corner's sidewalks one far enough out that no
    half's bounds cross); else across the way from the one edge's centre to the other's."""
    middles: list = [None] * len(la)
    bent = np.flatnonzero(~_aligned_points(la, ra, lb, rb))
    for start in range(0, len(bent), CHUNK):  # arrays small enough for the CPU's caches
        part = bent[start:start + CHUNK]
        for k, middle in zip(part, _middle_edges_of(la[part], ra[part], lb[part], rb[part])):
            middles[k] = middle
    return middles


def _middle_edges_of(la, ra, lb, rb) -> list:
    """The middle edges of lanelets that need one (``_middle_edges``): each reach is tested
    for all lanelets still without a middle edge at once."""
    centre = (la + ra + lb + rb) / 4
    ahead = (lb + rb) / 2 - (la + ra) / 2
    best = np.arctan2(ahead[:, 1], ahead[:, 0]) + np.pi / 2  # left of the way ahead
    turns = best[:, None] + np.arange(TURNS) * 2 * np.pi / TURNS
    unit = np.stack([np.cos(turns), np.sin(turns)], axis=-1)  # (lanelet, turn, xy)
    across = MIDDLE_HALF_WIDTH * unit[:, None]  # (lanelet, 1, turn, xy)
    square = MIDDLE_HALF_WIDTH * np.stack([np.cos(best), np.sin(best)], axis=-1)
    middles = [(c + s, c - s) for c, s in zip(centre, square)]  # where no turn does
    todo = np.arange(len(la))  # lanelets still without a middle edge
    for reach in (None, *MIDDLE_REACH):
        if not len(todo):
            break
        places = centre[todo, None] if reach is None else centre[todo, None] + reach * unit[todo]
        left, right = places[:, :, None] + across[todo], places[:, :, None] - across[todo]
        a, b, c, d = (e[todo, None, None] for e in (la, ra, lb, rb))
        fits = (_aligned_points(a, b, left, right)
                & _aligned_points(left, right, c, d)).reshape(len(todo), -1)
        first, found = fits.argmax(axis=1), fits.any(axis=1)
        left, right = left.reshape(len(todo), -1, 2), right.reshape(len(todo), -1, 2)
        for i in np.flatnonzero(found):  # copies: a view would keep the whole array alive
            middles[todo[i]] = (left[i, first[i]].copy(), right[i, first[i]].copy())
        todo = todo[~found]
    return middles


def _aligned_points(la, ra, lb, rb):
    """lanelet2's test (``geometry::align`` when it loads a lanelet): the middle of the right
    bound must lie right of the left bound and the middle of the left bound left of the right
    one, else it turns that bound round. Bounds shorter than ``MIN_BOUND_M`` fail: their side
    is a rounding error. The two bounds must not cross either: the lanelet's outline would be
    a bow-tie, which lanelet2 loads but CommonRoad, shapely and area checks reject. Points are
    arrays of shape (..., 2); the answer has their shape less the last axis."""
    long_enough = np.minimum(_length(lb - la), _length(rb - ra)) >= MIN_BOUND_M
    return (long_enough & (_cross(lb - la, (ra + rb) / 2 - la) < -MIN_BOUND_M)
            & (_cross(rb - ra, (la + lb) / 2 - ra) > MIN_BOUND_M)
            & ~_segments_cross(la, lb, ra, rb))


def _segments_cross(a, b, c, d):
    """Whether segment a-b and segment c-d cross (each one's ends on either side of the
    other's line)."""
    return ((_cross(b - a, c - a) * _cross(b - a, d - a) < 0)
            & (_cross(d - c, a - c) * _cross(d - c, b - c) < 0))


def _cross(a, b):
    return a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]


def _length(v):
    return np.hypot(v[..., 0], v[..., 1])


def _leaving(ends: dict, port: tuple) -> tuple[int, int]:
    """(left, right) nodes where a pedestrian leaves the lanelet of ``port`` into the walking
    area: its end points if it ends there, else its start points seen walking it backwards."""
    _, source, end = port
    left, right = ends[source, end]
    return (left, right) if end == "end" else (right, left)


def _entering(ends: dict, port: tuple) -> tuple[int, int]:
    """(left, right) nodes where a pedestrian enters the lanelet of ``port``: its start
    points if it starts there, else its end points seen walking it backwards."""
    _, source, end = port
    left, right = ends[source, end]
    return (left, right) if end == "start" else (right, left)
