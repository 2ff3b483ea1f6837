"""Polyline and Bezier geometry for lane construction, vectorised with numpy.

Offsets are positive to the left of the driving direction (x east, y north, metres).
"""

from __future__ import annotations

import numpy as np

MAX_MITER = 4.0  # cap on the miter stretch at sharp vertices, so offsets never spike
BEZIER_SAMPLES = 12  # a 90° turn of 8 m radius: 2 cm from the true curve
BEZIER_TOLERANCE = 0.02  # m: gentler connectors get fewer samples, as close to their curve
INNER_REACH = 0.8  # an inner boundary stays within this share of the curvature radius
INNER_RAMP = 3  # samples over which a narrowed inner boundary returns to the lane ends


def dedupe(coords: np.ndarray, tol: float = 1e-6) -> np.ndarray:
    """Drop consecutive points closer than ``tol`` (zero-length segments have no direction),
    keeping both ends exactly (part of paper Algorithm 1, RefineRoadGraph)."""
    coords = np.asarray(coords, dtype=np.float64)
    out = coords[np.r_[True, np.hypot(*np.diff(coords, axis=0).T) > tol]]
    out[-1] = coords[-1]  # a dropped last point moves its kept neighbour onto it
    return out if len(out) >= 2 else coords[[0, -1]]


def arc_lengths(coords: np.ndarray) -> np.ndarray:
    """Cumulative arc length at each vertex, starting at 0."""
    coords = np.asarray(coords, dtype=np.float64)
    return np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(coords, axis=0).T))])


def _point_at(coords: np.ndarray, s: np.ndarray, at: float) -> np.ndarray:
    """The point at arc length ``at`` of a polyline whose vertices lie at arc lengths ``s``."""
    return np.array([np.interp(at, s, coords[:, 0]), np.interp(at, s, coords[:, 1])])


def cut(coords: np.ndarray, s0: float, s1: float, gap: float = 0.5) -> np.ndarray:
    """The part of a polyline between arc lengths ``s0 < s1``, ends interpolated.

    Vertices closer than ``gap`` to a cut end are dropped: a sliver segment of a few
    centimetres next to the end would give the lanes offset from it a fold, and the lane's end
    tangent would point backwards."""
    coords = np.asarray(coords, dtype=np.float64)
    s = arc_lengths(coords)
    inner = coords[(s > s0 + gap) & (s < s1 - gap)]
    return np.vstack([_point_at(coords, s, s0), inner, _point_at(coords, s, s1)])


def end_directions(lines: list[np.ndarray], probe: float) -> np.ndarray:
    """Unit directions (2 m, 2) from each polyline's first and then its last point towards
    the point ``probe`` metres (at most half its length) along it from that end."""
    out = np.empty((2 * len(lines), 2))
    for k, line in enumerate(lines):
        line = np.asarray(line, dtype=np.float64)
        for end, ordered in enumerate((line, line[::-1])):
            s = arc_lengths(ordered)
            out[2 * k + end] = _point_at(ordered, s, min(probe, s[-1] / 2.0)) - ordered[0]
    return unit_tangent(out)


def unit_tangent(vector: np.ndarray) -> np.ndarray:
    """Unit vector(s) along ``vector`` (rows)."""
    return vector / np.linalg.norm(vector, axis=-1, keepdims=True)


def start_tangent(coords: np.ndarray) -> np.ndarray:
    """Unit driving direction at the first vertex."""
    return unit_tangent(coords[1] - coords[0])


def end_tangent(coords: np.ndarray) -> np.ndarray:
    """Unit driving direction at the last vertex."""
    return unit_tangent(coords[-1] - coords[-2])


def _left(t: np.ndarray) -> np.ndarray:
    """Left normals of unit tangents (rotate by +90 degrees)."""
    return np.stack([-t[..., 1], t[..., 0]], axis=-1)


def miter_normals(coords: np.ndarray) -> np.ndarray:
    """Per-vertex left offset vectors for a unit distance, (n, 2).

    Interior vertices use the miter join (exact for straight pieces: each offset segment stays
    parallel to its original), so every lane boundary of a road shares the reference line's
    vertices (paper Algorithm 1, GenerateLaneBoundaries): the sum of the two segment normals,
    normalised, stretched by 1 / cos(half the turn), at most ``MAX_MITER`` times.
    """
    coords = np.asarray(coords, dtype=np.float64)
    normals = _left(unit_tangent(np.diff(coords, axis=0)))
    k = np.arange(len(coords))
    before, after = normals[np.maximum(k - 1, 0)], normals[np.minimum(k, len(normals) - 1)]
    joined = after.copy()
    joined[1:-1] += before[1:-1]
    joined = unit_tangent(joined)
    cos_half = np.maximum(np.einsum("ij,ij->i", joined, before), 1.0 / MAX_MITER)
    return joined / cos_half[:, None]


def offset(coords: np.ndarray, distances, miter: np.ndarray | None = None) -> np.ndarray:
    """Parallel copies of a polyline at signed ``distances`` (left positive), shape (k, n, 2)."""
    coords = np.asarray(coords, dtype=np.float64)
    miter = miter_normals(coords) if miter is None else miter
    d = np.atleast_1d(np.asarray(distances, dtype=np.float64))
    return coords[None] + d[:, None, None] * miter[None]


def signed_angles(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Angles (radians, in (-pi, pi]) turning direction ``a`` into each row of ``b``; positive
    means a left turn."""
    return np.arctan2(_cross(a, b), b @ a)


def _bernstein(n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Cubic Bernstein basis and its first and second derivatives at ``n`` parameters, (n, 4)."""
    t = np.linspace(0.0, 1.0, n)
    u = 1.0 - t
    basis = np.column_stack([u**3, 3 * u**2 * t, 3 * u * t**2, t**3])
    d1 = np.column_stack([-3 * u**2, 3 * u**2 - 6 * u * t, 6 * u * t - 3 * t**2, 3 * t**2])
    d2 = np.column_stack([6 * u, 6 * t - 12 * u, 6 * u - 12 * t, 6 * t])
    return basis, d1, d2


def bezier_controls(p0: np.ndarray, t0: np.ndarray, p3: np.ndarray, t3: np.ndarray) -> np.ndarray:
    """Cubic Bezier control points, (m, 4, 2), from ``p0`` leaving along unit ``t0`` to ``p3``
    arriving along unit ``t3`` (all (m, 2)).

    Handle length is the circular-arc approximation ``4/3 tan(theta/4) r`` for the turn angle
    ``theta`` and the chord's arc radius ``r``: chord/3 when straight, 2/3 chord for a U-turn.
    """
    chord = np.linalg.norm(p3 - p0, axis=1)
    theta = np.abs(np.arctan2(_cross(t0, t3), np.einsum("ij,ij->i", t0, t3)))
    bent = theta > 1e-6
    safe = np.where(bent, theta, 1.0)
    k = np.where(bent, 4.0 / 3.0 * np.tan(safe / 4.0) * chord / (2.0 * np.sin(safe / 2.0)),
                 chord / 3.0)
    k = np.maximum(k, 1e-3)[:, None]
    return np.stack([p0, p0 + k * t0, p3 - k * t3, p3], axis=1)


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """z component of the cross product of 2-d row vectors."""
    return a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]


def bezier_sample(ctrl: np.ndarray, n: int = BEZIER_SAMPLES):
    """Points (m, n, 2), unit tangents (m, n, 2) and signed curvature (m, n; positive turning
    left) of cubic Beziers.

    The first and last points are the first and last control points exactly (alignment 0).
    """
    ctrl = np.asarray(ctrl, dtype=np.float64)
    basis, d1, d2 = _bernstein(n)
    pts = np.einsum("nk,mkd->mnd", basis, ctrl)
    vel = np.einsum("nk,mkd->mnd", d1, ctrl)
    acc = np.einsum("nk,mkd->mnd", d2, ctrl)
    pts[:, 0], pts[:, -1] = ctrl[:, 0], ctrl[:, 3]
    speed = np.maximum(np.linalg.norm(vel, axis=2), 1e-9)
    return pts, vel / speed[..., None], _cross(vel, acc) / speed**3


def bezier_sample_counts(ctrl: np.ndarray, tol: float = BEZIER_TOLERANCE,
                         most: int = BEZIER_SAMPLES) -> np.ndarray:
    """Samples per cubic Bezier (m, 4, 2) so that the polyline through them stays within
    ``tol`` of the curve: 2 for a straight connector, ``most`` for a tight turn.

    A chord over a parameter step h deviates at most h² max|B''| / 8 from the curve, and |B''|
    peaks at an end: 6 |P0 - 2 P1 + P2| or 6 |P1 - 2 P2 + P3|. Most connectors in a map are
    through movements and gentle bends; every sample is a node in the lanelet2 file."""
    second = np.maximum(np.linalg.norm(ctrl[:, 0] - 2 * ctrl[:, 1] + ctrl[:, 2], axis=1),
                        np.linalg.norm(ctrl[:, 1] - 2 * ctrl[:, 2] + ctrl[:, 3], axis=1))
    steps = np.ceil(np.sqrt(0.75 * second / tol))
    return np.clip(steps, 1, most - 1).astype(int) + 1


def offset_along(pts: np.ndarray, tangents: np.ndarray, distances: np.ndarray) -> np.ndarray:
    """Points moved left by ``distances`` (broadcast against the points' leading axes) along
    the normals of the given unit tangents."""
    return pts + _left(tangents) * distances[..., None]


def boundary_offsets(curvature: np.ndarray, half: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Signed offsets (left positive) of the left and right boundaries of curved lanes, (m, n).

    Half the width, except on the inside of a bend tighter than half the width: an offset
    beyond the curvature radius folds back (lanelet2 then guesses the bound's direction wrong
    and reverses the lanelet). There the inner boundary keeps within ``INNER_REACH`` of the
    smallest radius on that side, a parallel curve, and the lane narrows; it ramps back to
    half the width over ``INNER_RAMP`` samples at each end, where it meets the joined lanes.
    """
    n = curvature.shape[1]
    ends = np.minimum(np.arange(n), np.arange(n)[::-1])  # samples to the nearer end
    ramp = np.clip(1.0 - ends / INNER_RAMP, 0.0, 1.0)  # 1 at the end points, 0 inside
    sides = []
    for sign in (1.0, -1.0):
        bend = np.clip(sign * curvature, 0.0, None)
        reach = INNER_REACH / np.maximum(bend, 1e-9)
        inner = np.minimum(half, reach.min(axis=1, keepdims=True))
        side = np.minimum(inner + (half - inner) * ramp, reach)
        side[:, [0, -1]] = half[:, [0, -1]]
        sides.append(sign * side)
    return sides[0], sides[1]
