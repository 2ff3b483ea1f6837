"""Clean-up of the planar road graph (paper §III-C): remove what a road engineer would not draw.

Near-duplicate junctions are merged and slivers of road contracted (:mod:`.junction_merge`),
junction angles that are too sharp resolved by dropping the minor road
(:mod:`.junction_angles`), stubs that run off the map pruned, fragments outside the main
component (the one holding the perimeter ring, :mod:`.perimeter`) dropped, roads within
another's clearance removed (:mod:`.clearance`), and degree-2 nodes dissolved into longer
roads; passes repeat until nothing changes. Then corners are rounded (:mod:`.bends`).
"""

from __future__ import annotations

import math

import networkx as nx
import numpy as np
import shapely

from ..clearance import roads_too_close
from ..roadgraph import add_road, edge_coords, edge_length, sorted_edge_list
from .bends import smooth_bends
from .junction_angles import HAIRPIN_ANGLE, meeting_angle, remove_sharp_angles
from .junction_merge import contract_short_edges, merge_close_nodes
from .node_sweep import sweep_nodes
from .perimeter import components_main_first, road_keep_weight
from .planar import higher_class, road_lines


def dissolve_degree_two(G: nx.Graph, min_angle_deg: float = 0.0) -> None:
    """Join the two roads at a degree-2 node into one, unless that would duplicate a road or
    the two meet at less than ``min_angle_deg`` or ``HAIRPIN_ANGLE`` (the joined road would
    double back: that V is :func:`.junction_angles.remove_sharp_angles`' to resolve).

    A join keeps the degree of every other node (its ends trade a road for a road), so the
    nodes of degree 2 are found once."""
    limit = math.radians(max(min_angle_deg, HAIRPIN_ANGLE))
    for n in sorted(n for n, degree in G.degree() if degree == 2):
        a, b = sorted(G.neighbors(n))
        if a == b or G.has_edge(a, b):
            continue
        if meeting_angle(G, n) < limit:
            continue
        ca, cb = edge_coords(G, a, n), edge_coords(G, n, b)
        cls = higher_class(G.edges[a, n]["road_class"], G.edges[n, b]["road_class"])
        G.remove_node(n)
        add_road(G, a, b, np.vstack([ca, cb[1:]]), cls)


def prune_stubs(G: nx.Graph, max_length: float, margin: float) -> None:
    """Remove dead-end roads shorter than ``max_length`` or ending within ``margin`` of the map
    border (roads cut off by the border), and nodes left without a road, sweeping the nodes
    in order until none is left, so chains of stubs go too.

    Whether a node goes depends on its own roads alone, so a sweep visits only the nodes
    with at most one road at its start and those that lost one since they were looked at
    (as :func:`.junction_angles.remove_sharp_angles` does)."""
    width, height = G.graph["width"], G.graph["height"]

    def at_border(n):
        x, y = G.nodes[n]["xy"]
        return min(x, y, width - x, height - y) < margin

    def visit(n):
        if n not in G or G.degree(n) > 1:
            return ()
        roads = list(G.neighbors(n))
        if roads and not (at_border(n) or edge_length(G, n, roads[0]) < max_length):
            return ()
        G.remove_node(n)
        return roads  # a lone node goes without another sweep

    sweep_nodes([n for n, degree in G.degree() if degree <= 1], visit)


def keep_largest_component(G: nx.Graph) -> None:
    """The component filter: keep the component holding the perimeter ring road, else the
    largest. Every block the density fill splits closes against the ring; once fragments of a
    learned skeleton are reconnected, a cluster of them can outnumber the ring's component in
    nodes, and keeping it left a 2 km map with 0.15 km² of blocks."""
    for comp in components_main_first(G)[1:]:
        G.remove_nodes_from(comp)


def remove_close_roads(G: nx.Graph) -> bool:
    """Remove, of every pair of roads closer than their lanes allow (:mod:`.clearance`), the
    road less worth keeping (:func:`.perimeter.road_keep_weight`); returns whether one went."""
    removed = False
    for a, b in roads_too_close(G):
        if G.has_edge(*a) and G.has_edge(*b):
            G.remove_edge(*min(a, b, key=lambda e: (*road_keep_weight(G, *e), e)))
            removed = True
    return removed


def clean(G: nx.Graph, min_edge: float, min_angle: float, stub: float, margin: float,
          keep_largest: bool = True, min_block_area: float = 0.0) -> None:
    """The whole clean-up: junctions closer than ``0.8 min_edge`` merged, then passes over the
    whole graph until nothing changes, then corners rounded (:func:`.bends.smooth_bends`).
    ``keep_largest=False`` keeps every component: the clean-up before A* reconnection, which
    may join them (paper §III-C). ``min_block_area``: open blocks smaller than this
    (:func:`open_tiny_blocks`), then clean again.

    Junctions close together are merged once: no pass moves or adds a node, so none come
    close later. Roads too close to another (:func:`remove_close_roads`) are looked for once
    the other passes change nothing: that check measures every pair of neighbouring roads."""
    merge_close_nodes(G, min_edge * 0.8)
    for _ in range(MAX_ROUNDS):
        before = (G.number_of_nodes(), G.number_of_edges())
        contract_short_edges(G, min_edge)
        remove_sharp_angles(G, min_angle)
        prune_stubs(G, stub, margin)
        if keep_largest:
            keep_largest_component(G)
        dissolve_degree_two(G, min_angle)
        if (G.number_of_nodes(), G.number_of_edges()) == before:
            if not remove_close_roads(G):
                break
            if keep_largest:
                keep_largest_component(G)
    if min_block_area > 0 and open_tiny_blocks(G, min_block_area):
        clean(G, min_edge, min_angle, stub, margin, keep_largest, min_block_area)
        return
    smooth_bends(G)


MAX_ROUNDS = 20  # passes of the clean-up at most; maps settle in a handful


#: A block smaller than this is a sliver between junctions, not a city block: netconvert's
#: junction shapes swallow its sides. A 146 m² triangle of 16-26 m roads by the ring road of a
#: learned map left roads 0 m long between overlapping junctions; cars locked up there and,
#: after a teleport, one hit another. :func:`open_tiny_blocks` removes its least road.
MIN_BLOCK_AREA = 500.0


def open_tiny_blocks(G: nx.Graph, min_area: float = MIN_BLOCK_AREA) -> list[tuple]:
    """Remove from each block (face) smaller than ``min_area`` the road least worth keeping
    (:func:`.perimeter.road_keep_weight`: never the ring, lowest class, shortest); returns
    those roads."""
    roads = sorted_edge_list(G)
    if not roads:
        return []
    edges = [(u, v) for u, v, _ in roads]
    lines = road_lines(roads)
    blocks = [p for p in shapely.get_parts(shapely.polygonize(lines)) if 1.0 < p.area < min_area]
    if not blocks:
        return []
    tree = shapely.STRtree(lines)
    removed = []
    for block in sorted(blocks, key=lambda p: p.bounds):
        sides = [edges[k] for k in tree.query(block.exterior, predicate="covers")]
        if not sides or not all(G.has_edge(*e) for e in sides):
            continue  # a side already went with a neighbouring block's: the two are one now
        road = min(sides, key=lambda e: (*road_keep_weight(G, *e), e))
        G.remove_edge(*road)
        removed.append(road)
    return removed
