"""Skeleton-guided road growth (paper §III-C): collectors grown from both sides of the skeleton.

The guide is the structure tensor of the skeleton's own tangents (Eq. (1)-(2)), so grown roads
follow the skeleton's local orientation; far from any skeleton road, where that tensor has no
support, the skeleton generator's basis field takes over.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from ..compiled import F8, F8_2D, I8_1D, compiled
from ..skeleton import Skeleton
from ..skeleton.procedural import block_size, growth_params
from ..spec import ScenarioSpec
from ..streamlines import SegmentIndex, trace
from ..tensor_field import TensorField, blend, structure_tensor

TANGENT_SPACING = 20.0  # metres between skeleton tangent samples


def skeleton_tensor_field(skeleton: Skeleton, sigma: float = 150.0) -> TensorField:
    """T(p) from skeleton tangents, blended into the basis field where support is thin."""
    points, tangents = tangent_samples(skeleton.polylines, TANGENT_SPACING)
    shape = skeleton.basis.c2.shape
    if len(points) == 0:
        return skeleton.basis
    field, support = structure_tensor(points, tangents, shape, skeleton.res, sigma, 3 * sigma)
    # support is Σ g_i; one sample per cell within ~σ gives ≈ 2πσ²/(res·spacing)·peak weight.
    full = 0.5 * np.quantile(support[support > 0], 0.5) if np.any(support > 0) else 1.0
    return blend(field, support / full, skeleton.basis)


def tangent_samples(lines: list[np.ndarray], spacing: float) -> tuple[np.ndarray, np.ndarray]:
    """Points every ``spacing`` metres along the lines with their unit tangents."""
    pts, tans, _ = _samples_each(lines, spacing)
    return pts, tans


def _samples_each(lines: list[np.ndarray], spacing: float):
    """:func:`tangent_samples` of all lines stacked, and where each line's samples start."""
    if not lines:
        return np.zeros((0, 2)), np.zeros((0, 2)), np.zeros(1, dtype=np.int64)
    lines = [np.asarray(line, dtype=float).reshape(-1, 2) for line in lines]
    offsets = np.r_[0, np.cumsum([len(line) for line in lines])]
    return _tangent_steps(np.ascontiguousarray(np.concatenate(lines)), offsets, float(spacing))


@compiled(nb.types.Tuple((F8_2D, F8_2D, I8_1D))(F8_2D, I8_1D, F8))
def _tangent_steps(points, offsets, spacing):
    """The samples of each line ``points[offsets[k]:offsets[k + 1]]``: marks ``i * spacing``
    along its steps longer than 1e-9 m (numpy's ``arange``), each on the step it falls in
    (``searchsorted``), its distance summed in order (``cumsum``); numpy's operations in
    numpy's order, so the same bits as measuring line by line with numpy."""
    n = len(offsets) - 1
    size = len(points)
    step_x, step_y, length = np.empty(size), np.empty(size), np.empty(size)
    from_x, from_y, upto = np.empty(size), np.empty(size), np.empty(size)
    first = np.zeros(n + 1, dtype=np.int64)  # each line's first kept step
    cuts = np.zeros(n + 1, dtype=np.int64)
    for k in range(n):
        q, total = first[k], 0.0
        for m in range(offsets[k], offsets[k + 1] - 1):
            dx, dy = points[m + 1, 0] - points[m, 0], points[m + 1, 1] - points[m, 1]
            h = math.hypot(dx, dy)
            if h > 1e-9:
                step_x[q], step_y[q], length[q] = dx, dy, h
                from_x[q], from_y[q] = points[m, 0], points[m, 1]
                total += h
                upto[q] = total
                q += 1
        first[k + 1] = q
        cuts[k + 1] = cuts[k] + max(math.ceil(total / spacing), 0)
    pts, tans = np.empty((cuts[n], 2)), np.empty((cuts[n], 2))
    for k in range(n):
        q0, steps = first[k], first[k + 1] - first[k]
        idx = 0
        for i in range(cuts[k + 1] - cuts[k]):
            mark = i * spacing
            while idx + 1 <= steps and upto[q0 + idx] <= mark:
                idx += 1
            q = q0 + min(idx, steps - 1)
            before = upto[q - 1] if q > q0 else 0.0
            frac = (mark - before) / length[q]
            pts[cuts[k] + i, 0] = from_x[q] + frac * step_x[q]
            pts[cuts[k] + i, 1] = from_y[q] + frac * step_y[q]
            tans[cuts[k] + i, 0] = step_x[q] / length[q]
            tans[cuts[k] + i, 1] = step_y[q] / length[q]
    return pts, tans, cuts


def grow_collectors(
    spec: ScenarioSpec, skeleton: Skeleton, field: TensorField, rng: np.random.Generator
) -> list[np.ndarray]:
    """Fronts seeded on both sides of every skeleton road, grown until they meet a road."""
    spacing = 2.2 * block_size(spec.density)
    params = growth_params(spec, spacing, parallel_gap=0.45 * spacing, max_length=3 * spacing * 4)
    index = SegmentIndex(cell=50.0)
    for k, line in enumerate(skeleton.polylines):
        index.add(line, k)
    index.add(skeleton.frame, -1)
    roads: list[np.ndarray] = []
    seeds = []
    sources = list(enumerate(skeleton.polylines))
    if skeleton.grow_from_frame:
        sources.append((-1, skeleton.frame))
    all_points, all_tangents, cuts = _samples_each([line for _, line in sources], spacing)
    for (k, _), a, b in zip(sources, cuts[:-1].tolist(), cuts[1:].tolist(), strict=True):
        points, tangents = all_points[a:b], all_tangents[a:b]
        offset = int(rng.integers(1, 3))
        for p, t in zip(points[offset:], tangents[offset:]):
            normal = np.array([-t[1], t[0]])
            seeds.append((p, normal, k))
            seeds.append((p, -normal, k))
    order = rng.permutation(len(seeds))
    bounds = (spec.width, spec.height)
    for s in order:
        p, d, parent = seeds[s]
        tr = trace(p, d, field, index, bounds, params, rng, frozenset([parent]), params.step * 3)
        if len(tr.coords) < 3 or tr.end == "blocked":
            continue
        road_id = len(skeleton.polylines) + len(roads)
        index.add(tr.coords, road_id)
        roads.append(tr.coords)
    return roads
