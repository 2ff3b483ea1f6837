"""Tracing roads through a tensor field (paper §III-C, Eq. (3)-(5)) against the roads already drawn.

One tracer serves the skeleton (arterials that pass through each other) and the expansion
(collectors and locals that end on the first road they meet). A front advances by Euler steps;
each step picks the tensor eigen-direction closest to the current heading, blends it with the
heading (inertia), clamps the turn, adds style jitter, and then looks ahead for existing roads.
"""

from __future__ import annotations

import math
from collections import defaultdict
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from .tensor_field import TensorField


@dataclass(frozen=True)
class GrowthParams:
    """Knobs of one family of roads. Lengths in metres, angles in degrees."""

    step: float = 10.0
    max_turn: float = 15.0
    w_tensor: float = 1.0
    w_inertia: float = 0.8
    jitter: float = 1.0
    snap_radius: float = 25.0
    parallel_gap: float = 40.0  # a road running alongside closer than this stops the front
    max_length: float = 5000.0
    min_angle: float = 35.0  # a front meeting a road at a shallower angle stops instead
    pass_through: bool = False  # arterials cross other roads; others end on them


@dataclass
class Trace:
    """A traced polyline and why it ended: 'boundary', 'snap', 'blocked', 'loop' or 'length'."""

    coords: np.ndarray
    end: str


class SegmentIndex:
    """A dynamic uniform-grid index of road segments (shapely's STRtree cannot grow)."""

    def __init__(self, cell: float = 50.0):
        self.cell = cell
        self.cells: dict[tuple[int, int], list[int]] = defaultdict(list)
        self.a = np.zeros((256, 2))
        self.b = np.zeros((256, 2))
        self.road = np.zeros(256, dtype=int)
        self.size = 0
        self._windows: dict = {}  # cell range -> segments (see window); cleared by add

    def add(self, coords: np.ndarray, road_id: int) -> None:
        n = len(coords) - 1
        while self.size + n > len(self.a):
            for name in ("a", "b", "road"):
                arr = getattr(self, name)
                setattr(self, name, np.concatenate([arr, np.zeros_like(arr)]))
        first = self.size
        self.a[first : first + n] = coords[:-1]
        self.b[first : first + n] = coords[1:]
        self.road[first : first + n] = road_id
        self.size += n
        self._windows.clear()
        lo = np.floor(np.minimum(coords[:-1], coords[1:]) / self.cell).astype(int)
        hi = np.floor(np.maximum(coords[:-1], coords[1:]) / self.cell).astype(int)
        for k in range(n):
            for cx in range(lo[k, 0], hi[k, 0] + 1):
                for cy in range(lo[k, 1], hi[k, 1] + 1):
                    self.cells[(cx, cy)].append(first + k)

    def near(self, p: np.ndarray, radius: float) -> np.ndarray:
        """Ids of segments that may lie within ``radius`` of ``p`` (a superset)."""
        return self._ids(self._range(p, radius))

    def _range(self, p, radius: float) -> tuple[int, int, int, int]:
        x, y = float(p[0]), float(p[1])
        return (int((x - radius) // self.cell), int((y - radius) // self.cell),
                int((x + radius) // self.cell), int((y + radius) // self.cell))

    def _ids(self, cells: tuple[int, int, int, int]) -> np.ndarray:
        x0, y0, x1, y1 = cells
        found: set[int] = set()
        for cx in range(x0, x1 + 1):
            for cy in range(y0, y1 + 1):
                found.update(self.cells.get((cx, cy), ()))
        return np.array(sorted(found), dtype=int)

    def window(self, p: np.ndarray, radius: float):
        """:meth:`near` with the segments' ends, road ids and unit directions: a tracer asks
        for the same cells step after step, so the answer is kept until the next ``add``."""
        cells = self._range(p, radius)
        hit = self._windows.get(cells)
        if hit is None:
            a, b, road = self.arrays(self._ids(cells))
            edge = b - a
            unit = edge / np.maximum(np.hypot(*edge.T), 1e-9)[:, None]
            sq = np.einsum("ij,ij->i", edge, edge)
            hit = self._windows[cells] = _Window(a, road, unit, edge, np.where(sq > 0, sq, 1.0))
        return hit

    def arrays(self, ids: np.ndarray):
        return self.a[ids], self.b[ids], self.road[ids]


class _Window(NamedTuple):
    """Segments near a point: start ``a``, road id, unit direction, ``edge = b - a`` and its
    squared length (1 for zero-length segments: the projection divisor)."""

    a: np.ndarray
    road: np.ndarray
    unit: np.ndarray
    edge: np.ndarray
    edge_sq: np.ndarray


def choose_axis(field: TensorField, p: np.ndarray, d: np.ndarray) -> np.ndarray:
    """Paper Eq. (3): the eigen-direction among ±e_major, ±e_minor best aligned with ``d``."""
    ex, ey = field.major_at(float(p[0]), float(p[1]))
    dx, dy = float(d[0]), float(d[1])
    along, across = ex * dx + ey * dy, ex * dy - ey * dx  # d·e_major, d·e_minor
    if abs(along) >= abs(across):
        sign = 1.0 if along >= 0 else -1.0
        return np.array([sign * ex, sign * ey])
    sign = 1.0 if across >= 0 else -1.0
    return np.array([-sign * ey, sign * ex])


def clamp_turn(d_old: np.ndarray, d_new: np.ndarray, max_turn_rad: float) -> np.ndarray:
    """The operator C_θmax of Eq. (4): rotate ``d_new`` back to at most θmax away from ``d_old``."""
    ox, oy, nx, ny = float(d_old[0]), float(d_old[1]), float(d_new[0]), float(d_new[1])
    ang = math.atan2(ox * ny - oy * nx, ox * nx + oy * ny)
    ang = max(-max_turn_rad, min(max_turn_rad, ang))
    return rotate(d_old, ang)


def rotate(v: np.ndarray, ang: float) -> np.ndarray:
    c, s = math.cos(ang), math.sin(ang)
    x, y = float(v[0]), float(v[1])
    return np.array([c * x - s * y, s * x + c * y])


def next_direction(field, p, d, params: GrowthParams, rng: np.random.Generator) -> np.ndarray:
    """Eq. (4) then the style perturbation Δφ. The tracer's inner loop, so written out on plain
    floats: the same operations as :func:`choose_axis`, :func:`clamp_turn` and :func:`rotate`
    on 2-vectors (same results to the bit), without a numpy array per operation."""
    ex, ey = field.major_at(float(p[0]), float(p[1]))
    dx, dy = float(d[0]), float(d[1])
    along, across = ex * dx + ey * dy, ex * dy - ey * dx
    if abs(along) >= abs(across):
        sign = 1.0 if along >= 0 else -1.0
        ax, ay = sign * ex, sign * ey
    else:
        sign = 1.0 if across >= 0 else -1.0
        ax, ay = -sign * ey, sign * ex
    bx, by = params.w_tensor * ax + params.w_inertia * dx, params.w_tensor * ay + params.w_inertia * dy
    norm = np.hypot(bx, by)
    nx, ny = (bx / norm, by / norm) if norm > 1e-9 else (dx, dy)
    limit = math.radians(params.max_turn)
    ang = max(-limit, min(limit, math.atan2(dx * ny - dy * nx, dx * nx + dy * ny)))
    c, s = math.cos(ang), math.sin(ang)
    x, y = c * dx - s * dy, s * dx + c * dy
    if params.jitter > 0:
        jitter = math.radians(rng.normal(0.0, params.jitter))
        c, s = math.cos(jitter), math.sin(jitter)
        x, y = c * x - s * y, s * x + c * y
    return np.array([x, y])


def _ray_hits(p, d, reach, a, e):
    """Distances along the ray p + t d (0 < t <= reach) to segments a-(a + e), inf where none."""
    denom = d[0] * e[:, 1] - d[1] * e[:, 0]
    w = a - p
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (w[:, 0] * e[:, 1] - w[:, 1] * e[:, 0]) / denom
        u = (w[:, 0] * d[1] - w[:, 1] * d[0]) / denom
    ok = (np.abs(denom) > 1e-12) & (t > 1e-6) & (t <= reach) & (u >= 0) & (u <= 1)
    return np.where(ok, t, np.inf)


def point_segment_distance(p, a, b):
    e = b - a
    ll = np.einsum("ij,ij->i", e, e)
    return _segment_distance(p, a, e, np.where(ll > 0, ll, 1.0))


def _segment_distance(p, a, e, edge_sq):
    t = (np.einsum("ij,ij->i", p - a, e) / edge_sq).clip(0, 1)
    proj = a + t[:, None] * e
    return np.hypot(*(p - proj).T)


def trace(
    start: np.ndarray,
    direction: np.ndarray,
    field: TensorField,
    index: SegmentIndex,
    bounds: tuple[float, float],
    params: GrowthParams,
    rng: np.random.Generator,
    ignore_roads: frozenset = frozenset(),
    ignore_for: float = 0.0,
) -> Trace:
    """Grow one front from ``start``; roads in ``ignore_roads`` are invisible for the first
    ``ignore_for`` metres (the road a front is seeded on)."""
    width, height = bounds
    p = np.asarray(start, dtype=float)
    d = np.asarray(direction, dtype=float) / np.hypot(*direction)
    pts = [p.copy()]
    own = _OwnPath(p, params)
    travelled = 0.0
    min_cos = math.cos(math.radians(params.min_angle))
    ignored = np.array(sorted(ignore_roads), dtype=int)
    while True:
        d = next_direction(field, p, d, params, rng)
        reach = params.step + params.snap_radius
        near = index.window(p, reach)
        if travelled < ignore_for and len(near.road):
            keep = ~(near.road[:, None] == ignored).any(axis=1)  # np.isin, without its setup
            near = _Window(*(column[keep] for column in near))
        if len(near.a):
            shallow = np.abs(near.unit @ d) > min_cos
            side = _segment_distance(p, near.a, near.edge, near.edge_sq)
            if travelled > 0 and (shallow & (side < params.parallel_gap)).any():
                return Trace(np.array(pts), "blocked")
            if not params.pass_through:  # a front that passes through roads ignores hits
                hits = _ray_hits(p, d, reach, near.a, near.edge)
                k = int(np.argmin(hits))
                if np.isfinite(hits[k]):
                    if shallow[k]:
                        return Trace(np.array(pts), "blocked")
                    pts.append(p + hits[k] * d)
                    return Trace(np.array(pts), "snap")
        q = p + params.step * d
        met = _meets_itself(own, pts, q, params)
        if met is not None:
            return met
        if not (0 <= q[0] <= width and 0 <= q[1] <= height):
            pts.append(_clip_to_box(p, q, width, height))
            return Trace(np.array(pts), "boundary")
        p = q
        pts.append(p.copy())
        own.add(p)
        travelled += params.step
        if travelled >= params.max_length:
            return Trace(np.array(pts), "length")


class _OwnPath:
    """The points a front has laid so far, hashed on a grid so that checking whether the front
    comes back to its own path costs O(1) per step rather than O(path length)."""

    def __init__(self, start: np.ndarray, params: GrowthParams):
        self.cell = params.parallel_gap
        self.recent = int(3 * params.parallel_gap / params.step) + 2
        self.cells: dict[tuple[int, int], list[int]] = defaultdict(list)
        self.pts: list[tuple[float, float]] = []
        self.add(start)

    def add(self, p: np.ndarray) -> None:
        x, y = float(p[0]), float(p[1])
        self.cells[(int(x // self.cell), int(y // self.cell))].append(len(self.pts))
        self.pts.append((x, y))

    def nearest_older(self, q: np.ndarray) -> tuple[int, float]:
        """Index of and distance to the nearest point laid more than ``recent`` steps ago."""
        x, y = float(q[0]), float(q[1])
        cx, cy = int(x // self.cell), int(y // self.cell)
        limit = len(self.pts) - self.recent
        best, best_d = -1, math.inf
        for i in range(cx - 1, cx + 2):
            for j in range(cy - 1, cy + 2):
                for k in self.cells.get((i, j), ()):
                    if k < limit:
                        d = math.hypot(self.pts[k][0] - x, self.pts[k][1] - y)
                        if d < best_d or (d == best_d and k < best):
                            best, best_d = k, d
        return best, best_d


def _meets_itself(own: _OwnPath, pts: list, q: np.ndarray, params: GrowthParams):
    """A front that comes back to its own start closes a ring; one that comes back alongside
    its own earlier path stops (streamlines of radial fields would otherwise spiral forever)."""
    if len(pts) <= own.recent:
        return None
    x, y = float(q[0]), float(q[1])
    if math.hypot(pts[0][0] - x, pts[0][1] - y) < params.snap_radius:
        return Trace(np.array(pts + [pts[0]]), "loop")
    _, dist = own.nearest_older(q)
    if dist < params.parallel_gap:
        return Trace(np.array(pts), "blocked")
    return None


def _clip_to_box(p, q, width, height) -> np.ndarray:
    """The point where segment p-q leaves the box [0, width] x [0, height]."""
    t = 1.0
    for k, hi in ((0, width), (1, height)):
        if q[k] < 0:
            t = min(t, p[k] / (p[k] - q[k]))
        elif q[k] > hi:
            t = min(t, (hi - p[k]) / (q[k] - p[k]))
    return p + t * (q - p)
