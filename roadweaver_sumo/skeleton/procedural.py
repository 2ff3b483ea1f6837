"""Procedural skeleton: principal roads traced through a blend of basis tensor fields.

The style decides the basis fields (Chen et al. 2008, "Interactive procedural street modeling"):
grid fields with an orientation, radial fields around a centre, and a smooth rotation noise for
organic towns. Arterials are hyperstreamlines of that field, seeded one family from the other at
the arterial spacing. The learned skeleton (paper §III-B) will plug in behind the same
``Skeleton`` result.
"""

from __future__ import annotations

import math
from collections import deque

import numpy as np
from scipy.ndimage import gaussian_filter

from ..spec import STAGE_SKELETON, ScenarioSpec
from ..streamlines import GrowthParams, SegmentIndex, point_segment_distance, trace
from ..tensor_field import TensorField, field_grid
from .model import Skeleton, perimeter, road_field_from_polylines

FIELD_RES = 10.0  # metres per tensor-field cell


def block_size(density: float) -> float:
    """Spacing (m) of a square grid whose junction density is ``density`` per km²."""
    return 1000.0 / math.sqrt(density)


def arterial_spacing(density: float) -> float:
    return float(np.clip(3.0 * block_size(density), 300.0, 900.0))


STYLE_PARAMS = {
    #          jitter  inertia  max_turn  noise_deg
    "grid": (0.3, 0.5, 8.0, 0.0),
    "radial": (0.8, 0.5, 10.0, 8.0),
    "mixed": (1.5, 0.5, 12.0, 15.0),
    "organic": (3.0, 0.4, 15.0, 100.0),
}


def basis_field(spec: ScenarioSpec, rng: np.random.Generator) -> TensorField:
    """Sum of the style's basis fields, each weighted by a Gaussian decay from its centre."""
    W, H = spec.width, spec.height
    X, Y = field_grid(W, H, FIELD_RES)
    scale = max(W, H)
    c2 = np.zeros_like(X)
    s2 = np.zeros_like(X)

    def add_grid(cx, cy, theta, decay, weight=1.0):
        w = weight * np.exp(-((X - cx) ** 2 + (Y - cy) ** 2) / (2 * decay**2))
        c2[:] += w * math.cos(2 * theta)
        s2[:] += w * math.sin(2 * theta)

    def add_radial(cx, cy, decay, weight=1.0):
        w = weight * np.exp(-((X - cx) ** 2 + (Y - cy) ** 2) / (2 * decay**2))
        theta = np.arctan2(Y - cy, X - cx)
        c2[:] += w * np.cos(2 * theta)
        s2[:] += w * np.sin(2 * theta)

    theta0 = rng.uniform(0, math.pi / 2)
    centre = (W * rng.uniform(0.35, 0.65), H * rng.uniform(0.35, 0.65))
    if spec.style == "grid":
        add_grid(*centre, theta0, scale)
        add_grid(W * rng.uniform(), H * rng.uniform(), theta0 + rng.normal(0, 0.03), 0.4 * scale, 0.3)
    elif spec.style == "radial":
        add_radial(*centre, 0.35 * scale, 1.0)
        add_grid(*centre, theta0, scale, 0.15)
    elif spec.style == "organic":
        for _ in range(8):
            add_grid(W * rng.uniform(), H * rng.uniform(), rng.uniform(0, math.pi), 0.2 * scale)
    else:  # mixed
        for _ in range(3):
            add_grid(W * rng.uniform(), H * rng.uniform(), rng.uniform(0, math.pi), 0.3 * scale)
        add_radial(*centre, 0.2 * scale, 0.8)
    theta = 0.5 * np.arctan2(s2, c2)
    noise_deg = STYLE_PARAMS[spec.style][3]
    if noise_deg > 0:
        noise = gaussian_filter(rng.normal(size=X.shape), 250.0 / FIELD_RES, mode="wrap")
        noise /= max(np.abs(noise).max(), 1e-9)
        theta = theta + math.radians(noise_deg) * noise
    return TensorField(np.cos(2 * theta), np.sin(2 * theta), FIELD_RES)


def growth_params(spec: ScenarioSpec, spacing: float, **overrides) -> GrowthParams:
    jitter, inertia, max_turn, _ = STYLE_PARAMS[spec.style]
    base = {
        "step": 10.0,
        "max_turn": max_turn,
        "w_inertia": inertia,
        "jitter": jitter,
        "snap_radius": 25.0,
        "parallel_gap": 0.5 * spacing,
        "max_length": 4 * max(spec.width, spec.height),
        "min_angle": 35.0,
    }
    base.update(overrides)
    return GrowthParams(**base)


def trace_arterials(spec: ScenarioSpec, field: TensorField, frame, rng) -> list[np.ndarray]:
    """Hyperstreamlines of both eigen-families, each seeded along the other at the spacing."""
    spacing = arterial_spacing(spec.density)
    params = growth_params(spec, spacing, pass_through=True)
    index = SegmentIndex(cell=max(50.0, spacing / 4))
    index.add(frame, -1)
    bounds = (spec.width, spec.height)
    start = np.array([spec.width * rng.uniform(0.4, 0.6), spec.height * rng.uniform(0.4, 0.6)])
    seeds = deque([(start, 0)])
    lines: list[np.ndarray] = []
    while seeds and len(lines) < 400:
        p, family = seeds.popleft()
        if _too_close(index, p, 0.6 * spacing, field, family):
            continue
        line = _trace_both_ways(p, family, field, index, bounds, params, rng)
        if _length(line) < min(spacing, 0.5 * min(spec.width, spec.height)):
            continue
        road_id = len(lines)
        index.add(line, road_id)
        lines.append(line)
        for q in _points_every(line, spacing, offset=float(rng.uniform(0.3, 0.7)) * spacing):
            seeds.append((q, 1 - family))
    return lines


def _too_close(index: SegmentIndex, p, radius: float, field: TensorField, family: int) -> bool:
    """Is a road of the same family (nearly parallel to this one) already within ``radius``?"""
    ids = index.near(p, radius)
    if len(ids) == 0:
        return False
    a, b, _ = index.arrays(ids)
    e = field.major(p[0], p[1])
    d = e if family == 0 else np.array([-e[1], e[0]])
    seg = (b - a) / np.maximum(np.hypot(*(b - a).T), 1e-9)[:, None]
    dist = point_segment_distance(p, a, b)
    return bool(np.any((np.abs(seg @ d) > math.cos(math.radians(35))) & (dist < radius)))


def _trace_both_ways(p, family, field, index, bounds, params, rng) -> np.ndarray:
    e = field.major(p[0], p[1])
    d = e if family == 0 else np.array([-e[1], e[0]])
    fwd = trace(p, d, field, index, bounds, params, rng).coords
    bwd = trace(p, -d, field, index, bounds, params, rng).coords
    return np.vstack([bwd[::-1], fwd[1:]])


def _length(line: np.ndarray) -> float:
    return float(np.hypot(*np.diff(line, axis=0).T).sum()) if len(line) > 1 else 0.0


def _points_every(line: np.ndarray, spacing: float, offset: float) -> list[np.ndarray]:
    seg = np.hypot(*np.diff(line, axis=0).T)
    s = np.concatenate([[0.0], np.cumsum(seg)])
    marks = np.arange(offset, s[-1], spacing)
    return [np.array([np.interp(m, s, line[:, 0]), np.interp(m, s, line[:, 1])]) for m in marks]


def procedural_skeleton(spec: ScenarioSpec) -> Skeleton:
    """Skeleton stage, procedural variant: arterials + the road field the expansion uses."""
    rng = spec.rng(STAGE_SKELETON)
    field = basis_field(spec, rng)
    frame = perimeter(spec.width, spec.height)
    lines = trace_arterials(spec, field, frame, rng)
    road_prob = road_field_from_polylines(lines + [frame], field.c2.shape, FIELD_RES, width_m=60.0)
    return Skeleton(polylines=lines, frame=frame, basis=field, road_prob=road_prob, res=FIELD_RES)
