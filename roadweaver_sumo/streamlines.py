"""Tracing roads through a tensor field (paper §III-C, Eq. (3)-(5)) against the roads already drawn.

One tracer serves the skeleton (arterials that pass through each other) and the expansion
(collectors and locals that end on the first road they meet). A front advances by Euler steps;
each step picks the tensor eigen-direction closest to the current heading, blends it with the
heading (inertia), clamps the turn, adds style jitter, and then looks ahead for existing roads.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba as nb
import numpy as np

from .compiled import F8, F8_1D, F8_2D, I8, I8_1D, I8_2D, compiled
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
    """A dynamic uniform-grid index of road segments (shapely's STRtree cannot grow).

    Each grid cell holds a linked list of its segments in flat arrays (``head`` per cell,
    ``entry_seg`` / ``entry_next`` per entry), so the compiled tracer can walk the cells; the
    grid grows when a segment lands outside it."""

    def __init__(self, cell: float = 50.0):
        self.cell = cell
        self.a = np.zeros((256, 2))
        self.b = np.zeros((256, 2))
        self.road = np.zeros(256, dtype=np.int64)
        self.size = 0
        self.origin = (0, 0)  # cell (cx, cy) of head[0, 0]
        self.head = np.full((1, 1), -1, dtype=np.int64)  # first entry of each cell, -1: none
        self.entry_seg = np.zeros(1024, dtype=np.int64)
        self.entry_next = np.zeros(1024, dtype=np.int64)
        self.entries = 0

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
        lo = np.floor(np.minimum(coords[:-1], coords[1:]) / self.cell).astype(np.int64)
        hi = np.floor(np.maximum(coords[:-1], coords[1:]) / self.cell).astype(np.int64)
        if n > 0:
            self._cover(lo.min(axis=0), hi.max(axis=0))
        span = (hi - lo + 1).prod(axis=1)
        while self.entries + int(span.sum()) > len(self.entry_seg):
            self.entry_seg = np.concatenate([self.entry_seg, np.zeros_like(self.entry_seg)])
            self.entry_next = np.concatenate([self.entry_next, np.zeros_like(self.entry_next)])
        self.entries = _link_segments(lo - self.origin, hi - self.origin, first, self.head,
                                      self.entry_seg, self.entry_next, self.entries)

    def _cover(self, lo: np.ndarray, hi: np.ndarray) -> None:
        """Grow the grid (with a margin) until it covers cells ``lo`` to ``hi``."""
        ny, nx = self.head.shape
        ox, oy = self.origin
        if lo[0] >= ox and lo[1] >= oy and hi[0] < ox + nx and hi[1] < oy + ny:
            return
        new_ox, new_oy = min(ox, int(lo[0]) - 8), min(oy, int(lo[1]) - 8)
        new_nx = max(ox + nx, int(hi[0]) + 9) - new_ox
        new_ny = max(oy + ny, int(hi[1]) + 9) - new_oy
        head = np.full((new_ny, new_nx), -1, dtype=np.int64)
        head[oy - new_oy : oy - new_oy + ny, ox - new_ox : ox - new_ox + nx] = self.head
        self.head, self.origin = head, (new_ox, new_oy)

    def near(self, p: np.ndarray, radius: float) -> np.ndarray:
        """Ids of segments that may lie within ``radius`` of ``p`` (a superset), ascending."""
        x, y = float(p[0]), float(p[1])
        x0, y0 = int((x - radius) // self.cell), int((y - radius) // self.cell)
        x1, y1 = int((x + radius) // self.cell), int((y + radius) // self.cell)
        ox, oy = self.origin
        return np.unique(_cell_segments(self.head, self.entry_seg, self.entry_next,
                                        x0 - ox, y0 - oy, x1 - ox, y1 - oy))

    def arrays(self, ids: np.ndarray):
        return self.a[ids], self.b[ids], self.road[ids]


@compiled(I8_1D(I8_2D, I8_1D, I8_1D, I8, I8, I8, I8))
def _cell_segments(head, entry_seg, entry_next, x0, y0, x1, y1):
    """The segments listed in grid cells x0..x1 by y0..y1 (clipped to the grid), with
    repeats: a segment crossing several cells is listed in each."""
    ny, nx = head.shape
    count = 0
    for step in range(2):  # count, then fill
        found = np.empty(count, dtype=np.int64)
        count = 0
        for cy in range(max(y0, 0), min(y1, ny - 1) + 1):
            for cx in range(max(x0, 0), min(x1, nx - 1) + 1):
                e = head[cy, cx]
                while e >= 0:
                    if step == 1:
                        found[count] = entry_seg[e]
                    count += 1
                    e = entry_next[e]
    return found


@compiled(I8(I8_2D, I8_2D, I8, I8_2D, I8_1D, I8_1D, I8))
def _link_segments(lo, hi, first, head, entry_seg, entry_next, entries):
    """Prepend segment ``first + k`` to every grid cell from ``lo[k]`` to ``hi[k]``."""
    for k in range(len(lo)):
        for cx in range(lo[k, 0], hi[k, 0] + 1):
            for cy in range(lo[k, 1], hi[k, 1] + 1):
                entry_seg[entries] = first + k
                entry_next[entries] = head[cy, cx]
                head[cy, cx] = entries
                entries += 1
    return entries


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


@compiled(nb.types.UniTuple(F8, 2)(F8_1D, F8_1D, I8, I8, F8, F8, F8, F8, F8))
def _nearest_axis(ux, uy, nx, ny, res, x, y, dx, dy):
    """Compiled :func:`choose_axis` on the field's flattened unit vectors (as ``major_at``)."""
    k = min(max(int(y / res), 0), ny - 1) * nx + min(max(int(x / res), 0), nx - 1)
    ex, ey = ux[k], uy[k]
    along, across = ex * dx + ey * dy, ex * dy - ey * dx
    if abs(along) >= abs(across):
        sign = 1.0 if along >= 0 else -1.0
        return sign * ex, sign * ey
    sign = 1.0 if across >= 0 else -1.0
    return -sign * ey, sign * ex


def follow_field(field: TensorField, start, d: np.ndarray, count: int, max_turn_rad: float,
                 step: float) -> tuple[np.ndarray, np.ndarray]:
    """``count`` Euler steps from ``start`` along the field, each the nearest eigen-direction
    with the turn clamped (:func:`choose_axis` then :func:`clamp_turn`), with no look-out for
    roads: the density fill checks a chunk of steps at once. Returns the new points and the
    last heading; compiled (:func:`_follow_field`), the same bits as the Python steps."""
    ux, uy = field.unit_vectors()
    ny, nx = field.c2.shape
    out = np.empty((count, 2))
    dx, dy = _follow_field(float(start[0]), float(start[1]), float(d[0]), float(d[1]), ux, uy,
                           int(nx), int(ny), float(field.res), float(max_turn_rad), float(step),
                           out)
    return out, np.array([dx, dy])


@compiled(nb.types.UniTuple(F8, 2)(F8, F8, F8, F8, F8_1D, F8_1D, I8, I8, F8, F8, F8, F8_2D))
def _follow_field(x, y, dx, dy, ux, uy, nx, ny, res, max_turn, step, out):
    for n in range(out.shape[0]):
        ax, ay = _nearest_axis(ux, uy, nx, ny, res, x, y, dx, dy)
        ang = max(-max_turn, min(max_turn, math.atan2(dx * ay - dy * ax, dx * ax + dy * ay)))
        c, s = math.cos(ang), math.sin(ang)
        dx, dy = c * dx - s * dy, s * dx + c * dy
        x, y = x + step * dx, y + step * dy
        out[n, 0], out[n, 1] = x, y
    return dx, dy


def point_segment_distance(p, a, b):
    e = b - a
    ll = np.einsum("ij,ij->i", e, e)
    t = (np.einsum("ij,ij->i", p - a, e) / np.where(ll > 0, ll, 1.0)).clip(0, 1)
    proj = a + t[:, None] * e
    return np.hypot(*(p - proj).T)


ENDS = ("boundary", "snap", "blocked", "loop", "length")


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
    ``ignore_for`` metres (the road a front is seeded on).

    The steps run in :func:`_trace_steps`, compiled: a 10 km map takes some 70,000 of them,
    and as numpy calls on a handful of nearby segments each cost about 0.1 ms. The style
    jitter is drawn here ahead of the steps, and the generator is then moved on by exactly
    the draws the steps used, so the stream stays what one draw per step would make it."""
    p = np.asarray(start, dtype=float)
    d = np.asarray(direction, dtype=float) / np.hypot(*direction)
    most_steps = int(params.max_length / params.step) + 4
    jittered = params.jitter > 0
    if jittered:
        state = rng.bit_generator.state
        jitter = np.radians(rng.normal(0.0, params.jitter, size=most_steps))
    else:
        jitter = np.zeros(most_steps)
    ux, uy = field.unit_vectors()
    out = np.empty((most_steps + 2, 2))
    ny, nx = field.c2.shape
    count, end, used = _trace_steps(  # plain Python scalars: one compiled signature only
        float(p[0]), float(p[1]), float(d[0]), float(d[1]), ux, uy, int(nx), int(ny),
        float(field.res), index.a, index.b, index.road, index.head, index.entry_seg,
        index.entry_next, int(index.origin[0]), int(index.origin[1]), float(index.cell),
        float(bounds[0]), float(bounds[1]), float(params.step), math.radians(params.max_turn),
        float(params.w_tensor), float(params.w_inertia), jitter, float(params.snap_radius),
        float(params.parallel_gap), float(params.max_length),
        math.cos(math.radians(params.min_angle)), bool(params.pass_through),
        np.array(sorted(ignore_roads), dtype=np.int64), float(ignore_for),
        int(3 * params.parallel_gap / params.step) + 2, out)
    if jittered:
        rng.bit_generator.state = state
        rng.normal(0.0, params.jitter, size=used)
    return Trace(out[:count].copy(), ENDS[end])


@compiled(nb.boolean(I8_1D, I8))
def _contains(values, value) -> bool:
    for v in values:
        if v == value:
            return True
    return False


@compiled(nb.types.UniTuple(I8, 3)(
    F8, F8, F8, F8, F8_1D, F8_1D, I8, I8, F8, F8_2D, F8_2D, I8_1D, I8_2D, I8_1D, I8_1D, I8, I8,
    F8, F8, F8, F8, F8, F8, F8, F8_1D, F8, F8, F8, F8, nb.boolean, I8_1D, F8, I8, F8_2D))
def _trace_steps(px, py, dx, dy, ux, uy, nx, ny, res, seg_a, seg_b, seg_road, head, entry_seg,
                 entry_next, ox, oy, cell, width, height, step, max_turn, w_tensor, w_inertia,
                 jitter, snap_radius, parallel_gap, max_length, min_cos, pass_through, ignored,
                 ignore_for, recent, out):
    """The front's Euler steps (paper Eq. (3)-(5)); fills ``out`` with the polyline and
    returns (points, index of the end in ``ENDS``, jitter draws used). Each step:
    1. the eigen-direction nearest the heading, blended with it (inertia), the turn clamped
       to ``max_turn``, then the jitter;
    2. the segments in the grid cells within ``step + snap_radius``: a nearly parallel one
       closer than ``parallel_gap`` blocks the front; otherwise the first road the next step
       would cross is snapped to (unless fronts pass through roads);
    3. a front coming back to its start closes a loop, one coming back alongside its own
       earlier path (older than ``recent`` points) is blocked; the map border ends it."""
    out[0, 0], out[0, 1] = px, py
    count, travelled, used = 1, 0.0, 0
    reach = step + snap_radius
    gy, gx = head.shape
    while True:
        # 1. direction
        ax, ay = _nearest_axis(ux, uy, nx, ny, res, px, py, dx, dy)
        bx, by = w_tensor * ax + w_inertia * dx, w_tensor * ay + w_inertia * dy
        norm = np.hypot(bx, by)
        if norm > 1e-9:
            nxd, nyd = bx / norm, by / norm
        else:
            nxd, nyd = dx, dy
        ang = max(-max_turn, min(max_turn, math.atan2(dx * nyd - dy * nxd, dx * nxd + dy * nyd)))
        c, s = math.cos(ang), math.sin(ang)
        x, y = c * dx - s * dy, s * dx + c * dy
        if jitter[used] != 0.0:
            c, s = math.cos(jitter[used]), math.sin(jitter[used])
            x, y = c * x - s * y, s * x + c * y
        used += 1
        dx, dy = x, y
        # 2. nearby roads
        blocked, best_t, best_seg, best_shallow = False, np.inf, -1, False
        x0, y0 = int((px - reach) // cell) - ox, int((py - reach) // cell) - oy
        x1, y1 = int((px + reach) // cell) - ox, int((py + reach) // cell) - oy
        for cy in range(max(y0, 0), min(y1, gy - 1) + 1):
            for cx in range(max(x0, 0), min(x1, gx - 1) + 1):
                e = head[cy, cx]
                while e >= 0:
                    sid = entry_seg[e]
                    e = entry_next[e]
                    if travelled < ignore_for and _contains(ignored, seg_road[sid]):
                        continue
                    sax, say = seg_a[sid, 0], seg_a[sid, 1]
                    evx, evy = seg_b[sid, 0] - sax, seg_b[sid, 1] - say
                    length = max(np.hypot(evx, evy), 1e-9)
                    shallow = abs((evx / length) * dx + (evy / length) * dy) > min_cos
                    sq = evx * evx + evy * evy
                    if sq <= 0:
                        sq = 1.0
                    t = min(max(((px - sax) * evx + (py - say) * evy) / sq, 0.0), 1.0)
                    side = np.hypot(px - (sax + t * evx), py - (say + t * evy))
                    if travelled > 0 and shallow and side < parallel_gap:
                        blocked = True
                    denom = dx * evy - dy * evx
                    if abs(denom) > 1e-12:
                        wx, wy = sax - px, say - py
                        hit = (wx * evy - wy * evx) / denom
                        u = (wx * dy - wy * dx) / denom
                        first = hit < best_t or (hit == best_t and sid < best_seg)
                        if 1e-6 < hit <= reach and 0 <= u <= 1 and first:
                            best_t, best_seg, best_shallow = hit, sid, shallow
        if blocked:
            return count, 2, used
        if not pass_through and best_seg >= 0:
            if best_shallow:
                return count, 2, used
            out[count, 0], out[count, 1] = px + best_t * dx, py + best_t * dy
            return count + 1, 1, used
        # 3. the step
        qx, qy = px + step * dx, py + step * dy
        if count > recent:
            if math.hypot(out[0, 0] - qx, out[0, 1] - qy) < snap_radius:
                out[count, 0], out[count, 1] = out[0, 0], out[0, 1]
                return count + 1, 3, used
            for j in range(count - recent):
                if math.hypot(out[j, 0] - qx, out[j, 1] - qy) < parallel_gap:
                    return count, 2, used
        if not (0 <= qx <= width and 0 <= qy <= height):
            t = 1.0
            if qx < 0:
                t = min(t, px / (px - qx))
            elif qx > width:
                t = min(t, (width - px) / (qx - px))
            if qy < 0:
                t = min(t, py / (py - qy))
            elif qy > height:
                t = min(t, (height - py) / (qy - py))
            out[count, 0], out[count, 1] = px + t * (qx - px), py + t * (qy - py)
            return count + 1, 0, used
        px, py = qx, qy
        out[count, 0], out[count, 1] = px, py
        count += 1
        travelled += step
        if travelled >= max_length:
            return count, 4, used
