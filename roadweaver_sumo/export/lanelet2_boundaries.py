"""Lane boundaries as lanelet2 needs them. Offsetting a sharply bent centreline leaves loops
(swallowtails) and fold-backs in a boundary: a lanelet with such a bound has a self-intersecting
polygon, and lanelet2 guesses the orientation of a bound from its middle vertices
(``geometry::align``). They are cut before a boundary is written; its end points stay, as they
are nodes shared with the lanes before and after."""

from __future__ import annotations

import math

import numpy as np
from shapely.geometry import LineString

MIN_STEP_M = 1e-3  # shorter boundary steps are dropped


def untangle_all(polylines: list) -> list[np.ndarray]:
    """Each polyline untangled (:func:`untangle`); most need nothing, and those are found for
    all at once (:func:`_clean`)."""
    return [np.asarray(points, float) if clean else untangle(points)
            for points, clean in zip(polylines, _clean(polylines), strict=True)]


def untangle(points: np.ndarray) -> np.ndarray:
    """``points`` without the loops and fold-backs that offsetting a sharp bend leaves in a
    boundary, and without sub-millimetre steps; the end points stay (they are shared nodes)."""
    points = _cut_loops(np.asarray(points, float))
    step = np.diff(points, axis=0)
    if (len(step) and np.hypot(step[:, 0], step[:, 1]).min() > 1.001 * MIN_STEP_M  # margin: math.hypot below
            and (step[:-1, 0] * step[1:, 0] + step[:-1, 1] * step[1:, 1] >= 0).all()):
        return points  # no short step and no fold-back: the loop below would keep every point
    points = points.tolist()  # plain floats: a hot loop
    kept = [points[0]]
    for index, (x, y) in enumerate(points[1:], start=1):
        if math.hypot(x - kept[-1][0], y - kept[-1][1]) < MIN_STEP_M:
            if index == len(points) - 1 and len(kept) > 1:
                kept[-1] = [x, y]
            continue
        while len(kept) >= 2 and ((kept[-1][0] - kept[-2][0]) * (x - kept[-1][0])
                                  + (kept[-1][1] - kept[-2][1]) * (y - kept[-1][1])) < 0:
            kept.pop()  # a turn of more than 90 degrees: the polyline folds back here
        kept.append([x, y])
    return np.array(kept)


def _cut_loops(points: np.ndarray) -> np.ndarray:
    """Replace each self-crossing loop by its crossing point (swallowtails of offset curves)."""
    if len(points) < 4 or _turning(points) < 0.99 * math.pi or LineString(points).is_simple:
        return points  # a polyline turning less than half a turn in all cannot cross itself
    i = 0
    while i < len(points) - 3:
        a, b = points[i], points[i + 1]
        starts, ends = points[i + 2:-1], points[i + 3:]
        t, u = _segment_crossings(a, b, starts, ends)
        hits = np.nonzero((t >= 0) & (t <= 1) & (u >= 0) & (u <= 1))[0]
        if len(hits):
            j = i + 2 + hits[-1]  # the last crossing removes the largest loop
            crossing = a + t[hits[-1]] * (b - a)
            points = np.vstack([points[:i + 1], crossing, points[j + 1:]])
        i += 1
    return points


def _turning(points: np.ndarray) -> float:
    """Total absolute turning (rad) of a polyline; a zero-length step only adds to it."""
    step = np.diff(points, axis=0)
    heading = np.arctan2(step[:, 1], step[:, 0])
    return float(np.abs(np.angle(np.exp(1j * np.diff(heading)))).sum())


def _segment_crossings(a, b, starts, ends):
    """Parameters ``t`` on segment a-b and ``u`` on each segment starts-ends of their lines'
    intersection (``inf`` for parallel segments)."""
    d, e = b - a, ends - starts
    denom = d[0] * e[:, 1] - d[1] * e[:, 0]
    w = starts - a
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (w[:, 0] * e[:, 1] - w[:, 1] * e[:, 0]) / denom
        u = (w[:, 0] * d[1] - w[:, 1] * d[0]) / denom
    parallel = np.abs(denom) < 1e-12
    t[parallel] = u[parallel] = np.inf
    return t, u



def _clean(polylines: list) -> np.ndarray:
    """Per polyline, whether :func:`untangle` would return it unchanged because it turns less
    than half a turn in all (so it cannot cross itself), has no sub-millimetre step and never
    turns by more than 90 degrees: one vectorised pass over all boundaries of the map instead
    of a dozen small numpy calls per boundary."""
    sizes = np.fromiter(map(len, polylines), int, len(polylines))
    pts = np.concatenate(polylines, dtype=float)  # (n, 2) each: no per-polyline conversion
    owner = np.repeat(np.arange(len(polylines)), sizes)
    step = np.diff(pts, axis=0)
    inside = owner[1:] == owner[:-1]  # steps between two polylines are not steps
    step, step_owner = step[inside], owner[1:][inside]
    short = np.hypot(step[:, 0], step[:, 1]) <= 1.001 * MIN_STEP_M  # margin: untangle's hypot
    pair = step_owner[1:] == step_owner[:-1]
    fold = (step[:-1, 0] * step[1:, 0] + step[:-1, 1] * step[1:, 1] < 0)[pair]
    heading = np.arctan2(step[:, 1], step[:, 0])
    turn = np.abs(np.angle(np.exp(1j * (heading[1:] - heading[:-1])[pair])))
    n = len(polylines)
    turning = np.bincount(step_owner[1:][pair], weights=turn, minlength=n)
    bad = (np.bincount(step_owner[short], minlength=n)
           + np.bincount(step_owner[1:][pair][fold], minlength=n))
    return (bad == 0) & ((sizes < 4) | (turning < 0.99 * math.pi)) & (sizes >= 2)
