"""Building RoadGraphs from polylines: the shared step of OSM import, tile cutting and
field vectorisation.

A RoadGraph is a simple :class:`networkx.Graph`, so two roads between the same pair of nodes, or a
road that returns to its start, need extra degree-2 nodes. Those do not change the road-node count
(metrics.py counts degree != 2 only) and keep every polyline addressable by its end nodes.
"""

from __future__ import annotations

from collections.abc import Callable, Hashable
from itertools import count, pairwise

import networkx as nx
import numpy as np

from ..roadgraph import add_road, edge_coords

MIN_LOOP_M = 1.0  # closed polylines shorter than this are digitising noise


def node_counter(G: nx.Graph, start: int | None = None) -> Callable[[], int]:
    """A source of fresh integer node ids that do not collide with those of ``G``."""
    if start is None:
        ints = [n for n in G.nodes if isinstance(n, (int, np.integer))]
        start = (max(ints) + 1) if ints else 0
    it = count(start)
    return lambda: next(it)


def _cut(coords: np.ndarray, parts: int) -> list[np.ndarray]:
    """``coords`` cut into ``parts`` polylines of equal length (cut points become vertices)."""
    s = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(coords, axis=0).T))])
    marks = s[-1] * np.arange(1, parts) / parts
    cuts = np.column_stack([np.interp(marks, s, coords[:, 0]), np.interp(marks, s, coords[:, 1])])
    order = np.argsort(np.concatenate([s, marks]), kind="stable")
    points = np.vstack([coords, cuts])[order]
    at = np.flatnonzero(order >= len(coords))
    bounds = np.concatenate([[0], at, [len(points) - 1]])
    return [points[a : b + 1] for a, b in pairwise(bounds)]


def _same_polyline(G: nx.Graph, u, v, coords: np.ndarray) -> bool:
    old = edge_coords(G, u, v)
    return old.shape == coords.shape and np.allclose(old, coords)


def add_segment(
    G: nx.Graph, u: Hashable, v: Hashable, coords, road_class: str, fresh: Callable[[], int]
) -> None:
    """Add road u-v with polyline ``coords`` (from u to v; end nodes must already exist).

    A second, different road between u and v is split in two by a degree-2 node; a closed road
    (u == v) in three. An exact duplicate (two OSM ways over the same nodes) is ignored.
    """
    coords = np.asarray(coords, dtype=float)
    length = float(np.hypot(*np.diff(coords, axis=0).T).sum())
    if u == v:
        if length < MIN_LOOP_M:
            return
        parts = 3
    elif G.has_edge(u, v):
        if _same_polyline(G, u, v, coords) or length == 0.0:
            return
        parts = 2
    else:
        add_road(G, u, v, coords, road_class)
        return
    pieces = _cut(coords, parts)
    ends = [u] + [fresh() for _ in range(parts - 1)] + [v]
    for node, piece in zip(ends[1:-1], pieces[1:]):
        G.add_node(node, xy=(float(piece[0, 0]), float(piece[0, 1])))
    for a, b, piece in zip(ends[:-1], ends[1:], pieces):
        add_road(G, a, b, piece, road_class)



def relabel_consecutive(G: nx.Graph) -> nx.Graph:
    """A copy of ``G`` with nodes 0..n-1 (in insertion order) and ``start`` attributes updated."""
    mapping = {n: i for i, n in enumerate(G.nodes)}
    H = nx.relabel_nodes(G, mapping, copy=True)
    for _, _, data in H.edges(data=True):
        data["start"] = mapping[data["start"]]
    return H
