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
    pts, tans = [], []
    for line in lines:
        seg = np.diff(line, axis=0)
        length = np.hypot(*seg.T)
        keep = length > 1e-9
        seg, length, starts = seg[keep], length[keep], line[:-1][keep]
        s = np.concatenate([[0.0], np.cumsum(length)])
        marks = np.arange(0.0, s[-1], spacing)
        k = np.clip(np.searchsorted(s, marks, side="right") - 1, 0, len(seg) - 1)
        frac = (marks - s[k]) / length[k]
        pts.append(starts[k] + frac[:, None] * seg[k])
        tans.append(seg[k] / length[k][:, None])
    if not pts:
        return np.zeros((0, 2)), np.zeros((0, 2))
    return np.vstack(pts), np.vstack(tans)


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
    for k, line in sources:
        points, tangents = tangent_samples([line], spacing)
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
