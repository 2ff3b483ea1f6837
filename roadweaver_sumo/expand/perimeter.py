"""The perimeter ring road in the clean-up (paper §III-C): the one road never given up.

Every block the density fill splits closes against the ring road round the map
(``skeleton.model.perimeter``). Cutting it, or keeping a fragment's component instead of its
own, leaves the fill no blocks; so a road that runs along it outranks every other road
(:func:`road_keep_weight`), a merge keeps the node on it, and the component holding most of it
is the map (the paper's largest-connected-component filtering, :func:`components_main_first`).
"""

from __future__ import annotations

import networkx as nx
import numpy as np

from ..roadgraph import edge_length, edge_list
from ..skeleton.model import PERIMETER_INSET
from .planar import CLASS_RANK


def road_keep_weight(G, u, v):
    """Which of two roads to keep: the perimeter ring always, then the higher class, then the
    longer road. Cutting the ring for a road that meets it at a shallow angle would leave two
    dead ends at the border, and pruning those unravels the whole ring (seen with fragmentary
    learned skeletons: no block left for the density fill)."""
    return (on_perimeter(G, u, v), CLASS_RANK[G.edges[u, v]["road_class"]], edge_length(G, u, v))


def on_perimeter(G: nx.Graph, u: int, v: int, tolerance: float = 1.0) -> bool:
    """Whether road u-v runs along the perimeter ring road (``skeleton.model.perimeter``).

    Most roads are nowhere near it: their first point, measured first in plain floats (the
    same operations, so the same bits), settles them without the vectorised check."""
    c = np.asarray(G.edges[u, v]["coords"], dtype=float)
    x, y = c[0].tolist()
    lo, hx, hy = PERIMETER_INSET, G.graph["width"] - PERIMETER_INSET, G.graph["height"] - PERIMETER_INSET
    if not min(abs(x - lo), abs(y - lo), abs(x - hx), abs(y - hy)) < tolerance:
        return False
    return bool((_perimeter_offset(G, c) < tolerance).all())


def _perimeter_offset(G: nx.Graph, c: np.ndarray) -> np.ndarray:
    """Each point's distance from the nearest side of the perimeter ring's rectangle."""
    lo, hx, hy = PERIMETER_INSET, G.graph["width"] - PERIMETER_INSET, G.graph["height"] - PERIMETER_INSET
    return np.minimum.reduce([np.abs(c[:, 0] - lo), np.abs(c[:, 1] - lo),
                              np.abs(c[:, 0] - hx), np.abs(c[:, 1] - hy)])


def on_ring(G: nx.Graph, n: int) -> bool:
    """Whether a road of node ``n`` runs along the perimeter ring."""
    return any(on_perimeter(G, n, w) for w in G.neighbors(n))


def _ring_nodes(G: nx.Graph, tolerance: float = 1.0) -> set:
    """The nodes of every road :func:`on_perimeter`, all roads measured in one vectorised
    pass."""
    edges = edge_list(G)
    if not edges:
        return set()
    coords = [np.asarray(data["coords"], dtype=float) for _, _, data in edges]
    owner = np.repeat(np.arange(len(edges)), [len(c) for c in coords])
    away = ~(_perimeter_offset(G, np.concatenate(coords)) < tolerance)
    along = np.bincount(owner[away], minlength=len(edges)) == 0
    return {n for (u, v, _), hit in zip(edges, along.tolist(), strict=True) if hit
            for n in (u, v)}


def components_main_first(G: nx.Graph, comps: list[set] | None = None) -> list[set]:
    """Connected components (or the node sets ``comps``), the one holding the most of the
    perimeter ring first, then by size (ties: lowest node id)."""
    comps = list(nx.connected_components(G)) if comps is None else comps
    if len(comps) <= 1:
        return comps
    ring = _ring_nodes(G)
    return sorted(comps, key=lambda c: (len(c & ring), len(c), -min(c)), reverse=True)
