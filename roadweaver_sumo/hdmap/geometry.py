"""Polyline and Bezier geometry for lane construction, vectorised with numpy.

Offsets are positive to the left of the driving direction (x east, y north, metres).
"""

from __future__ import annotations

import numba as nb
import numpy as np

from ..compiled import F8, F8_1D, F8_2D, F8_2D_ANY, compiled

F8_3D = F8[:, :, ::1]

MAX_MITER = 4.0  # cap on the miter stretch at sharp vertices, so offsets never spike
BEZIER_SAMPLES = 12  # a 90° turn of 8 m radius: 2 cm from the true curve
BEZIER_TOLERANCE = 0.02  # m: gentler connectors get fewer samples, as close to their curve
INNER_REACH = 0.8  # an inner boundary stays within this share of the curvature radius
INNER_RAMP = 3  # samples over which a narrowed inner boundary returns to the lane ends


def dedupe(coords: np.ndarray, tol: float = 1e-6) -> np.ndarray:
    """Drop consecutive points closer than ``tol`` (zero-length segments have no direction),
    keeping both ends exactly (part of paper Algorithm 1, RefineRoadGraph)."""
    return _dedupe(np.asarray(coords, dtype=np.float64), float(tol))


@compiled(F8_2D(F8_2D_ANY, F8))
def _dedupe(coords, tol):
    """Compiled (a call per road), the same bits as numpy's ``hypot`` of ``diff``."""
    keep = np.ones(len(coords), dtype=np.bool_)
    for k in range(len(coords) - 1):
        keep[k + 1] = np.hypot(coords[k + 1, 0] - coords[k, 0],
                               coords[k + 1, 1] - coords[k, 1]) > tol
    out = coords[keep]
    out[-1] = coords[-1]  # a dropped last point moves its kept neighbour onto it
    if len(out) >= 2:
        return out
    ends = np.empty((2, 2))
    ends[0], ends[1] = coords[0], coords[-1]
    return ends


def arc_lengths(coords: np.ndarray) -> np.ndarray:
    """Cumulative arc length at each vertex, starting at 0. Compiled: called for every road
    and junction approach, where numpy's per-call overhead was most of the cost; the same
    bits as ``cumsum`` of ``hypot`` of ``diff`` (a running sum in order)."""
    return _arc_lengths(np.asarray(coords, dtype=np.float64))


@compiled(F8_1D(F8_2D_ANY))
def _arc_lengths(coords):
    out = np.empty(len(coords))
    out[0] = 0.0
    for k in range(len(coords) - 1):
        out[k + 1] = out[k] + np.hypot(coords[k + 1, 0] - coords[k, 0],
                                       coords[k + 1, 1] - coords[k, 1])
    return out


def cut(coords: np.ndarray, s0: float, s1: float, gap: float = 0.5) -> np.ndarray:
    """The part of a polyline between arc lengths ``s0 < s1``, ends interpolated.

    Vertices closer than ``gap`` to a cut end are dropped: a sliver segment of a few
    centimetres next to the end would give the lanes offset from it a fold, and the lane's end
    tangent would point backwards. Compiled (one call per road), the same bits as ``np.interp``
    for the ends and the kept vertices in between."""
    return _cut(np.asarray(coords, dtype=np.float64), float(s0), float(s1), float(gap))


@compiled(F8(F8, F8_1D, F8_2D_ANY, nb.int64))
def _interp_at(x, xp, coords, col):
    """``np.interp(x, xp, coords[:, col])`` for one ``x`` and increasing ``xp``, the same bits:
    numpy's branches (outside and on a vertex: that vertex's value, else the slope times the
    step from the vertex below, from the vertex above if that is NaN)."""
    n = len(xp)
    if np.isnan(x):
        return x
    if x > xp[n - 1]:
        return coords[n - 1, col]
    if x < xp[0]:
        return coords[0, col]
    j = 0
    while j + 1 < n and x >= xp[j + 1]:
        j += 1
    if j == n - 1 or xp[j] == x:
        return coords[j, col]
    slope = (coords[j + 1, col] - coords[j, col]) / (xp[j + 1] - xp[j])
    out = slope * (x - xp[j]) + coords[j, col]
    if np.isnan(out):
        out = slope * (x - xp[j + 1]) + coords[j + 1, col]
        if np.isnan(out) and coords[j, col] == coords[j + 1, col]:
            out = coords[j, col]
    return out


@compiled(F8_2D(F8_2D_ANY, F8, F8, F8))
def _cut(coords, s0, s1, gap):
    s = _arc_lengths(coords)
    inner = (s > s0 + gap) & (s < s1 - gap)
    out = np.empty((inner.sum() + 2, 2))
    out[0, 0], out[0, 1] = _interp_at(s0, s, coords, 0), _interp_at(s0, s, coords, 1)
    out[-1, 0], out[-1, 1] = _interp_at(s1, s, coords, 0), _interp_at(s1, s, coords, 1)
    out[1:-1] = coords[inner]
    return out


def end_directions(lines: list[np.ndarray], probe: float) -> np.ndarray:
    """Unit directions (2 m, 2) from each polyline's first and then its last point towards
    the point ``probe`` metres (at most half its length) along it from that end. Compiled, for
    every road of a map in one call; the same bits as ``np.interp`` on ``arc_lengths`` and
    ``unit_tangent``."""
    if not lines:
        return np.empty((0, 2))
    bounds = np.cumsum([0, *map(len, lines)])
    return _end_directions(np.concatenate(lines).astype(np.float64), bounds, float(probe))


@compiled(F8_2D(F8_2D, nb.int64[::1], F8))
def _end_directions(coords, bounds, probe):
    out = np.empty((2 * (len(bounds) - 1), 2))
    for r in range(len(bounds) - 1):
        line = coords[bounds[r]:bounds[r + 1]]
        for end in range(2):
            if end == 1:
                line = line[::-1]
            s = _arc_lengths(line)
            at = min(probe, s[-1] / 2.0)
            dx = _interp_at(at, s, line, 0) - line[0, 0]
            dy = _interp_at(at, s, line, 1) - line[0, 1]
            norm = np.sqrt(dx * dx + dy * dy)
            out[2 * r + end, 0], out[2 * r + end, 1] = dx / norm, dy / norm
    return out


def unit_tangent(vector: np.ndarray) -> np.ndarray:
    """Unit vector(s) along ``vector`` (rows). The norm is written out as ``np.linalg.norm``
    computes it for real rows (same bits), without its per-call overhead: called for every
    lane end and junction approach."""
    return vector / np.sqrt(np.add.reduce(vector * vector, axis=-1, keepdims=True))


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
    vertices (paper Algorithm 1, GenerateLaneBoundaries).
    """
    return _miter_normals(np.asarray(coords, dtype=np.float64), 1.0 / MAX_MITER)


@compiled(F8_2D(F8_2D_ANY, F8))
def _miter_normals(coords, min_cos):
    """Compiled (one call per road, where numpy's per-call overhead dominated), the same bits
    as the numpy expressions: unit segment normals, their per-vertex sums normalised, each
    stretched by 1 / cos(half the turn) capped at ``1 / min_cos``."""
    n = len(coords)
    seg = np.empty((n - 1, 2))
    for k in range(n - 1):
        dx, dy = coords[k + 1, 0] - coords[k, 0], coords[k + 1, 1] - coords[k, 1]
        norm = np.sqrt(dx * dx + dy * dy)
        seg[k, 0], seg[k, 1] = -(dy / norm), dx / norm
    out = np.empty((n, 2))
    for k in range(n):
        before = seg[max(k - 1, 0)]
        after = seg[min(k, n - 2)]
        if 0 < k < n - 1:
            vx, vy = before[0] + after[0], before[1] + after[1]
        else:
            vx, vy = after[0], after[1]
        norm = np.sqrt(vx * vx + vy * vy)
        vx, vy = vx / norm, vy / norm
        cos_half = vx * before[0] + vy * before[1]
        if cos_half < min_cos:  # noqa: PLR1730 - as np.clip: a NaN (a fold back) stays NaN
            cos_half = min_cos
        out[k, 0], out[k, 1] = vx / cos_half, vy / cos_half
    return out


def offset(coords: np.ndarray, distances, miter: np.ndarray | None = None) -> np.ndarray:
    """Parallel copies of a polyline at signed ``distances`` (left positive), shape (k, n, 2).
    Compiled (a call per road), the same bits as ``coords + d * miter`` broadcast in numpy."""
    coords = np.asarray(coords, dtype=np.float64)
    miter = miter_normals(coords) if miter is None else miter
    d = np.atleast_1d(np.asarray(distances, dtype=np.float64))
    return _offset(coords, np.ascontiguousarray(d), np.asarray(miter, dtype=np.float64))


@compiled(F8_3D(F8_2D_ANY, F8_1D, F8_2D_ANY))
def _offset(coords, distances, miter):
    out = np.empty((len(distances), len(coords), 2))
    for k in range(len(distances)):
        for i in range(len(coords)):
            for c in range(2):
                out[k, i, c] = coords[i, c] + distances[k] * miter[i, c]
    return out


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
    pts, tangents, cross, speed = _bezier_frames(
        *_bernstein(n), np.ascontiguousarray(ctrl, dtype=np.float64))
    return pts, tangents, cross / speed**3  # numpy's power, as before: its bits


@compiled(nb.types.Tuple((F8_3D, F8_3D, F8_2D, F8_2D))(F8_2D, F8_2D, F8_2D, F8_3D))
def _bezier_frames(basis, d1, d2, ctrl):
    """Points (ends exactly the end control points), unit tangents (m, n, 2), and the cross
    product of velocity and acceleration and the speed (at least 1e-9) (m, n) of Beziers
    ``ctrl`` (m, 4, 2) from the basis tables (n, 4). Compiled, at a fraction of numpy's time on
    the 30,000 connectors of a 10 km map, the same bits as the numpy expressions: the sums as
    ``np.einsum("nk,mkd->mnd", table, ctrl)`` (a running sum from 0 over the four control
    points, in order), the speed as ``np.maximum(np.linalg.norm(vel, axis=2), 1e-9)``."""
    m, n = ctrl.shape[0], basis.shape[0]
    pts, tangents = np.empty((m, n, 2)), np.empty((m, n, 2))
    cross, speed = np.empty((m, n)), np.empty((m, n))
    vel, acc = np.empty(2), np.empty(2)
    for i in range(m):
        for j in range(n):
            for d in range(2):
                p = v = a = 0.0
                for k in range(4):
                    c = ctrl[i, k, d]
                    p += basis[j, k] * c
                    v += d1[j, k] * c
                    a += d2[j, k] * c
                pts[i, j, d], vel[d], acc[d] = p, v, a
            norm = np.sqrt(vel[0] * vel[0] + vel[1] * vel[1])
            if norm < 1e-9:  # noqa: PLR1730 - as np.maximum: a NaN stays NaN
                norm = 1e-9
            speed[i, j] = norm
            cross[i, j] = vel[0] * acc[1] - vel[1] * acc[0]
            tangents[i, j, 0], tangents[i, j, 1] = vel[0] / norm, vel[1] / norm
        for d in range(2):
            pts[i, 0, d], pts[i, n - 1, d] = ctrl[i, 0, d], ctrl[i, 3, d]
    return pts, tangents, cross, speed


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
