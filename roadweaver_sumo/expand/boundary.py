"""The map's boundary (issue 35): open by default, a map cut out of a larger town, or a ring road.

The expansion builds every map inside a perimeter ring road (``skeleton.model.perimeter``):
every block the density fill splits closes against it. No real map has one. A map cut out of a
larger network has roads that run off its edge at whatever angle they had, and a frame road
makes 11-21 % of the road length run along the border, where real tiles have about 2 %
(issue 35, measured by ``bench/realism.py``). So an open map is generated as a larger town,
:data:`TOWN_MARGIN` more on every side (``ScenarioSpec.town``), and :func:`open_boundary` cuts
the map out of it as a real map is cut out of a town: roads that cross the map edge end there
as fringe roads, everything outside goes (the ring with it), and pieces that only roads
outside held to the map are left out. The density fill aims at the road nodes that remain
(the road nodes of :func:`opened`); pruning spares what holds the cut map together
(:func:`spare_when_opened`), and a cut map with too many road nodes is pruned itself.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable

import networkx as nx
import numpy as np
import shapely

from ..clearance import clearance
from ..roadgraph import add_road, edge_coords, edge_list
from ..spec import TOWN_MARGIN
from .fill import on_cycle
from .perimeter import components_main_first
from .planar import CLASS_RANK, road_lines

#: metres of road a fringe road keeps at least: a junction just inside the map edge keeps no
#: stub of a road the edge cuts (a stub of a few metres lies inside the junction's own area);
#: the shortest road the clean-up keeps (``MIN_EDGE``), as real tiles' fringe roads run from
#: 13 m (p10) up
MIN_FRINGE = 12.0


def open_boundary(G: nx.Graph) -> None:
    """Cut the map out of the town ``G`` (module docstring): roads are cut at the map edge,
    a cut end closer than a clearance to another one goes back to its road's junction, nodes
    outside and every piece but the main one go, and the map's corner becomes the origin."""
    inside, outside = _map_and_outside(G)
    new_ids = itertools.count(max(G, default=-1) + 1)
    cut_ends = []
    for u, v, data in edge_list(G):
        line = shapely.LineString(data["coords"])
        if not line.intersects(outside):
            continue
        G.remove_edge(u, v)
        for part in shapely.get_parts(shapely.clip_by_rect(line, *inside.bounds)):
            if not part.is_empty and part.length > 0.0:
                cut_ends += _reattach(G, u, v, np.asarray(part.coords), data["road_class"],
                                      new_ids)
    _drop_crowded_ends(G, cut_ends)
    nodes = list(G)  # none in a density round whose town kept no road
    xy = np.array([G.nodes[n]["xy"] for n in nodes], dtype=float).reshape(-1, 2)
    out = ~shapely.covers(inside, shapely.points(xy))
    ends = set(cut_ends)
    G.remove_nodes_from([n for n, o in zip(nodes, out.tolist(), strict=True)
                         if o and n not in ends])
    for comp in components_main_first(G)[1:]:
        G.remove_nodes_from(comp)
    _move_to_map_frame(G)


def opened(G: nx.Graph) -> nx.Graph:
    """A copy of ``G`` with its boundary opened (:func:`open_boundary`)."""
    H = G.copy()
    open_boundary(H)
    return H


def spare_when_opened(G: nx.Graph) -> Callable[[int, int], bool]:
    """Whether the opened map holds together without road u-v (for ``prune_to_density``): a
    road that leaves the map always does (it becomes a fringe road, which holds nothing
    together), any other road if its ends stay connected by roads inside the map. Without
    this, pruning in the town leaves parts that only roads outside hold to the map, and
    cutting drops them (sparse learned maps lost up to half their road nodes at once). Roads
    are only removed from ``G`` while the answer is in use."""
    edges = edge_list(G)
    _, outside = _map_and_outside(G)
    hits = shapely.intersects(road_lines(edges), outside).tolist() if edges else []
    leaving = {frozenset((u, v)) for (u, v, _), hit in zip(edges, hits, strict=True) if hit}
    clear = nx.subgraph_view(G, filter_edge=lambda u, v: frozenset((u, v)) not in leaving)
    return lambda u, v: frozenset((u, v)) in leaving or on_cycle(clear, u, v)


def on_map_edge(G: nx.Graph, n) -> bool:
    """Whether node ``n`` of a cut map lies on its edge (a fringe road's end)."""
    x, y = G.nodes[n]["xy"]
    return min(x, y, G.graph["width"] - x, G.graph["height"] - y) < 1e-6


def _map_and_outside(G: nx.Graph) -> tuple[shapely.Polygon, shapely.Polygon]:
    """The map inside the town ``G`` (:data:`TOWN_MARGIN` in from each side) and the rest."""
    width, height = G.graph["width"], G.graph["height"]
    inside = shapely.box(TOWN_MARGIN, TOWN_MARGIN, width - TOWN_MARGIN, height - TOWN_MARGIN)
    return inside, shapely.box(-1.0, -1.0, width + 1.0, height + 1.0).difference(inside)


def _move_to_map_frame(G: nx.Graph) -> None:
    """Shift the cut map so that its corner is the origin; its size is the map's. Cut ends lie
    on the edge to floating-point precision: they are put exactly on it."""
    width, height = G.graph["width"] - 2 * TOWN_MARGIN, G.graph["height"] - 2 * TOWN_MARGIN
    G.graph.update(width=width, height=height)
    for n in G:
        xy = np.asarray(G.nodes[n]["xy"]) - TOWN_MARGIN
        for axis, side in ((0, width), (1, height)):
            for edge in (0.0, side):
                if abs(xy[axis] - edge) < 1e-6:
                    xy[axis] = edge
        G.nodes[n]["xy"] = (float(xy[0]), float(xy[1]))
    for u, v, data in edge_list(G):
        add_road(G, u, v, edge_coords(G, u, v) - TOWN_MARGIN, data["road_class"])


def _reattach(G: nx.Graph, u, v, coords: np.ndarray, road_class: str, new_ids) -> list:
    """Add the part ``coords`` of road u-v inside the map: an end at u or v stays on that
    node, an end on the map edge becomes a new node (ids from ``new_ids``); a part cut at the
    edge shorter than :data:`MIN_FRINGE` is left out. Returns the new nodes."""
    new = []
    ends = []
    at_node = [next((n for n in (u, v) if np.allclose(G.nodes[n]["xy"], point, atol=1e-3)),
                    None) for point in (coords[0], coords[-1])]
    if None in at_node and shapely.length(shapely.LineString(coords)) < MIN_FRINGE:
        return []
    for point, node in zip((coords[0], coords[-1]), at_node, strict=True):
        if node is None:
            node = next(new_ids)
            G.add_node(node, xy=(float(point[0]), float(point[1])))
            new.append(node)
        ends.append(node)
    if ends[0] != ends[1]:
        add_road(G, ends[0], ends[1], coords, road_class)
    return new


def _drop_crowded_ends(G: nx.Graph, cut_ends: list) -> None:
    """Of two cut ends closer than their roads' clearance (two roads that met at one
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
