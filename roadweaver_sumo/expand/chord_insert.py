"""Inserting a chord of the density fill (paper §III-C) into the planar road graph.

The chord's ends split the roads they land on into two, at new T-junctions; the chord then
joins them as a local road. A chord that touches any other road is refused, so the graph stays
planar without noding it again.
"""

from __future__ import annotations

import networkx as nx
import numpy as np
from shapely.geometry import LineString, Point

from ..roadgraph import add_road, edge_coords
from .chords import substring_coords
from .edge_index import EdgeIndex


def insert_chord(
    G: nx.Graph, chord: np.ndarray, min_edge: float, index: EdgeIndex, start_node=None
) -> tuple | None:
    """Split the road(s) the chord ends on and add the chord as a local road between them
    (from ``start_node`` itself, if given: a chord that starts at a junction).

    Refused when the chord touches any road other than those it ends on (a dead-end road
    inside the block, say), so the graph stays planar without re-noding. Returns the chord's
    end nodes, or None when refused."""
    line = LineString(chord)
    if start_node is not None:  # the junction's own roads meet the chord's first metres
        line = LineString(substring_coords(line, 2.0, line.length))
    touching = index.near(line, 0.5)
    if not 1 <= len(touching) <= (1 if start_node is not None else 2):
        return None
    nodes = [] if start_node is None else [start_node]
    for point in (chord[0], chord[-1])[len(nodes):]:
        # Look the edge up again for the second end: splitting for the first may have cut it.
        near = index.near(Point(point), 1.0)
        if not near:
            return None
        nodes.append(split_edge_at(G, near[0], point, min_edge, index))
    u, v = nodes
    if u == v:
        return None
    if G.has_edge(u, v):
        # Both ends landed on one road, next to each other: a shape node in the middle of the
        # chord keeps the graph simple (no two roads between the same pair of nodes).
        k = len(chord) // 2
        m = index.new_node_id()
        G.add_node(m, xy=(float(chord[k][0]), float(chord[k][1])))
        for a, b, part in ((u, m, chord[: k + 1]), (m, v, chord[k:])):
            add_road(G, a, b, part, "local")
            index.add(a, b)
        return u, v
    add_road(G, u, v, chord, "local")
    index.add(u, v)
    return u, v


def split_edge_at(G: nx.Graph, edge, point, tolerance: float, index: EdgeIndex):
    """Insert a node on road ``edge`` at ``point`` (or reuse an end node within tolerance)."""
    u, v = edge
    coords = edge_coords(G, u, v)
    line = LineString(coords)
    s = line.project(Point(point))
    if s < tolerance:
        return u
    if line.length - s < tolerance:
        return v
    cls = G.edges[u, v]["road_class"]
    first, second = substring_coords(line, 0.0, s), substring_coords(line, s, line.length)
    node = index.new_node_id()
    G.add_node(node, xy=tuple(second[0]))
    index.remove(u, v)
    G.remove_edge(u, v)
    add_road(G, u, node, first, cls)
    add_road(G, node, v, second, cls)
    index.add(u, node)
    index.add(node, v)
    return node
