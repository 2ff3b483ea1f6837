"""The road graph: the undirected, planar street network that every stage after the skeleton shares.

A ``RoadGraph`` is a plain :class:`networkx.Graph` (no subclass, so every networkx algorithm
applies) with these conventions:

* ``G.graph["width"]``, ``G.graph["height"]``: map extent in metres; the map is [0, W] x [0, H],
  x east, y north.
* node attribute ``xy``: ``(x, y)`` floats in metres.
* edge attribute ``coords``: ``(n, 2)`` float array, the centreline polyline, n >= 2; it runs from
  node ``start`` to the other end node, and its first and last points equal those nodes' ``xy``.
* edge attribute ``start``: the node the polyline starts at.
* edge attribute ``road_class``: ``"arterial"``, ``"collector"`` or ``"local"``.

Nodes of degree 2 may exist (to avoid parallel edges or self-loops); the metrics count only
*road nodes*, nodes whose degree is not 2.
"""

from __future__ import annotations

from operator import itemgetter

import networkx as nx
import numpy as np

from .spec import ROAD_CLASSES


def new_road_graph(width: float, height: float) -> nx.Graph:
    """An empty road graph for a map of ``width`` x ``height`` metres."""
    return nx.Graph(width=float(width), height=float(height))


def edge_coords(G: nx.Graph, u, v) -> np.ndarray:
    """The polyline of edge (u, v), oriented so that it starts at ``u``."""
    data = G.edges[u, v]
    coords = data["coords"]
    return coords if data["start"] == u else coords[::-1]


def add_road(G: nx.Graph, u, v, coords, road_class: str) -> None:
    """Add the edge u-v with polyline ``coords`` (from u to v), snapping its ends onto the nodes."""
    if road_class not in ROAD_CLASSES:
        raise ValueError(f"unknown road class {road_class!r}; expected one of {ROAD_CLASSES}")
    coords = np.array(coords, dtype=float)
    coords[0] = G.nodes[u]["xy"]
    coords[-1] = G.nodes[v]["xy"]
    G.add_edge(u, v, coords=coords, start=u, road_class=road_class)


def edge_list(G: nx.Graph) -> list[tuple]:
    """``list(G.edges(data=True))``, the same triples in the same order, built straight from
    the adjacency dicts: networkx's edge view counts the edges by walking them all before
    the list walks them again, a call per edge each time (clean-up asks after every pass)."""
    seen: set = set()
    edges: list = []
    for u, nbrs in G.adjacency():
        edges.extend([(u, v, data) for v, data in nbrs.items() if v not in seen])
        seen.add(u)
    return edges


def sorted_edge_list(G: nx.Graph) -> list[tuple]:
    """:func:`edge_list` in the order of ``sorted(G.edges)``."""
    return sorted(edge_list(G), key=itemgetter(0, 1))


def edge_length(G: nx.Graph, u, v) -> float:
    """Length of the polyline of edge (u, v) in metres. (``np.diff`` computes the same steps;
    clean-up and the fill ask for 100,000 lengths on a 10 km map, and its call costs more than
    the arithmetic.)"""
    c = G.edges[u, v]["coords"]
    step = c[1:] - c[:-1]
    return float(np.hypot(step[:, 0], step[:, 1]).sum())


def total_length(G: nx.Graph) -> float:
    """Sum of the centreline lengths of all roads, metres."""
    return sum(edge_length(G, u, v) for u, v in G.edges)


def merge_degree2(G: nx.Graph) -> nx.Graph:
    """Join the two roads at every degree-2 node into one (in place; returns ``G``).

    Nodes are kept where joining would create a self-loop or a parallel edge, or where the two
    roads have different classes (the class boundary is real information).
    """
    for n in [n for n, d in G.degree() if d == 2]:
        if G.degree(n) != 2:
            continue
        a, b = list(G.neighbors(n))
        ca, cb = G.edges[a, n]["road_class"], G.edges[n, b]["road_class"]
        if a == b or G.has_edge(a, b) or ca != cb:
            continue
        coords = np.vstack([edge_coords(G, a, n), edge_coords(G, n, b)[1:]])
        G.remove_node(n)
        add_road(G, a, b, coords, ca)
    return G


def _arc_frame(G: nx.Graph):
    """All polylines on one increasing arc-length axis (1 m gap between edges), for vectorised
    interpolation along every road at once: (edges, points, arc, edge length, edge offset)."""
    edges = list(G.edges)
    polylines = [G.edges[e]["coords"] for e in edges]
    pts = np.vstack(polylines)
    counts = np.array([len(c) for c in polylines])
    owner = np.repeat(np.arange(len(edges)), counts)
    step = np.hypot(*np.diff(pts, axis=0).T)
    step[np.cumsum(counts)[:-1] - 1] = 0.0  # no length across two edges
    local = np.concatenate([[0.0], np.cumsum(step)])
    start = np.cumsum(counts) - counts
    length = local[start + counts - 1] - local[start]
    offset = np.cumsum(length + 1.0) - (length + 1.0)
    arc = local - local[start][owner] + offset[owner]
    return edges, pts, arc, length, offset


def _at(pts: np.ndarray, arc: np.ndarray, marks: np.ndarray) -> np.ndarray:
    return np.column_stack([np.interp(marks, arc, pts[:, 0]), np.interp(marks, arc, pts[:, 1])])


def resample_roads(G: nx.Graph, step: float) -> tuple[np.ndarray, np.ndarray]:
    """Every road resampled at equal arc-length steps of at most ``step`` metres, ends included:
    points ``(m, 2)`` and the index of the edge (in ``G.edges`` order) each belongs to."""
    if G.number_of_edges() == 0:
        return np.zeros((0, 2)), np.zeros(0, dtype=int)
    _, pts, arc, length, offset = _arc_frame(G)
    n = np.maximum(np.ceil(length / step).astype(int), 1) + 1
    owner = np.repeat(np.arange(len(n)), n)
    t = (np.arange(n.sum()) - np.repeat(np.cumsum(n) - n, n)) / np.repeat(n - 1, n)
    return _at(pts, arc, offset[owner] + t * length[owner]), owner


def end_directions(G: nx.Graph, reach: float) -> tuple[list, np.ndarray]:
    """For both ends of every road: the end node and the angle (radians) in which the road leaves
    it, measured to the point ``reach`` metres along the road (or its far end if shorter)."""
    if G.number_of_edges() == 0:
        return [], np.zeros(0)
    edges, pts, arc, length, offset = _arc_frame(G)
    r = np.minimum(reach, length)
    base = _at(pts, arc, np.concatenate([offset, offset + length]))
    ahead = _at(pts, arc, np.concatenate([offset + r, offset + length - r]))
    starts = [G.edges[e]["start"] for e in edges]
    others = [v if s == u else u for (u, v), s in zip(edges, starts)]
    d = ahead - base
    return starts + others, np.arctan2(d[:, 1], d[:, 0])
