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
that remain (the road nodes of :func:`opened`); pruning spares what holds the opened map
together (:func:`spare_when_opened`), and an opened map with too many road nodes is pruned
itself.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable

import networkx as nx
import numpy as np
import shapely

from ..roadgraph import add_road, edge_coords, edge_list
from ..skeleton.model import perimeter
from .bends import round_corners
from .clearance import clearance
from .fill import on_cycle
from .perimeter import components_main_first
from .planar import CLASS_RANK, road_lines

#: metres either side of the ring's centre line that go with it: more than a rounded corner
#: of the ring strays from it, less than a clearance (no other road runs that close to it).
BAND = 6.0


def open_boundary(G: nx.Graph) -> None:
    """Cut ``G`` out of its perimeter ring (module docstring): edges through the band are cut at
    its inner side and taken square on to the nearest map edge, a cut end closer than a
    clearance to another one goes back to its road's junction, nodes in the band and every
    piece but the main one go."""
    inside, band = _band(G)
    new_ids = itertools.count(max(G, default=-1) + 1)
    cut_ends = []
    for u, v, data in edge_list(G):
        line = shapely.LineString(data["coords"])
        if not line.intersects(band):
            continue
        G.remove_edge(u, v)
        for part in shapely.get_parts(line.difference(band)):
            if not part.is_empty:
                cut_ends += _reattach(G, u, v, np.asarray(part.coords), data["road_class"],
                                      new_ids)
    _drop_crowded_ends(G, cut_ends)
    nodes = list(G)
    outside = ~shapely.covers(inside, shapely.points([G.nodes[n]["xy"] for n in nodes]))
    ends = set(cut_ends)
    G.remove_nodes_from([n for n, out in zip(nodes, outside.tolist(), strict=True)
                         if out and n not in ends])
    for comp in components_main_first(G)[1:]:
        G.remove_nodes_from(comp)
    for n in sorted(n for n in cut_ends if n in G):
        _to_edge(G, next(iter(G.neighbors(n))), n)


def opened(G: nx.Graph) -> nx.Graph:
    """A copy of ``G`` with its boundary opened (:func:`open_boundary`)."""
    H = G.copy()
    open_boundary(H)
    return H


def spare_when_opened(G: nx.Graph) -> Callable[[int, int], bool]:
    """Whether the opened map holds together without road u-v (for ``prune_to_density``): a
    road into the ring's band always does (it becomes a fringe road, which holds nothing
    together), any other road if its ends stay connected by roads clear of the band. Without
    this, pruning in the ring's presence leaves parts that only the ring holds to the map, and
    opening drops them (sparse learned maps lost up to half their road nodes at once). Roads
    are only removed from ``G`` while the answer is in use."""
    edges = edge_list(G)
    _, band = _band(G)
    hits = shapely.intersects(road_lines(edges), band).tolist() if edges else []
    into_band = {frozenset((u, v)) for (u, v, _), hit in zip(edges, hits, strict=True) if hit}
    clear = nx.subgraph_view(G, filter_edge=lambda u, v: frozenset((u, v)) not in into_band)
    return lambda u, v: frozenset((u, v)) in into_band or on_cycle(clear, u, v)


def on_map_edge(G: nx.Graph, n) -> bool:
    """Whether node ``n`` lies on the map's edge (a fringe road's end: :func:`_to_edge`)."""
    x, y = G.nodes[n]["xy"]
    return min(x, y, G.graph["width"] - x, G.graph["height"] - y) < 1e-6


def _band(G: nx.Graph) -> tuple[shapely.Polygon, shapely.Polygon]:
    """The map inside the ring's band, and the band: :data:`BAND` either side of the ring."""
    ring = shapely.Polygon(perimeter(G.graph["width"], G.graph["height"]))
    inside = ring.buffer(-BAND)
    return inside, ring.buffer(BAND).difference(inside)


def _reattach(G: nx.Graph, u, v, coords: np.ndarray, road_class: str, new_ids) -> list:
    """Add the part ``coords`` of road u-v left outside the band: an end at u or v stays on
    that node, an end on the band becomes a new node (ids from ``new_ids``). Returns the new
    nodes."""
    new = []
    ends = []
    for point in (coords[0], coords[-1]):
        node = next((n for n in (u, v) if np.allclose(G.nodes[n]["xy"], point, atol=1e-3)),
                    None)
        if node is None:
            node = next(new_ids)
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
    classes = {n: _road_class(G, n) for n in cut_ends if n in G}
    kept: list = []
    for n in sorted(classes, key=lambda n: (-CLASS_RANK[classes[n]], n)):
        road_class, xy = classes[n], G.nodes[n]["xy"]
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
