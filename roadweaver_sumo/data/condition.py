"""The condition vector c (paper §III-B): a 6-d road-style code and five structural priors.

``c = [style code (6), density, gridness, radialness, organicness, bearing entropy]``, all
measured on a RoadGraph by the functions below, so a generated map can be measured the same way
as the real tiles the model was trained on (docs/condition.md has the definitions and the check
on labelled city centres).
"""

from __future__ import annotations

import math

import networkx as nx
import numpy as np
from scipy.ndimage import gaussian_filter

from .. import metrics
from ..errors import RoadweaverError
from ..roadgraph import end_directions
from .sampling import edge_segments
from .style_code import STYLE_DIM, style_code

CONDITION_NAMES = tuple(f"style{i}" for i in range(STYLE_DIM)) + (
    "density", "gridness", "radialness", "organicness", "bearing_entropy")
RIGHT_ANGLE_TOL_DEG = 20.0
CURVATURE_SCALE = 4.0  # rad/km at which organicness is 1 - 1/e
CENTRE_SIGMA_M = 250.0
CENTRE_EXCLUDE_M = 100.0

#: c of the real v1 tiles most like each style (unrotated tiles, bench/prepare_data.py): grid and
#: organic are the top and bottom tenth by gridness − organicness, radial the top tenth by
#: radialness, mixed the fifth nearest the median of gridness − organicness. Means of c.
STYLE_PRESETS = {
    "grid": (-0.486, -0.398, -0.802, 1.055, -1.057, -0.038, 77.051, 0.673, 0.007, 0.095, 2.062),
    "organic": (0.031, 0.119, 0.989, -0.71, 0.59, 0.244, 59.229, 0.065, 0.009, 0.802, 3.472),
    "radial": (0.265, -0.027, -0.15, 0.055, -0.085, 0.041, 71.699, 0.308, 0.19, 0.364, 3.046),
    "mixed": (0.325, -0.127, 0.358, -0.237, 0.145, 0.436, 57.331, 0.308, 0.006, 0.407, 2.981),
}


def right_angle_crossings(G: nx.Graph, tol_deg: float = RIGHT_ANGLE_TOL_DEG,
                          reach: float = metrics.JUNCTION_REACH_M) -> float:
    """Share of junctions (degree >= 3) that are four-way crossings whose four angles are all
    within ``tol_deg`` of 90°: the local signature of a grid, whatever its orientation.

    A road's direction at a junction is taken to the point ``reach`` metres along it, so a
    kink in the first vertex does not count."""
    degree = dict(G.degree())
    n_junctions = sum(1 for d in degree.values() if d >= 3)
    if n_junctions == 0:
        return 0.0
    nodes, angles = end_directions(G, reach)
    ids = {n: i for i, n in enumerate(G.nodes)}
    four = np.array([degree[n] == 4 for n in nodes], dtype=bool)
    if not four.any():
        return 0.0
    node_id = np.array([ids[n] for n in nodes])[four]
    a = np.mod(angles[four], 2 * math.pi)
    a = a[np.lexsort((a, node_id))].reshape(-1, 4)
    gaps = np.degrees(np.diff(np.column_stack([a, a[:, :1] + 2 * math.pi]), axis=1))
    return float(np.all(np.abs(gaps - 90.0) < tol_deg, axis=1).sum() / n_junctions)


def gridness(G: nx.Graph) -> float:
    """Mean of Boeing's orientation order φ (global: one dominant pair of directions) and the
    share of right-angle crossings (local: streets cross squarely). 1 for a perfect grid.

    φ alone is a function of the bearing entropy, already in c; the crossing share adds the
    local evidence, so a town of several differently oriented grids still scores high.
    """
    phi = min(max(metrics.orientation_order(G), 0.0), 1.0) if G.number_of_edges() else 0.0
    return 0.5 * phi + 0.5 * right_angle_crossings(G)


def densest_centre(G: nx.Graph, sigma: float = CENTRE_SIGMA_M) -> np.ndarray:
    """Where road nodes are densest: the peak of their Gaussian kernel density (σ = 250 m) on a
    50 m grid, refined off the grid by one mean-shift step."""
    pts = np.array([G.nodes[n]["xy"] for n, d in G.degree() if d != 2], dtype=float)
    w, h = G.graph["width"], G.graph["height"]
    if len(pts) == 0:
        return np.array([w / 2, h / 2])
    cell = sigma / 5
    shape = (int(h // cell) + 1, int(w // cell) + 1)
    hist, _, _ = np.histogram2d(pts[:, 1], pts[:, 0], bins=shape,
                                range=[[0, shape[0] * cell], [0, shape[1] * cell]])
    iy, ix = np.unravel_index(np.argmax(gaussian_filter(hist, sigma / cell)), shape)
    peak = np.array([(ix + 0.5) * cell, (iy + 0.5) * cell])
    w = np.exp(-0.5 * (np.hypot(*(pts - peak).T) / sigma) ** 2)  # one mean-shift step
    return (w[:, None] * pts).sum(axis=0) / w.sum()


def radialness(G: nx.Graph, centre: np.ndarray | None = None,
               exclude: float = CENTRE_EXCLUDE_M) -> float:
    """How much more road segments line up with the radius from the densest centre than their
    directions and positions would by chance.

    With α the angle between a segment and the line from the centre to its midpoint, this is
    the length-weighted mean of cos 4α minus its expectation when directions and positions are
    paired at random (Re(m_θ m̄_β), m the weighted mean of exp(4i·angle) of the directions θ and
    of the radii β). Radial roads (α = 0) and ring roads (α = 90°) count alike, as in the radial
    basis field of tensor-field street modelling (Chen et al. 2008); a grid or a random network
    scores about 0 wherever its centre lies, a radial-concentric town close to 1.
    Segments within 100 m of the centre are ignored.
    """
    a, b = edge_segments(G)
    if len(a) == 0:
        return 0.0
    centre = densest_centre(G) if centre is None else np.asarray(centre, dtype=float)
    d, r = b - a, (a + b) / 2 - centre
    length, dist = np.hypot(*d.T), np.hypot(*r.T)
    keep = (dist > exclude) & (length > 0)
    if not keep.any():
        return 0.0
    w = length[keep] / length[keep].sum()
    theta = np.exp(4j * np.arctan2(d[keep, 1], d[keep, 0]))
    beta = np.exp(4j * np.arctan2(r[keep, 1], r[keep, 0]))
    observed = np.sum(w * theta * beta.conj()).real
    chance = (np.sum(w * theta) * np.sum(w * beta).conj()).real
    return float(observed - chance)


def main_road_radialness(G: nx.Graph, candidates: int = 20) -> float:
    """:func:`radialness` of the arterials and collectors around the centre where it is
    highest (a grid of ``candidates`` x ``candidates`` points): whether the main roads are the
    spokes and rings of one centre, as a reader sees a radial town. Learned `radial` maps
    measure 0.5-0.7, the other styles 0.1-0.2 (bench/style_gallery.py); real 2 km tiles
    0.25-0.47 (p10-p90), since their few main roads line up with some centre by chance."""
    main = G.edge_subgraph([(u, v) for u, v, c in G.edges(data="road_class")
                            if c in ("arterial", "collector")])
    if main.number_of_edges() == 0:
        return 0.0
    xs, ys = (np.linspace(0.0, G.graph[side], candidates + 2)[1:-1]
              for side in ("width", "height"))
    return max(radialness(main, np.array([x, y])) for x in xs for y in ys)


def organicness(G: nx.Graph) -> float:
    """1 − exp(−κ / 4 rad/km), κ the mean absolute curvature: 0 for straight streets, about 0.6
    for the curving streets of organic city centres."""
    return 1.0 - math.exp(-metrics.mean_curvature(G) / CURVATURE_SCALE)


def structural_priors(G: nx.Graph, area_km2: float) -> np.ndarray:
    """The five priors: density (road nodes/km²), gridness, radialness, organicness, bearing
    entropy (nats, osmnx definition via metrics.bearing_entropy)."""
    return np.array([metrics.density(G, area_km2), gridness(G), radialness(G), organicness(G),
                     metrics.bearing_entropy(G)], dtype=np.float32)


def condition_vector(G: nx.Graph, area_km2: float) -> np.ndarray:
    """c ∈ R^11: the style code (see :mod:`.style_code`) followed by the five priors."""
    return np.concatenate([style_code(G), structural_priors(G, area_km2)]).astype(
        np.float32)


def style_preset(style: str, **priors: float) -> np.ndarray:
    """c for ``--style grid|radial|organic|mixed``, with any of the five priors overridden by
    name (``density=60, gridness=0.8`` ...), measured as :func:`structural_priors` measures."""
    if style not in STYLE_PRESETS:
        raise RoadweaverError(f"unknown style {style!r}; choose one of {', '.join(STYLE_PRESETS)}")
    return with_priors(STYLE_PRESETS[style], **priors)


def with_priors(c, **priors: float) -> np.ndarray:
    """Condition vector ``c`` with the named structural priors replaced."""
    c = np.array(c, dtype=np.float32)
    for name, value in priors.items():
        if name not in CONDITION_NAMES[STYLE_DIM:]:
            raise RoadweaverError(f"unknown structural prior {name!r}")
        c[CONDITION_NAMES.index(name)] = value
    return c
