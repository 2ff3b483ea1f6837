"""Learned skeleton (paper §III-B): sample a road field from the trained model, vectorise it.

c is the style preset measured on real tiles (``data.condition.STYLE_PRESETS``) with the
requested density. The transformer knows densities only as dense as its training tiles (about
35 to 150 road nodes/km²); a sparser request samples a denser layout over a proportionally larger
window (``scale`` > 1), so block shapes stay real while blocks grow. The decoded field's
centrelines, squared up (:mod:`.square_up`) and with side streets continued into crossroads
by the gridness prior (:mod:`.crossroads`), become the skeleton roads, its orientation
channels the basis field and its road channel the A* cost map; the expansion then grows,
reconnects and fills to the exact density.
"""

from __future__ import annotations

import math
from functools import lru_cache

import networkx as nx
import numpy as np
import shapely
from scipy.ndimage import gaussian_filter, map_coordinates

from ..data.condition import CONDITION_NAMES, STYLE_PRESETS, with_priors
from ..data.field import field_to_graph
from ..portable import FLOAT32_DECIMALS, portable
from ..roadgraph import edge_coords, edge_length
from ..spec import STAGE_CROSSROADS, STAGE_SKELETON, ScenarioSpec
from ..tensor_field import TensorField, blend, field_grid, from_cross, magnitude, to_cross
from .crossroads import stem_continuations
from .model import Skeleton, perimeter
from .procedural import FIELD_RES, basis_field, block_size, trace_arterials
from .square_up import square_up

#: Densities (road nodes/km²) the training tiles cover well (5th..95th percentile of v1).
MODEL_DENSITY = (35.0, 145.0)
BASIS_SIGMA_M = 60.0
#: Strokes (roads followed straight on through junctions) ranked by length: the longest ones
#: making up this share of the road length are arterials, the next share collectors.
ARTERIAL_SHARE, COLLECTOR_SHARE = 0.25, 0.25
STROKE_MAX_DEFLECTION_DEG = 35.0
STROKE_REACH_M = 40.0
RADIAL_CLEARANCE_M = 30.0


@lru_cache(maxsize=2)
def shipped_generator():
    from ..generative.sampling import Generator

    return Generator.load()


def condition_for(spec: ScenarioSpec) -> tuple[np.ndarray, float]:
    """c for the spec (the style's preset with the priors of the ``--like`` city, then those
    the user set) and the window scale that makes the model's density the requested one."""
    lo, hi = MODEL_DENSITY
    model_density = float(np.clip(spec.density, lo, hi))
    scale = math.sqrt(model_density / spec.density) if spec.density < lo else 1.0
    priors = {**(spec.like["priors"] if spec.like else {}), **spec.priors,
              "density": model_density}
    return with_priors(STYLE_PRESETS[spec.style], **priors), scale


def learned_skeleton(spec: ScenarioSpec) -> Skeleton:
    from ..generative.sampling import sample_field

    gen = shipped_generator()
    c, scale = condition_for(spec)
    seed = int(spec.rng(STAGE_SKELETON).integers(2**31))
    F, res = sample_field(gen, c, spec.width, spec.height, seed, scale=scale)
    F = portable(F, FLOAT32_DECIMALS).astype(F.dtype)

    gridness = float(c[CONDITION_NAMES.index("gridness")])

    def centrelines() -> tuple[list, list]:
        graph = field_to_graph(F, F.shape[1] * res, threshold=gen.road_threshold)
        if spec.boundary == "ring":  # ring maps stay the maps of earlier versions
            return _clipped_roads(graph, spec.width, spec.height)
        square_up(graph, gridness=gridness)
        lines, classes = _clipped_roads(graph, spec.width, spec.height)
        extra = stem_continuations(lines, block_size(spec.density), gridness,
                                   spec.rng(STAGE_CROSSROADS))
        return lines + extra, classes + ["local"] * len(extra)

    def fields() -> tuple[TensorField, np.ndarray]:
        return _basis_field(F, res, spec), _resample(F[..., 0], res, spec.width, spec.height)

    (lines, classes), (basis, road_prob) = centrelines(), fields()
    if spec.style == "radial" and spec.boundary == "open":
        lines, classes, basis = _radial_frame(spec, lines, classes)
    return Skeleton(
        polylines=lines,
        frame=perimeter(spec.width, spec.height),
        basis=basis,
        road_prob=road_prob,
        res=FIELD_RES,
        classes=classes,
        grow_from_frame=True,
        provenance={"generator": "learned", "attribution": gen.meta.get("attribution", ""),
                    "condition": [round(float(v), 4) for v in c], "window_scale": scale},
    )


def _radial_frame(spec: ScenarioSpec, lines: list, classes: list):
    """The radial style's arterials, spokes and rings round a centre, traced through the
    procedural radial field (Chen et al. 2008), over the learned roads; learned roads that
    mostly run within :data:`RADIAL_CLEARANCE_M` of one are dropped as its duplicates. The
    fill follows the radial field. The model itself ignores its radialness prior: learned
    `radial` maps measured 0.00 ± 0.05 against the preset's 0.19 and showed no centre."""
    field = basis_field(spec, spec.rng(STAGE_SKELETON))
    arterials = trace_arterials(spec, field, perimeter(spec.width, spec.height),
                                spec.rng(STAGE_SKELETON))
    near = shapely.union_all([shapely.LineString(a).buffer(RADIAL_CLEARANCE_M)
                              for a in arterials])
    kept_lines, kept_classes = list(arterials), ["arterial"] * len(arterials)
    for line, cls in zip(lines, classes, strict=True):
        road = shapely.LineString(line)
        if shapely.intersection(road, near).length <= 0.5 * road.length:
            kept_lines.append(line)
            kept_classes.append("local" if cls == "arterial" else cls)
    return kept_lines, kept_classes, field


def _resample(channel: np.ndarray, res: float, width: float, height: float) -> np.ndarray:
    """A field channel (pixels ``res`` m) bilinearly on the FIELD_RES grid of the map."""
    X, Y = field_grid(width, height, FIELD_RES)
    return map_coordinates(channel, [Y / res - 0.5, X / res - 0.5], order=1, mode="nearest")


def _basis_field(F: np.ndarray, res: float, spec: ScenarioSpec) -> TensorField:
    """The decoded orientation channels, smoothed as crosses (``tensor_field``), where the field
    has roads; the style's procedural basis field where it has none (there the decoded
    direction is noise, and roads the expansion fills in would wander)."""
    c4, s4 = to_cross(TensorField(F[..., 1], F[..., 2], res))
    c4, s4 = (_resample(gaussian_filter(ch, BASIS_SIGMA_M / res), res, spec.width, spec.height)
              for ch in (c4, s4))
    mag = magnitude(c4, s4)
    full = max(float(np.quantile(mag, 0.9)), 1e-6)
    unit = 1.0 / np.maximum(mag, 1e-9)
    learned = from_cross(c4 * unit, s4 * unit, FIELD_RES)
    return blend(learned, mag / full, basis_field(spec, spec.rng(STAGE_SKELETON)))


def _clipped_roads(G: nx.Graph, width: float, height: float):
    """Edge polylines inside the map, each with its road class from the stroke hierarchy."""
    road_class = stroke_classes(G)
    lines, classes = [], []
    for u, v in sorted(G.edges):
        clipped = shapely.clip_by_rect(shapely.LineString(edge_coords(G, u, v)),
                                       0.0, 0.0, width, height)
        for part in getattr(clipped, "geoms", [clipped]):
            if part.geom_type == "LineString" and part.length > 1.0:
                lines.append(np.asarray(part.coords))
                classes.append(road_class[(u, v)])
    return lines, classes


def stroke_classes(G: nx.Graph) -> dict[tuple, str]:
    """Road class per edge from "strokes": at each junction, the pairs of roads that continue
    each other most straightly (deflection under 35°) are joined; long strokes are the main
    roads (arterial), the next longest collectors, the rest local (natural road hierarchy,
    Thomson 2006)."""
    parent = {_key(*e): _key(*e) for e in G.edges}

    def find(e):
        while parent[e] != e:
            parent[e] = parent[parent[e]]
            e = parent[e]
        return e

    for n in sorted(G.nodes):
        if G.degree(n) < 2:
            continue
        ends = []
        for v in sorted(G.neighbors(n)):
            coords = edge_coords(G, n, v)
            d = np.cumsum(np.hypot(*np.diff(coords, axis=0).T))
            k = min(int(np.searchsorted(d, STROKE_REACH_M)) + 1, len(coords) - 1)
            vec = coords[k] - coords[0]
            ends.append((math.atan2(vec[1], vec[0]), _key(n, v)))
        pairs = []
        for i in range(len(ends)):
            for j in range(i + 1, len(ends)):
                turn = abs((ends[i][0] - ends[j][0]) % (2 * math.pi) - math.pi)
                pairs.append((math.degrees(turn), i, j))
        used = set()
        for deflection, i, j in sorted(pairs):
            if deflection > STROKE_MAX_DEFLECTION_DEG or i in used or j in used:
                continue
            used.update((i, j))
            parent[find(ends[i][1])] = find(ends[j][1])
    length: dict = {}
    for e in G.edges:
        root = find(_key(*e))
        length[root] = length.get(root, 0.0) + edge_length(G, *e)
    total = sum(length.values()) or 1.0
    ranked = sorted(length, key=lambda r: (-length[r], r))
    cls, acc = {}, 0.0
    for r in ranked:
        share = acc / total
        cls[r] = ("arterial" if share < ARTERIAL_SHARE
                  else "collector" if share < ARTERIAL_SHARE + COLLECTOR_SHARE else "local")
        acc += length[r]
    out = {}
    for u, v in G.edges:
        out[(u, v)] = out[(v, u)] = cls[find(_key(u, v))]
    return out


def _key(u, v) -> tuple:
    return (u, v) if u <= v else (v, u)
