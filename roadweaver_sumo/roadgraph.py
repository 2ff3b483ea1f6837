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
from shapely.geometry import LineString

ROAD_CLASSES = ("arterial", "collector", "local")


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


def edge_line(G: nx.Graph, u, v) -> LineString:
    """The polyline of edge (u, v) as a shapely LineString (for spatial predicates)."""
    return LineString(G.edges[u, v]["coords"])


def road_nodes(G: nx.Graph) -> list:
    """Nodes whose degree is not 2: intersections and dead ends (the density definition)."""
    return [n for n, d in G.degree() if d != 2]


def total_length(G: nx.Graph) -> float:
    """Sum of the centreline lengths of all roads, metres."""
    return sum(edge_length(G, u, v) for u, v in G.edges)
