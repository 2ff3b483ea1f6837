"""Road reference lines as lines and circular arcs (paper Algorithm 1, RefineRoadGraph:
geometric regularisation), the one geometry every output is built from: the HD map lanes are
offset from these plans, sampled, and the OpenDRIVE plan view writes them as they are (ASAM
OpenDRIVE 1.7, chapter "Geometry": straight line, arc).

Each road's arcs are at least its class's ``LaneConfig.min_radius``: wider than the road's half
width, so that no lane boundary offset from an arc folds over (a reader that offsets lanes from
a 5 m arc by 7 m sees the outline cross itself; CommonRoad, lanelet2 tools and shapely call it
invalid), and no tighter than cars turn.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from shapely.geometry import LineString

STRAIGHT = 1e-9  # rad: a vertex turning less than this is no corner (no arc, lines merged)
MIN_LENGTH = 1e-8  # m: shorter pieces are dropped (the XSD wants length > 0)
#: m: straight line at each end of a plan (see ``_usable``): with arcs of 5 m or more, the
#: sharpest turn netconvert reads at a road end is 2 x 5 m x END_LINE = 10 m, above its 9 m.
END_LINE = 1.0
#: m: how far an arc may leave its corner's vertex, unless the least radius needs more: the largest
#: radius that fits between long segments would cut a gentle corner by metres (a 14 degree
#: turn between 120 m segments: 7 m), away from the HD map lanes the other files describe.
MAX_DEVIATION = 0.2
#: m: how far a corner merged or cut for the least radius (``eased``) may move the polyline.
EASE_TOLERANCE = 1.0

ARC_STEP = math.radians(5.0)  # an arc is sampled every 5 degrees: 3 cm from it at 8 m radius
#: steps of ARC_STEP an arc may exceed a whole number by and still take that number: a dead
#: end's U-turn is a half circle, 36 steps exactly, which rounding on one CPU put a last bit
#: above 36 and on another not (lanelet2 files with 38 or 37 points per U-turn)
STEP_SLACK = 1e-9


class Piece(NamedTuple):
    """One ``<geometry>`` record: start ``s``, start pose (``x``, ``y``, ``hdg``), ``length``,
    and either a ``curvature`` (line: 0, arc: signed, left positive) or normalised
    ``paramPoly3`` coefficients ``u``/``v`` (a, b, c, d) in the local frame of the start pose.
    A named tuple, not a frozen dataclass: a 10 km map has 160,000 of them, and a tuple is
    built several times faster."""

    kind: str  # "line", "arc" or "paramPoly3"
    s: float
    x: float
    y: float
    hdg: float
    length: float
    curvature: float = 0.0
    u: tuple[float, float, float, float] | None = None
    v: tuple[float, float, float, float] | None = None


def fillet_plans(lines: list[np.ndarray], min_radius) -> list[list[Piece]]:
    """Per polyline (two or more points), lines and circular arcs replacing each corner by a
    tangent arc, every arc of radius ``min_radius`` (one per polyline) or more and every plan
    starting and ending with ``END_LINE`` of straight line where its end segments allow.

    The result is G1 (continuous heading), starts at the first vertex along the first segment
    and ends at the last vertex along the last segment, so lane ends computed from it match
    the HD map's lane ends (which sit on the end segments' normals) exactly. Each corner's
    tangent length is shared out of its two segments in proportion to ``tan(turn / 2)`` so that
    neighbouring arcs get equal radii, the largest that fit, but no larger than keeps the arc
    within ``MAX_DEVIATION`` of the vertex (a tangent of ``MAX_DEVIATION / tan(turn / 4)``) or
    than the least radius needs. Polylines whose corners leave a smaller radius are eased first
    (:func:`eased`): corners merged or cut until every radius fits.

    All polylines at once: every figure is computed with the same operations, in the same
    order, as one polyline and one segment at a time (same bits), without a dozen small numpy
    calls per road.
    """
    if not lines:
        return []
    least = np.broadcast_to(np.asarray(min_radius, dtype=float), (len(lines),))
    pts, owner = _corners(*_stacked(lines))
    plans, radius = _fillets(pts, owner, least)
    bounds = np.searchsorted(owner, np.arange(len(lines) + 1))
    for road in np.flatnonzero(radius < least).tolist():
        line = eased(pts[bounds[road]:bounds[road + 1]], least[road])
        plans[road] = _fillets(*_corners(line, np.zeros(len(line), int)), least[road:road + 1])[0][0]
    return plans


def _fillets(pts: np.ndarray, owner: np.ndarray, least: np.ndarray):
    """The plans of stacked polylines (``pts`` cleaned by :func:`_corners`, polyline index
    ``owner``, least radius ``least`` each) and each one's smallest arc radius (inf without
    corners)."""
    count = len(least)
    seg = np.diff(pts, axis=0)
    inside = owner[1:] == owner[:-1]  # steps within a polyline: its segments
    seg, seg_owner, seg_start = seg[inside], owner[1:][inside], pts[:-1][inside]
    lengths = np.hypot(seg[:, 0], seg[:, 1])
    heading = np.arctan2(seg[:, 1], seg[:, 0])
    corner = seg_owner[1:] == seg_owner[:-1]  # per pair of segments: a vertex between them
    turn = np.angle(np.exp(1j * np.diff(heading)))  # signed turn, where corner
    weight = np.where(corner, np.tan(np.abs(turn) / 2.0), 0.0)  # of each segment's end vertex
    at_start, at_end = np.append(0.0, weight), np.append(weight, 0.0)  # per segment
    pair = at_start + at_end
    ends = np.append(True, ~corner), np.append(~corner, True)  # first, last of a polyline
    scale = np.divide(_usable(lengths, *ends), pair, out=np.full_like(lengths, np.inf),
                      where=pair > 0)
    with np.errstate(divide="ignore", invalid="ignore"):  # inf * 0 where no corner: not used
        cap = np.maximum(MAX_DEVIATION / np.tan(np.abs(turn) / 4.0),
                         least[seg_owner[1:]] * weight)
        tangent = np.where(corner, np.minimum(np.minimum(scale[:-1], scale[1:]) * weight, cap),
                           0.0)
    cut_start, cut_end = np.append(0.0, tangent), np.append(tangent, 0.0)
    start = (seg_start + cut_start[:, None] * seg / lengths[:, None]).tolist()
    run = (lengths - cut_start - cut_end).tolist()
    arc_start = seg_start[1:] - tangent[:, None] * seg[:-1] / lengths[:-1, None]  # at corners
    with np.errstate(divide="ignore", invalid="ignore"):  # 0 / 0 where no corner: not used
        radius = tangent / weight
        arc_length = (radius * np.abs(turn)).tolist()
        curvature = np.copysign(1.0 / radius, turn).tolist()
    smallest = np.full(count, np.inf)
    np.minimum.at(smallest, seg_owner[1:][corner], radius[corner])
    arc_start, heading, corner = arc_start.tolist(), heading.tolist(), corner.tolist()
    plans: list[list[Piece]] = [[] for _ in range(count)]
    previous = -1
    for i, road in enumerate(seg_owner.tolist()):
        if road != previous:
            pieces, s, previous = plans[road], 0.0, road
        s = _append(pieces, Piece("line", s, *start[i], heading[i], run[i]))
        if i < len(corner) and corner[i]:
            arc = Piece("arc", s, *arc_start[i], heading[i], arc_length[i],
                        curvature=curvature[i])
            s = _append(pieces, arc)
    return plans, smallest


def _usable(lengths: np.ndarray, first: np.ndarray, last: np.ndarray) -> np.ndarray:
    """Length of each segment that its corners' tangents may take: all of an inner segment,
    an end segment (``first`` or ``last`` of its polyline) less ``END_LINE`` (less half of it
    if shorter), so that a plan begins and ends straight. A reader that samples arcs in steps
    (netconvert: 2 m) otherwise ends a road with a short chord that turns against the one
    before it, and reads a tight turn there."""
    return np.where(first | last, lengths - np.minimum(END_LINE, lengths / 2.0), lengths)


def eased(points: np.ndarray, least: float) -> np.ndarray:
    """A cleaned polyline (:func:`_corners`) whose fillets all get radius ``least`` or more
    where that can be done by merging or cutting corners, with the same end points and end
    directions.

    While some corner's fillet is tighter, the segment that limits it goes: two corners that
    turn the same way become one at the crossing of the segments before and after (the
    tangent arc of that corner has room for a larger radius), and a corner of an S-bend is cut
    (its neighbours joined), each only where no vertex of ``points`` ends up farther than
    ``EASE_TOLERANCE`` from the new polyline. The end segments' directions stay: an end
    segment may be lengthened, never turned. Corners that nothing can help keep their radius.
    """
    original = LineString(points)
    pts = [np.asarray(p, float) for p in points]
    while len(pts) > 3:
        better = None
        for vertex, segment in _tight_corners(np.array(pts), least):
            other = vertex + (1 if segment == vertex else -1)  # the limiting segment's far end
            for candidate in (_merged(pts, segment), _cut(pts, vertex), _cut(pts, other)):
                if candidate and _within(original, candidate):
                    better = candidate
                    break
            if better:
                break
        if not better:
            break
        pts = better
    return np.array(pts)


def _within(original: LineString, candidate: list[np.ndarray]) -> bool:
    """Whether ``candidate`` and ``original`` are within ``EASE_TOLERANCE`` of each other."""
    return original.hausdorff_distance(LineString(candidate)) <= EASE_TOLERANCE


def _tight_corners(pts: np.ndarray, least: float) -> list[tuple[int, int]]:
    """(vertex, limiting segment) of every corner whose fillet would be tighter than
    ``least``, tightest first. Segment ``k`` runs from vertex ``k`` to ``k + 1``."""
    seg = np.diff(pts, axis=0)
    lengths = np.hypot(seg[:, 0], seg[:, 1])
    turn = np.angle(np.exp(1j * np.diff(np.arctan2(seg[:, 1], seg[:, 0]))))
    weight = np.tan(np.abs(turn) / 2.0)
    first = np.arange(len(lengths)) == 0
    with np.errstate(divide="ignore"):  # a segment between two straight vertices: no limit
        scale = _usable(lengths, first, first[::-1]) / (np.append(0.0, weight)
                                                         + np.append(weight, 0.0))
    limit = np.where(scale[:-1] <= scale[1:], np.arange(len(weight)), np.arange(len(weight)) + 1)
    radius = np.minimum(scale[:-1], scale[1:])
    order = np.argsort(radius, kind="stable")
    return [(int(v) + 1, int(limit[v])) for v in order if radius[v] < least]


def _merged(pts: list[np.ndarray], segment: int) -> list[np.ndarray] | None:
    """``pts`` with segment ``segment`` (clamped to an inner one) removed and its two corners
    made one at the crossing of its neighbour segments; None where the two turn different
    ways or together by half a turn or more (no crossing ahead)."""
    k = min(max(segment, 1), len(pts) - 3)
    a, b = pts[k] - pts[k - 1], pts[k + 2] - pts[k + 1]
    mid = pts[k + 1] - pts[k]
    cross_a, cross_b, cross_ab = _cross2(a, mid), _cross2(mid, b), _cross2(a, b)
    if cross_a * cross_b <= 0.0 or cross_a * cross_ab <= 0.0:
        return None
    ahead = _cross2(pts[k + 1] - pts[k], b) / cross_ab  # along a from pts[k]
    crossing = pts[k] + ahead * a
    if np.dot(crossing - pts[k - 1], a) <= 0.0 or np.dot(pts[k + 2] - crossing, b) <= 0.0:
        return None
    return [*pts[:k], crossing, *pts[k + 2:]]


def _cut(pts: list[np.ndarray], vertex: int) -> list[np.ndarray] | None:
    """``pts`` without the corner at ``vertex``, its neighbours joined; None for the first
    two and last two vertices (their segments set the end directions)."""
    if not 2 <= vertex <= len(pts) - 3:
        return None
    return [*pts[:vertex], *pts[vertex + 1:]]


def _cross2(a: np.ndarray, b: np.ndarray) -> float:
    return float(a[0] * b[1] - a[1] * b[0])


def _stacked(lines: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """The polylines' points one after another, and the index of the polyline of each."""
    sizes = np.fromiter(map(len, lines), int, len(lines))
    return np.concatenate(lines, dtype=float), np.repeat(np.arange(len(lines)), sizes)


def _corners(pts: np.ndarray, owner: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Stacked polylines without zero-length segments (but their last point) and without
    vertices that do not turn."""
    first = np.append(True, owner[1:] != owner[:-1])
    last = np.append(first[1:], True)
    step = np.diff(pts, axis=0)
    keep = first | last
    keep[1:] |= np.hypot(step[:, 0], step[:, 1]) > 0.0
    pts, owner, first, last = pts[keep], owner[keep], first[keep], last[keep]
    step = np.diff(pts, axis=0)
    heading = np.arctan2(step[:, 1], step[:, 0])
    turn = np.abs(np.angle(np.exp(1j * np.diff(heading))))  # at each interior point
    keep = first | last
    keep[1:-1] |= turn > STRAIGHT
    return pts[keep], owner[keep]


def _append(pieces: list[Piece], piece: Piece) -> float:
    """Add ``piece`` unless it is too short to write; return the ``s`` after it."""
    if piece.length < MIN_LENGTH:
        return piece.s
    pieces.append(piece)
    return piece.s + piece.length




def plan_points(pieces: list[Piece], start: np.ndarray,
                end: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A plan as points and their unit tangents: its lines' ends and its arcs sampled every
    ``ARC_STEP`` of turn, from ``start`` to ``end`` (the polyline's own end points, set exactly
    so that lane ends meet the connectors built from them). Lanes offset along the normals of
    these tangents are the plan's exact parallel curves at the samples, as an OpenDRIVE reader
    computes them; a miter offset of the chords would kink where an arc meets a line."""
    points, headings = [np.asarray(start, dtype=float)[None]], [pieces[0].hdg]
    for piece in pieces:
        if piece.kind == "arc":
            turn = abs(piece.curvature) * piece.length / ARC_STEP
            steps = max(1, math.ceil(turn - STEP_SLACK))
            k = piece.curvature
            heading = piece.hdg + k * piece.length * np.arange(1, steps + 1) / steps
            points.append(np.column_stack([piece.x + (np.sin(heading) - math.sin(piece.hdg)) / k,
                                           piece.y - (np.cos(heading) - math.cos(piece.hdg)) / k]))
            headings.extend(heading.tolist())
        else:
            points.append(np.array([[piece.x + piece.length * math.cos(piece.hdg),
                                     piece.y + piece.length * math.sin(piece.hdg)]]))
            headings.append(piece.hdg)
    out = np.vstack(points)
    out[-1] = end
    headings = np.array(headings)
    return out, np.column_stack([np.cos(headings), np.sin(headings)])
