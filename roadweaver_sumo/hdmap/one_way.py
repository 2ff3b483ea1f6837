"""One-way streets (issue 36, "Streets"): local streets that carry traffic one way, in
alternating pairs where streets run parallel, as in the cores of real towns.

A one-way street in a real town is rarely one block: it is a street followed straight on
through several junctions, and its neighbour street of the same direction runs the other way,
so that the pair carries both directions (a "one-way pair", or couplet). So:

* candidates are *strokes* of local streets (``realism.stroke_groups``: roads followed straight
  on through junctions), at least ``MIN_STROKE_M`` long, that end at junctions on both
  sides (a dead end or a road leaving the map can only be two-way);
* strokes of similar bearing (``BEARING_BIN_DEG``) are ranked by their offset across that
  bearing and take alternating directions, so neighbours run opposite ways;
* the longest strokes are made one-way first, until ``share`` of the local road length is,
  each only if every node can still reach every other (the road graph stays strongly
  connected; the lane graph's own check follows in ``topology``).

A one-way road is oriented so that it runs along its reference line: it keeps its ``f`` lanes,
centred on the reference line, and has no ``b`` lanes.
"""

from __future__ import annotations

import itertools
import math

import networkx as nx
import numpy as np
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import connected_components

from ..realism import junction_arms, stroke_groups
from .geometry import arc_lengths
from .model import Road

MIN_STROKE_M = 60.0
BEARING_BIN_DEG = 20.0


def choose_one_way(G: nx.Graph, roads: dict[int, Road], share: float) -> None:
    """Make up to ``share`` of the local road length of ``roads`` (one per edge of ``G``)
    one-way, reversing the reference line of a road that runs against its reference line."""
    if share <= 0.0:
        return
    by_edge = {frozenset((r.from_node, r.to_node)): r for r in roads.values()}
    local = sum(_length(r) for r in roads.values() if r.road_class == "local")
    strokes = [s for s in _candidate_strokes(G, by_edge) if s["length"] >= MIN_STROKE_M]
    _alternate(strokes)
    nodes = {n: k for k, n in enumerate(sorted(G.nodes))}
    arcs = {(u, v) for u, v in G.edges} | {(v, u) for u, v in G.edges}
    arcs -= {(r.to_node, r.from_node) for r in roads.values() if r.one_way}  # roundabouts
    chosen = 0.0
    for stroke in sorted(strokes, key=lambda s: (-s["length"], s["path"])):
        if chosen + stroke["length"] > share * local:
            continue
        against = {(b, a) for a, b in stroke["arcs"]}
        if not _strongly_connected(nodes, arcs - against):
            continue
        arcs -= against
        chosen += stroke["length"]
        for a, b in stroke["arcs"]:
            _make_one_way(by_edge[frozenset((a, b))], a)


def _length(road: Road) -> float:
    return float(arc_lengths(road.centreline)[-1])


def _candidate_strokes(G: nx.Graph, by_edge: dict) -> list[dict]:
    """Strokes of local roads between two junctions of three or more arms, each as the
    node path it follows, its arcs in path order, length, bearing and offset."""
    groups = stroke_groups(G, junction_arms(G))
    members: dict = {}
    for edge, root in groups.items():
        members.setdefault(root, []).append(edge)
    strokes = []
    for edges in members.values():
        if any(by_edge[frozenset(e)].road_class != "local" for e in edges):
            continue
        path = _path(edges)
        if path is None or G.degree(path[0]) < 3 or G.degree(path[-1]) < 3:
            continue
        start, end = np.array(G.nodes[path[0]]["xy"]), np.array(G.nodes[path[-1]]["xy"])
        chord = end - start
        bearing = math.atan2(chord[1], chord[0]) % math.pi
        if math.atan2(chord[1], chord[0]) != bearing:  # path runs against its bearing
            path, chord = path[::-1], -chord
        normal = np.array([-math.sin(bearing), math.cos(bearing)])
        centre = np.mean([G.nodes[n]["xy"] for n in path], axis=0)
        strokes.append({"path": tuple(path), "arcs": list(itertools.pairwise(path)),
                        "length": sum(_length(by_edge[frozenset(e)]) for e in edges),
                        "bearing": bearing, "offset": float(centre @ normal)})
    return strokes


def _path(edges: list[tuple]) -> list | None:
    """The nodes of ``edges`` in order along them, or None if they do not form one open
    path (a ring has no ends for its traffic to enter and leave)."""
    H = nx.Graph(list(edges))
    ends = [n for n, d in H.degree if d == 1]
    if len(ends) != 2 or H.number_of_edges() != H.number_of_nodes() - 1:
        return None
    return nx.shortest_path(H, *sorted(ends))


def _alternate(strokes: list[dict]) -> None:
    """Within each bearing bin, strokes ranked by offset alternate direction: every other
    one runs against its bearing (its path reversed)."""
    bins: dict = {}
    for stroke in strokes:
        key = int(math.degrees(stroke["bearing"]) // BEARING_BIN_DEG)
        bins.setdefault(key, []).append(stroke)
    for group in bins.values():
        for rank, stroke in enumerate(sorted(group, key=lambda s: (s["offset"], s["path"]))):
            if rank % 2:
                stroke["path"] = stroke["path"][::-1]
                stroke["arcs"] = [(b, a) for a, b in reversed(stroke["arcs"])]


def _strongly_connected(nodes: dict, arcs: set) -> bool:
    rows = [nodes[a] for a, _ in arcs]
    cols = [nodes[b] for _, b in arcs]
    graph = csr_matrix((np.ones(len(rows)), (rows, cols)), shape=(len(nodes), len(nodes)))
    return connected_components(graph, directed=True, connection="strong")[0] == 1


def _make_one_way(road: Road, start: int) -> None:
    """Make ``road`` one-way leaving node ``start``: along its reference line."""
    if road.from_node != start:
        road.from_node, road.to_node = road.to_node, road.from_node
        road.centreline = road.centreline[::-1].copy()
    road.one_way = True
