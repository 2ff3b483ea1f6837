"""Skeleton-guided road growth (paper §III-C): collectors grown from both sides of the skeleton.

The guide is the structure tensor of the skeleton's own tangents (Eq. (1)-(2)), so grown roads
follow the skeleton's local orientation; far from any skeleton road, where that tensor has no
support, the skeleton generator's basis field takes over.
"""

from __future__ import annotations

import numpy as np

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
    samples = [_line_samples(np.asarray(line, dtype=float).reshape(-1, 2), spacing)
               for line in lines]
    cuts = np.r_[0, np.cumsum([len(points) for points, _ in samples])].astype(np.int64)
    if not samples:
        return np.zeros((0, 2)), np.zeros((0, 2)), cuts
    return (np.concatenate([p for p, _ in samples]), np.concatenate([t for _, t in samples]),
            cuts)


def _line_samples(line: np.ndarray, spacing: float) -> tuple[np.ndarray, np.ndarray]:
    """Points every ``spacing`` metres along one line, from its start, and the unit tangent of
    the step each lies on."""
    steps = np.diff(line, axis=0)
    length = np.hypot(steps[:, 0], steps[:, 1])
    keep = length > 1e-9
    starts, steps, length = line[:-1][keep], steps[keep], length[keep]
    if not len(length):
        return np.zeros((0, 2)), np.zeros((0, 2))
    upto = np.cumsum(length)
    marks = np.arange(0.0, upto[-1], spacing)
    on = np.minimum(np.searchsorted(upto, marks, side="right"), len(length) - 1)
    along = (marks - np.r_[0.0, upto][on]) / length[on]
    return starts[on] + along[:, None] * steps[on], steps[on] / length[on, None]


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
