"""The map's boundary (issue 35): open by default, as a map cut out of a town, or a ring road.

The expansion builds every map inside a perimeter ring road (``skeleton.model.perimeter``):
every block the density fill splits closes against it. No real map has one. A map cut out of a
larger network has roads that run off its edge, and a frame road makes 11-21 % of the road
length run along the border, where real tiles have about 2 % (issue 35, measured by
``bench/realism.py``). :func:`open_boundary` cuts the finished map out of the ring as a real map
is cut out of a town: everything within :data:`BAND` of the ring goes (the ring, its junctions,
roads that ran along it), every road that crossed into that band runs on to the map edge and
ends there as a fringe road, and pieces that only the ring held to the map (a road cutting a
corner, a small tree off the ring) are left outside. The density fill aims at the road nodes
that remain (:func:`opened_road_nodes`).
"""

from __future__ import annotations

import math

import networkx as nx
import numpy as np
import shapely

from ..metrics import road_node_count
from ..roadgraph import add_road, edge_coords, edge_list
from ..skeleton.model import perimeter
from .bends import round_corners
from .clearance import clearance
from .perimeter import components_main_first
from .planar import CLASS_RANK

#: metres either side of the ring's centre line that go with it: more than a rounded corner
#: of the ring strays from it, less than a clearance (no other road runs that close to it).
BAND = 6.0


def open_boundary(G: nx.Graph) -> None:
    """Cut ``G`` out of its perimeter ring (module docstring): edges through the band are cut at
    its inner side and taken square on to the nearest map edge, a cut end closer than a
    clearance to another one goes back to its road's junction, nodes in the band and every
    piece but the main one go."""
    band = shapely.Polygon(perimeter(G.graph["width"], G.graph["height"])).buffer(BAND)
    band = band.difference(band.buffer(-2 * BAND))
    cut_ends = []
    for u, v, data in edge_list(G):
        line = shapely.LineString(data["coords"])
        if not line.intersects(band):
            continue
        G.remove_edge(u, v)
        for part in shapely.get_parts(line.difference(band)):
            if part.is_empty:
                continue
            cut_ends += _reattach(G, u, v, np.asarray(part.coords), data["road_class"])
    _drop_crowded_ends(G, cut_ends)
    inside = shapely.Polygon(band.interiors[0])
    G.remove_nodes_from([n for n in list(G) if not inside.covers(shapely.Point(G.nodes[n]["xy"]))
                         and n not in cut_ends])
    for comp in components_main_first(G)[1:]:
        G.remove_nodes_from(comp)
    for n in sorted(n for n in cut_ends if n in G):
        _to_edge(G, next(iter(G.neighbors(n))), n)


def opened_road_nodes(G: nx.Graph) -> int:
    """The road nodes ``G`` keeps once its boundary is opened (:func:`open_boundary` on a
    copy): what the density fill aims at on a map with an open boundary."""
    H = G.copy()
    open_boundary(H)
    return road_node_count(H)


def _reattach(G: nx.Graph, u, v, coords: np.ndarray, road_class: str) -> list:
    """Add the part ``coords`` of road u-v left outside the band: an end at u or v stays on
    that node, an end on the band becomes a new node. Returns the new nodes."""
    new = []
    ends = []
    for point in (coords[0], coords[-1]):
        node = next((n for n in (u, v) if np.allclose(G.nodes[n]["xy"], point, atol=1e-3)),
                    None)
        if node is None:
            node = max(G) + 1
            G.add_node(node, xy=(float(point[0]), float(point[1])))
            new.append(node)
        ends.append(node)
    if ends[0] != ends[1]:
        add_road(G, ends[0], ends[1], coords, road_class)
    return new


def _drop_crowded_ends(G: nx.Graph, cut_ends: list) -> None:
    """Of two cut ends closer than their roads' clearance (two roads that met at one ring
    junction), the road of the lower class (else the later one) goes back to its junction."""
    G.remove_nodes_from([n for n in cut_ends if G.degree(n) != 1])  # a part too short to be a road
    ends = sorted((-CLASS_RANK[_road_class(G, n)], n, _road_class(G, n), G.nodes[n]["xy"])
                  for n in cut_ends if n in G)
    kept: list = []
    for _, n, road_class, xy in ends:
        if any(math.dist(xy, other) < clearance(road_class, cls) for cls, other in kept):
            G.remove_node(n)
        else:
            kept.append((road_class, xy))
    cut_ends[:] = [n for n in cut_ends if n in G and G.degree(n) == 1]


def _road_class(G: nx.Graph, n) -> str:
    """The class of the one road of cut end ``n``."""
    return G.edges[n, next(iter(G.neighbors(n)))]["road_class"]


def _to_edge(G: nx.Graph, other, n) -> None:
    """Take dead-end node ``n`` (its road from ``other``) square out to the nearest map edge,
    the corner rounded."""
    x, y = G.nodes[n]["xy"]
    width, height = G.graph["width"], G.graph["height"]
    side = int(np.argmin([x, width - x, y, height - y]))
    G.nodes[n]["xy"] = ((0.0, width, x, x)[side], (y, y, 0.0, height)[side])
    coords = np.vstack([edge_coords(G, other, n), [G.nodes[n]["xy"]]])
    road_class = G.edges[other, n]["road_class"]
    G.remove_edge(other, n)
    add_road(G, other, n, round_corners(coords, 30.0, 20.0), road_class)
