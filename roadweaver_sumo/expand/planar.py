"""Turn traced polylines into a planar RoadGraph, and keep it clean (paper §III-C, clean-up).

Planarity is guaranteed by noding: shapely's union splits every polyline wherever it meets
another, so every crossing of two roads becomes a junction (and a road that ends a hair off
another meets it too, :func:`_noded`). Clean-up then removes what a road
engineer would not draw: near-duplicate junctions, slivers of road, junction angles that are
too sharp, stubs that run off the map, and fragments outside the largest component.
"""

from __future__ import annotations

import heapq
import math
from functools import partial

import networkx as nx
import numba as nb
import numpy as np
import shapely
import shapely.ops
from scipy.spatial import cKDTree

from ..compiled import F8, F8_1D, F8_2D, F8_2D_ANY, I8_1D, compiled
from ..hdmap.lanes import LANE_CONFIGS
from ..metrics import SHARP_BEND_DEG, SHARP_BEND_REACH_M, sharp_bend_at, sharp_bend_roads
from ..roadgraph import (
    ROAD_CLASSES,
    add_road,
    edge_coords,
    edge_length,
    edge_list,
    new_road_graph,
    sorted_edge_list,
)
from ..skeleton.model import PERIMETER_INSET
from .clearance import half_width, roads_too_close

GRID = 0.01  # noding precision, metres
CLASS_RANK = {name: rank for rank, name in enumerate(reversed(ROAD_CLASSES))}  # local=0


def higher_class(a: str, b: str) -> str:
    return a if CLASS_RANK[a] >= CLASS_RANK[b] else b


def build_planar_graph(roads: list[tuple[np.ndarray, str]], width: float, height: float):
    """Node all polylines against each other and build the graph of the pieces.

    Each piece becomes the road between the nodes at its rounded ends, in order of (first
    point, last point, length); a second piece between the same two nodes, or one closing a
    loop, goes through :func:`add_piece`. Everything up to that is done in bulk over all
    pieces: a 10 km map has 5,000 of them, and the graph is rebuilt after every reconnection
    and fill round."""
    G = new_road_graph(width, height)
    kept = [(np.asarray(c, float).reshape(-1, 2), cls) for c, cls in roads if len(c) >= 2]
    if not kept:
        return G
    lines = _linestrings([c for c, _ in kept])
    long_enough = shapely.length(lines) > GRID
    kept = [road for road, ok in zip(kept, long_enough.tolist(), strict=True) if ok]
    if not kept:
        return G
    noded = _noded(lines[long_enough])
    pieces = shapely.get_parts(noded)
    xy, owner = shapely.get_coordinates(pieces, return_index=True)
    first = np.flatnonzero(np.r_[True, owner[1:] != owner[:-1]])
    last = np.r_[first[1:], len(owner)] - 1
    lengths = shapely.length(pieces)
    order = np.lexsort((lengths, xy[last, 1], xy[last, 0], xy[first, 1], xy[first, 0]))
    classes = _piece_classes(pieces, kept)
    ends = np.empty((2 * len(pieces), 2))  # start and end of each piece, interleaved
    ends[0::2], ends[1::2] = _rounded(xy[first]), _rounded(xy[last])
    node_of, node_xy = _unique_points(ends)
    for nid, key in enumerate(node_xy):
        G.add_node(nid, xy=key)
    snapped = xy.copy()  # add_road's snapping of each road's ends onto its nodes
    snapped[first] = np.array(node_xy)[node_of[0::2]]
    snapped[last] = np.array(node_xy)[node_of[1::2]]
    bounds = np.r_[first, len(owner)].tolist()
    seen: set = set()
    batch = []
    for k in order.tolist():
        u, v = int(node_of[2 * k]), int(node_of[2 * k + 1])
        a, b = bounds[k], bounds[k + 1]
        pair = (u, v) if u < v else (v, u)
        if u != v and pair not in seen:
            seen.add(pair)
            batch.append((u, v, {"coords": snapped[a:b].copy(), "start": u,
                                 "road_class": classes[k]}))
            continue
        G.add_edges_from(batch)
        batch = []
        add_piece(G, u, v, xy[a:b].tolist(), classes[k])
    G.add_edges_from(batch)
    return G


def _noded(lines: np.ndarray):
    """The lines split wherever they meet and their overlaps merged, their vertices on the
    GRID: what snap-rounding (``shapely.union_all(lines, grid_size=GRID)``) gives, in a fifth
    of its time on a 10 km map (0.03-0.06 s against 0.1-0.37 s a build, four builds a map).
    Plain noding of the lines rounded to the grid finds every crossing and shared vertex; what
    snap-rounding adds is the road end that stops a hair off another road (a reconnection
    link ends on a road's nearest point, rarely exactly on it), so such an end first becomes
    a vertex of that road (:func:`_ends_onto_roads`). Should a dead end within half a grid
    step of another road still be left unnoded, the lines are snap-rounded after all."""
    xy, owner = shapely.get_coordinates(lines, return_index=True)
    rounded = shapely.linestrings(np.rint(xy * 100) / 100, indices=owner)
    rounded = rounded[shapely.length(rounded) > 0]
    noded = shapely.union_all(_ends_onto_roads(rounded))
    return shapely.union_all(lines, grid_size=GRID) if _loose_end(noded) else noded


HALF_GRID = 0.5 * GRID


def _line_ends(lines: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Every line's first and last point (x, y) (all first points, then all last ones), which
    line each is of, all vertices, and where each line's vertices start (and the end)."""
    xy, owner = shapely.get_coordinates(lines, return_index=True)
    first = np.flatnonzero(np.r_[True, owner[1:] != owner[:-1]])
    last = np.r_[first[1:], len(owner)] - 1
    ends = np.r_[first, last]
    return xy[ends], owner[ends], xy, np.r_[first, len(owner)]


def _ends_onto_roads(lines: np.ndarray) -> np.ndarray:
    """``lines`` where each end within a grid step of another line, but not on it, is on
    it: moved onto that line's vertex if one is that close, else made a vertex of it. (A
    grid step, where :func:`_loose_end` looks within half of one: the rounding may have
    moved either line by that much.)"""
    ends, owner, xy, offsets = _line_ends(lines)
    points = shapely.points(ends)
    e, k = shapely.STRtree(lines).query(points, predicate="dwithin", distance=GRID)
    other = k != owner[e]
    e, k = e[other], k[other]
    off = shapely.distance(points[e], lines[k]) > 0
    if not off.any():
        return lines
    e, k = e[off], k[off]
    segment, along, vertex, vertex_gap = _nearest_on_lines(xy, offsets, ends[e], k)
    xy = xy.copy()
    onto = vertex_gap <= GRID  # the end moves onto the other line's vertex
    first = e[onto] < len(lines)
    own = owner[e[onto]]
    xy[np.where(first, offsets[own], offsets[own + 1] - 1)] = xy[vertex[onto]]
    # Each other end becomes a vertex of the line it stops at, after its nearest segment's
    # start (in order along that segment).
    at = ~onto
    order = np.lexsort((along[at], segment[at]))
    xy = np.insert(xy, segment[at][order] + 1, ends[e[at]][order], axis=0)
    counts = np.diff(offsets) + np.bincount(k[at], minlength=len(lines))
    return shapely.linestrings(xy, indices=np.repeat(np.arange(len(lines)), counts))


@compiled(nb.types.Tuple((I8_1D, F8_1D, I8_1D, F8_1D))(F8_2D, I8_1D, F8_2D, I8_1D))
def _nearest_on_lines(xy, offsets, points, lines):
    """For each point and line (vertices ``xy[offsets[k]:offsets[k + 1]]``): the line's segment
    nearest to it (the index of its first vertex in ``xy``) and how far along it the nearest
    point lies (0..1), and the line's nearest vertex (its index in ``xy``) and distance."""
    n = len(points)
    segment, along = np.empty(n, np.int64), np.empty(n)
    vertex, vertex_gap = np.empty(n, np.int64), np.empty(n)
    for i in range(n):
        px, py = points[i, 0], points[i, 1]
        a, b = offsets[lines[i]], offsets[lines[i] + 1]
        best, best_v = np.inf, np.inf
        for m in range(a, b):
            gap = math.hypot(xy[m, 0] - px, xy[m, 1] - py)
            if gap < best_v:
                best_v, vertex[i] = gap, m
            if m + 1 == b:
                continue
            dx, dy = xy[m + 1, 0] - xy[m, 0], xy[m + 1, 1] - xy[m, 1]
            len2 = dx * dx + dy * dy
            t = 0.0 if len2 == 0 else min(max(((px - xy[m, 0]) * dx + (py - xy[m, 1]) * dy)
                                              / len2, 0.0), 1.0)
            gap = math.hypot(xy[m, 0] + t * dx - px, xy[m, 1] + t * dy - py)
            if gap < best:
                best, segment[i], along[i] = gap, m, t
        vertex_gap[i] = best_v
    return segment, along, vertex, vertex_gap


def _loose_end(noded) -> bool:
    """Whether a dead end of the noded lines lies within half a grid step of another piece
    without being on it (a junction the noding missed)."""
    pieces = shapely.get_parts(noded)
    ends, owner, _, _ = _line_ends(pieces)
    _, index, counts = np.unique(np.rint(ends * 100), axis=0, return_inverse=True,
                                 return_counts=True)
    dead = counts[index.ravel()] == 1
    if not dead.any():
        return False
    points = shapely.points(ends[dead])
    e, l = shapely.STRtree(pieces).query(points, predicate="dwithin", distance=HALF_GRID)
    other = l != owner[dead][e]
    return bool((shapely.distance(points[e[other]], pieces[l[other]]) > 0).any())


def _linestrings(coords: list) -> np.ndarray:
    """The polylines as LineStrings, from one shapely call."""
    return shapely.linestrings(np.concatenate(coords),
                               indices=np.repeat(np.arange(len(coords)), [len(c) for c in coords]))


def road_lines(roads: list) -> list:
    """The polylines of ``roads`` (``(u, v, data)``, as :func:`~roadweaver_sumo.roadgraph.edge_list`
    gives them) as LineStrings, from one shapely call."""
    return _linestrings([data["coords"] for _, _, data in roads]).tolist() if roads else []


def _piece_classes(pieces: np.ndarray, kept: list) -> list[str]:
    """The road class of every piece: the best class of the polylines passing within 5 cm of
    its middle, from one compiled pass over their segments (a tree of whole polylines would
    measure every piece against each map-long arterial, vertex by vertex, and a tree of the
    segments costs more to build than to query)."""
    mids = shapely.get_coordinates(shapely.line_interpolate_point(pieces, 0.5, normalized=True))
    points = np.concatenate([c for c, _ in kept])
    point_owner = np.repeat(np.arange(len(kept)), [len(c) for c, _ in kept])
    inside = point_owner[1:] == point_owner[:-1]  # steps between two polylines are not segments
    rank = np.array([CLASS_RANK[cls] for _, cls in kept])
    best = _best_rank_near(mids, np.ascontiguousarray(points[:-1][inside]),
                           np.ascontiguousarray(points[1:][inside]),
                           rank[point_owner[1:][inside]], 0.05)
    names = sorted(CLASS_RANK, key=CLASS_RANK.__getitem__)
    return [names[r] for r in best.tolist()]


@compiled(F8(F8, F8, F8, F8, F8, F8))
def _point_to_segment(px, py, ax, ay, bx, by):
    """GEOS's ``Distance::pointToSegment``, operation for operation."""
    if ax == bx and ay == by:
        return np.sqrt((px - ax) * (px - ax) + (py - ay) * (py - ay))
    len2 = (bx - ax) * (bx - ax) + (by - ay) * (by - ay)
    r = ((px - ax) * (bx - ax) + (py - ay) * (by - ay)) / len2
    if r <= 0.0:
        return np.sqrt((px - ax) * (px - ax) + (py - ay) * (py - ay))
    if r >= 1.0:
        return np.sqrt((px - bx) * (px - bx) + (py - by) * (py - by))
    s = ((ay - py) * (bx - ax) - (ax - px) * (by - ay)) / len2
    return abs(s) * np.sqrt(len2)


@compiled(I8_1D(F8_2D, F8_2D, F8_2D, I8_1D, F8))
def _best_rank_near(points, starts, ends, rank, reach):
    """For every point, the highest rank of the segments within ``reach`` of it (0 where none
    is), each segment tested against the points in the grid cells its box covers. A point and a
    segment are within reach exactly when GEOS's ``dwithin`` says so: the same envelope
    distance, then the same point-to-segment distance (``Distance::pointToSegment``)."""
    n = len(points)
    best = np.zeros(n, dtype=np.int64)
    if n == 0:
        return best
    x0, y0 = points[:, 0].min(), points[:, 1].min()
    extent = max(points[:, 0].max() - x0, points[:, 1].max() - y0)
    cell = max(25.0, extent / 1000.0)
    nx = int((points[:, 0].max() - x0) / cell) + 1
    ny = int((points[:, 1].max() - y0) / cell) + 1
    cell_of = np.empty(n, dtype=np.int64)
    for i in range(n):
        cell_of[i] = int((points[i, 1] - y0) / cell) * nx + int((points[i, 0] - x0) / cell)
    order = np.argsort(cell_of, kind="mergesort")
    first = np.zeros(nx * ny + 1, dtype=np.int64)
    for i in range(n):
        first[cell_of[i] + 1] += 1
    for c in range(nx * ny):
        first[c + 1] += first[c]
    for s in range(len(starts)):
        ax, ay, bx, by = starts[s, 0], starts[s, 1], ends[s, 0], ends[s, 1]
        lox, hix, loy, hiy = min(ax, bx), max(ax, bx), min(ay, by), max(ay, by)
        cx0 = max(int(np.floor((lox - reach - x0) / cell)), 0)
        cx1 = min(int(np.floor((hix + reach - x0) / cell)), nx - 1)
        cy0 = max(int(np.floor((loy - reach - y0) / cell)), 0)
        cy1 = min(int(np.floor((hiy + reach - y0) / cell)), ny - 1)
        r = rank[s]
        for cy in range(cy0, cy1 + 1):
            for c in range(cy * nx + cx0, cy * nx + cx1 + 1):
                for j in range(first[c], first[c + 1]):
                    i = order[j]
                    if best[i] >= r:
                        continue
                    px, py = points[i, 0], points[i, 1]
                    dx = lox - px if px < lox else (px - hix if px > hix else 0.0)
                    dy = loy - py if py < loy else (py - hiy if py > hiy else 0.0)
                    if dx == 0.0:
                        envelope = dy
                    elif dy == 0.0:
                        envelope = dx
                    else:
                        envelope = np.sqrt(dx * dx + dy * dy)
                    if envelope > reach:
                        continue
                    if _point_to_segment(px, py, ax, ay, bx, by) <= reach:
                        best[i] = r
    return best


def _rounded(points: np.ndarray) -> np.ndarray:
    """Python's ``round(x, 2)`` of every coordinate. The union's vertices lie on the 0.01 grid
    already (``rint(100 x) / 100 == x``: x is the double nearest k/100, which ``round`` keeps);
    any other goes through ``round`` itself."""
    off = np.rint(points * 100) / 100 != points
    out = points.copy()
    out[off] = [round(x, 2) for x in points[off].tolist()]
    return out


def _unique_points(points: np.ndarray) -> tuple[np.ndarray, list[tuple]]:
    """Number the distinct points in (x, y) order: each point's number, and each number's
    point (as Python floats, the first of equal ones: ``sorted(dict.fromkeys(...))``)."""
    order = np.lexsort((points[:, 1], points[:, 0]))  # stable: equal points keep their order
    ranked = points[order]
    new = np.r_[True, (ranked[1:] != ranked[:-1]).any(axis=1)]
    number = np.empty(len(points), dtype=int)
    number[order] = np.cumsum(new) - 1
    return number, [tuple(p) for p in ranked[new].tolist()]


def add_piece(G: nx.Graph, u: int, v: int, coords, cls: str) -> None:
    """Add a road u-v. A second road between the same nodes gets a shape node in its middle, a
    closed loop two, so the graph stays simple (SUMO and the lane builder need distinct node
    pairs). The nodes of ``G`` are numbered 0..n-1, as :func:`build_planar_graph` numbers
    them: a shape node is number n."""
    if u != v and not G.has_edge(u, v):
        add_road(G, u, v, coords, cls)
        return
    line = shapely.LineString(coords)
    cuts = [0.5] if u != v else [1 / 3, 2 / 3]
    ends = [u]
    for frac in cuts:
        p = line.interpolate(frac, normalized=True)
        m = G.number_of_nodes()
        G.add_node(m, xy=(float(p.x), float(p.y)))
        ends.append(m)
    ends.append(v)
    marks = [0.0] + [f * line.length for f in cuts] + [line.length]
    for a, b, s0, s1 in zip(ends[:-1], ends[1:], marks[:-1], marks[1:]):
        add_road(G, a, b, np.asarray(shapely.ops.substring(line, s0, s1).coords), cls)


def merge_nodes(G: nx.Graph, keep: int, drop: int) -> None:
    """Move every road of ``drop`` onto ``keep`` and delete ``drop``."""
    for w in list(G.neighbors(drop)):
        data = G.edges[drop, w]
        coords = edge_coords(G, drop, w).copy()
        G.remove_edge(drop, w)
        if w == keep:
            continue
        if G.has_edge(keep, w):
            old = G.edges[keep, w]
            old["road_class"] = higher_class(old["road_class"], data["road_class"])
            continue
        coords[0] = G.nodes[keep]["xy"]
        add_road(G, keep, w, unhooked(coords), data["road_class"])
    G.remove_node(drop)


#: A road moved onto the kept node of a merge leaves it towards its old first vertex, which may
#: lie beyond the node (a rounded corner just past it): the road then turns back on itself a
#: few metres out, a hook no lane can follow (a 20 km learned map had a junction where SUMO
#: counted a collision). A road turning more than HOOK_TURN within HOOK_REACH metres of the node
#: leaves it straight towards its first point HOOK_REACH metres away instead.
HOOK_TURN = 90.0
HOOK_REACH = 15.0


def unhooked(coords: np.ndarray, reach: float = HOOK_REACH) -> np.ndarray:
    """``coords`` (from the node out) with no hook at their start."""
    step = np.diff(coords, axis=0)
    length = np.hypot(*step.T)
    step, start = step[length > 1e-9], (np.cumsum(length) - length)[length > 1e-9]
    near = step[start < reach]
    if len(near) < 2:
        return coords
    heading = np.unwrap(np.arctan2(near[:, 1], near[:, 0]))
    if np.abs(heading - heading[0]).max() <= math.radians(HOOK_TURN):
        return coords
    away = np.hypot(*(coords - coords[0]).T)
    far = np.flatnonzero(away >= reach)
    if len(far) == 0:
        return coords[[0, -1]]
    k = int(far[0])  # coords[k - 1] lies within reach, coords[k] beyond: cut between them
    a, d = coords[k - 1] - coords[0], coords[k] - coords[k - 1]
    qa, qb, qc = d @ d, 2 * (a @ d), a @ a - reach**2
    t = (-qb + math.sqrt(max(qb * qb - 4 * qa * qc, 0.0))) / (2 * qa)
    cut = [coords[k - 1] + t * d] if t < 1.0 - 1e-9 else []
    return np.vstack([coords[:1], *cut, coords[k:]])


#: Roads between two junctions (degree >= 3 at both ends) shorter than this are merged into one
#: junction: the junction areas of multi-lane roads reach about 10 m from their centres, so a
#: shorter road left SUMO edges a few centimetres long between them, where traffic locked up.
MIN_JUNCTION_GAP = 20.0


def contract_short_edges(G: nx.Graph, min_length: float,
                         junction_gap: float = MIN_JUNCTION_GAP, nodes: set | None = None,
                         order: dict | None = None) -> set:
    """Merge the two ends of every road shorter than ``min_length``, and of every road between
    two junctions shorter than ``junction_gap`` (the busier end stays); returns the nodes
    whose roads changed.

    Each pass first measures all roads in one vectorised step and looks closer only at those
    that may be short: a merge replaces the roads of the node it drops and changes no other
    road's polyline, so a road of the pass that still exists has the length measured. A road
    becomes short only when it is made or the degree of an end changes, so each pass after
    the first measures only the roads at the nodes the one before changed; ``nodes``: the
    first pass too (no other road is short). ``order``: :func:`node_order` of ``G``, or of
    ``G`` before nodes were removed from it."""
    longest = max(junction_gap, min_length)
    touched: set = set()
    while True:
        if nodes is None:
            edges = sorted_edge_list(G)
        else:
            order = node_order(G) if order is None else order
            edges = _edges_at(G, nodes, order)
        nodes = set()
        for k in np.flatnonzero(_maybe_shorter([data["coords"] for _, _, data in edges],
                                               longest)).tolist():
            u, v, _ = edges[k]
            if not G.has_edge(u, v):
                continue
            limit = junction_gap if G.degree(u) >= 3 and G.degree(v) >= 3 else min_length
            if edge_length(G, u, v) < max(limit, min_length):
                keep, drop = _keep_and_drop(G, u, v)
                merge_nodes(G, keep, drop)
                nodes.add(keep)  # the dropped node's neighbours are the kept one's now
                nodes.update(G.neighbors(keep))
        if not nodes:
            return touched
        touched |= nodes


def node_order(G: nx.Graph) -> dict:
    """Each node's place in the graph's node order (removing nodes keeps the others' order)."""
    return {n: k for k, n in enumerate(G)}


def _edges_at(G: nx.Graph, nodes, order: dict) -> list[tuple]:
    """The roads at ``nodes`` (those still in ``G``) as :func:`sorted_edge_list` lists them:
    each from the end that comes first in the node ``order``."""
    found = {}
    for n in nodes:
        for w, data in G.adj.get(n, {}).items():
            found[(n, w) if order[n] < order[w] else (w, n)] = data
    return sorted((u, v, data) for (u, v), data in found.items())


def _roads_at(G: nx.Graph, nodes) -> list[tuple]:
    """The roads at ``nodes`` (those still in ``G``), each once, as (u, v, data)."""
    found = {}
    for n in nodes:
        for w, data in G.adj.get(n, {}).items():
            found[id(data)] = (n, w, data)
    return list(found.values())


def _maybe_shorter(coords: list, length: float) -> np.ndarray:
    """Per polyline, whether it may be shorter than ``length``: summed in another order than
    ``edge_length`` sums, so with a margin (a road can only be looked at needlessly)."""
    if not coords:
        return np.zeros(0, dtype=bool)
    owner = np.repeat(np.arange(len(coords)), [len(c) for c in coords])
    step = np.diff(np.concatenate(coords), axis=0)
    inside = owner[1:] == owner[:-1]  # steps between two roads are not steps
    lengths = np.bincount(owner[1:][inside], weights=np.hypot(*step[inside].T),
                          minlength=len(coords))
    return lengths < length * (1 + 1e-9) + 1e-9


def merge_close_nodes(G: nx.Graph, radius: float) -> set:
    """Merge junctions closer than ``radius`` even when no road joins them directly, pair by
    pair in node order; returns the nodes whose roads changed. A merge keeps the kept node
    where it is and makes no node, so the close pairs are found once; a pair whose node has
    gone is skipped."""
    nodes = sorted(G.nodes)
    touched: set = set()
    if len(nodes) < 2:
        return touched
    pts = np.array([G.nodes[n]["xy"] for n in nodes])
    dropped: set = set()
    for i, j in sorted(cKDTree(pts).query_pairs(radius)):
        if nodes[i] in dropped or nodes[j] in dropped:
            continue
        keep, drop = _keep_and_drop(G, nodes[i], nodes[j])
        merge_nodes(G, keep, drop)
        dropped.add(drop)
        touched.add(keep)  # the dropped node's neighbours are the kept one's now
        touched.update(G.neighbors(keep))
    return touched


def _keep_and_drop(G: nx.Graph, u: int, v: int) -> tuple[int, int]:
    """Which of two nodes to merge stays: one on the perimeter ring road, else the busier one.

    Keeping a junction 11 m inside the map for a ring node bends the ring's two roads inward,
    across the roads there without a junction; the blocks along the ring then no longer close
    (a 10 km map kept 1.6 of its 99 km² of blocks, and the density fill starved)."""
    ring_u, ring_v = _on_ring(G, u), _on_ring(G, v)
    if ring_u != ring_v:
        return (u, v) if ring_u else (v, u)
    return (u, v) if G.degree(u) >= G.degree(v) else (v, u)


def _on_ring(G: nx.Graph, n: int) -> bool:
    return any(on_perimeter(G, n, w) for w in G.neighbors(n))


#: Two roads at a degree-2 node meeting at less than this (a turn of over 120° from one into
#: the other) would join into a hairpin: lanes offset from so tight a bend fold over each other,
#: and within a few metres of a junction SUMO's internal lanes cross (a 20 km learned map had
#: 35 collisions at one). :func:`remove_sharp_angles` drops the minor road instead.
HAIRPIN_ANGLE = 60.0
HAIRPIN_PROBES = (5.0, 20.0)  # metres out along both roads: a bend close to the node counts too


def _meeting_angle(G: nx.Graph, n: int, cache: dict | None) -> float:
    """The smaller angle (radians) between the two roads of degree-2 node ``n``, the sharpest
    of those measured ``HAIRPIN_PROBES`` out."""
    sharpest = math.pi
    for probe in HAIRPIN_PROBES:
        (a1, _), (a2, _) = departure_angles(G, n, probe, cache)
        sharpest = min(sharpest, (a2 - a1) % (2 * math.pi), (a1 - a2) % (2 * math.pi))
    return sharpest


def dissolve_degree_two(G: nx.Graph, min_angle_deg: float = 0.0,
                        cache: dict | None = None) -> set:
    """Join the two roads at a degree-2 node into one, unless that would duplicate a road or
    the two meet at less than ``min_angle_deg`` or ``HAIRPIN_ANGLE`` (the joined road would
    double back: that V is :func:`remove_sharp_angles`' to resolve).

    A join keeps the degree of every other node (its ends trade a road for a road), so the
    nodes of degree 2 are found once. Returns the nodes whose roads changed."""
    limit = math.radians(max(min_angle_deg, HAIRPIN_ANGLE))
    touched: set = set()
    for n in sorted(n for n, degree in G.degree() if degree == 2):
        a, b = sorted(G.neighbors(n))
        if a == b or G.has_edge(a, b):
            continue
        if _meeting_angle(G, n, cache) < limit:
            continue
        ca, cb = edge_coords(G, a, n), edge_coords(G, n, b)
        cls = higher_class(G.edges[a, n]["road_class"], G.edges[n, b]["road_class"])
        G.remove_node(n)
        add_road(G, a, b, np.vstack([ca, cb[1:]]), cls)
        touched.update((a, b))
    return touched


def departure_angles(
    G: nx.Graph, n: int, probe: float = 20.0, cache: dict | None = None
) -> list[tuple[float, int]]:
    """(bearing, neighbour) of each road leaving ``n``, measured ``probe`` metres out.

    ``cache`` keeps each bearing with the polyline it was measured on: clean-up asks for the
    same junctions over and over, and a road whose polyline is replaced is measured again."""
    out = []
    for w in G.neighbors(n):
        coords = G.edges[n, w]["coords"]
        hit = cache.get((n, w, probe)) if cache is not None else None
        if hit is not None and hit[0] is coords:
            out.append((hit[1], w))
            continue
        c = edge_coords(G, n, w)
        qx, qy = point_along(c, probe)
        bearing = math.atan2(qy - float(c[0, 1]), qx - float(c[0, 0]))
        if cache is not None:
            cache[(n, w, probe)] = (coords, bearing)
        out.append((bearing, w))
    return sorted(out)


def point_along(c: np.ndarray, probe: float) -> tuple[float, float]:
    """The point ``min(probe, half the length)`` along polyline ``c`` (n x 2), computed as
    GEOS's ``interpolate`` does, step for step (so the same bits), without building a
    LineString: clean-up measures tens of thousands of these, hence compiled."""
    return _point_along_steps(np.asarray(c, dtype=np.float64), float(probe))


@compiled(nb.types.UniTuple(F8, 2)(F8_2D_ANY, F8))
def _point_along_steps(c, probe):
    total = 0.0
    for k in range(len(c) - 1):  # GEOS Length::ofLine: a running sum in order
        total += math.sqrt((c[k + 1, 0] - c[k, 0]) * (c[k + 1, 0] - c[k, 0])
                           + (c[k + 1, 1] - c[k, 1]) * (c[k + 1, 1] - c[k, 1]))
    target = min(probe, total * 0.5)
    if target <= 0.0:
        return c[0, 0], c[0, 1]
    done = 0.0
    for k in range(len(c) - 1):  # GEOS LengthLocationMap::getLocationForward
        x0, y0, x1, y1 = c[k, 0], c[k, 1], c[k + 1, 0], c[k + 1, 1]
        step = math.sqrt((x1 - x0) * (x1 - x0) + (y1 - y0) * (y1 - y0))
        if done + step > target:
            frac = (target - done) / step
            if frac <= 0.0:
                return x0, y0
            if frac >= 1.0:
                return x1, y1
            return (x1 - x0) * frac + x0, (y1 - y0) * frac + y0
        done += step
    return c[-1, 0], c[-1, 1]


def remove_sharp_angles(G: nx.Graph, min_angle_deg: float, cache: dict | None = None,
                        nodes: set | None = None) -> set:
    """Drop the minor road of every pair meeting at a node at less than ``min_angle_deg``,
    sweeping the nodes in order until none is left.

    Degree-2 nodes count too, up to ``HAIRPIN_ANGLE``: two roads left in a V (a third road at
    the node removed) would otherwise be joined into one road that doubles back on itself, a
    hairpin whose lanes fold over each other (a learned map had one 3 m from its own junction,
    and a car hit).

    Whether a node has a pair to drop depends on its own roads alone, so the first sweep
    visits only the nodes that may have one (:func:`_maybe_sharp_nodes`), and each later one
    only the nodes that lost a road since they were last looked at: every other node would
    find nothing. ``nodes``: the first sweep too (the others were looked at since their roads
    last changed). Returns the nodes whose roads changed."""
    limit = math.radians(min_angle_deg)
    hairpin = math.radians(max(min_angle_deg, HAIRPIN_ANGLE))

    def visit(n):
        road = _sharp_pair_road(G, n, limit, hairpin, cache)
        if road is None:
            return ()
        G.remove_edge(*road)
        return road

    return _sweep(_maybe_sharp_nodes(G, limit, hairpin, nodes), visit)


def _sweep(nodes, visit) -> set:
    """Visit ``nodes`` in order, and again every node that ``visit`` (which returns the nodes
    whose roads it changed) touches: later in the same sweep if it comes after the node
    visited, else in the next sweep; until a sweep touches no node it already passed.
    Returns every node touched."""
    todo = sorted(nodes)  # a sorted list is a heap
    touched: set = set()
    while todo:
        queued, again = set(todo), set()
        while todo:
            n = heapq.heappop(todo)
            for m in visit(n):
                touched.add(m)
                if m <= n:
                    again.add(m)  # already visited in this sweep: the next one
                elif m not in queued:
                    heapq.heappush(todo, m)
                    queued.add(m)
        todo = sorted(again)
    return touched


def _maybe_sharp_nodes(G: nx.Graph, limit: float, hairpin: float,
                       among: set | None = None) -> list:
    """The nodes (of ``among``, if given) that may have a pair of roads for
    :func:`_sharp_pair_road` to drop: every road's bearings at both ends measured in one
    compiled pass (the same steps as :func:`departure_angles`, compared with a margin, so a
    node can only be looked at needlessly)."""
    edges = edge_list(G) if among is None else _roads_at(G, among)
    if not edges:
        return []
    coords = [data["coords"] for _, _, data in edges]
    offsets = np.r_[0, np.cumsum([len(c) for c in coords])]
    points = np.ascontiguousarray(np.concatenate(coords), dtype=np.float64)
    starts = [data["start"] for _, _, data in edges]
    node = np.array(starts + [v if s == u else u for (u, v, _), s in zip(edges, starts,
                                                                         strict=True)])
    order = np.argsort(node, kind="stable")
    head = np.flatnonzero(np.r_[True, node[order][1:] != node[order][:-1]])
    bounds = np.r_[head, len(node)]
    wide, near = (_tightest(bounds, np.concatenate(_departures(points, offsets, probe))[order])
                  for probe in (HAIRPIN_PROBES[1], HAIRPIN_PROBES[0]))
    degree = np.diff(bounds)
    margin = 1e-9
    sharp = ((degree >= 3) & (wide < limit + margin)) | (
        (degree == 2) & (np.minimum(wide, near) < hairpin + margin))
    found = node[order[head[sharp]]].tolist()
    return found if among is None else [n for n in found if n in among]


@compiled(F8_1D(I8_1D, F8_1D))
def _tightest(bounds, bearing):
    """Per node (its roads' bearings ``bearing[bounds[k]:bounds[k + 1]]``), the smallest
    angle from one road to the next round it (2π at a dead end)."""
    out = np.empty(len(bounds) - 1)
    for k in range(len(bounds) - 1):
        b = np.sort(bearing[bounds[k]:bounds[k + 1]])
        tightest = b[0] - b[-1] + 2 * math.pi
        for i in range(len(b) - 1):
            tightest = min(tightest, b[i + 1] - b[i])
        out[k] = tightest
    return out


@compiled(nb.types.UniTuple(F8_1D, 2)(F8_2D, I8_1D, F8))
def _departures(points, offsets, probe):
    """The bearing of every road (``points[offsets[k]:offsets[k + 1]]``) ``probe`` metres out
    from its first point, and from its last point, as :func:`departure_angles` measures."""
    n = len(offsets) - 1
    ahead, back = np.empty(n), np.empty(n)
    for k in range(n):
        c = points[offsets[k]:offsets[k + 1]]
        qx, qy = _point_along_steps(c, probe)
        ahead[k] = math.atan2(qy - c[0, 1], qx - c[0, 0])
        r = c[::-1]
        qx, qy = _point_along_steps(r, probe)
        back[k] = math.atan2(qy - r[0, 1], qx - r[0, 0])
    return ahead, back


def _sharp_pair_road(G: nx.Graph, n: int, limit: float, hairpin: float,
                     cache: dict | None) -> tuple | None:
    """The road :func:`remove_sharp_angles` drops at ``n`` (the minor road of its first pair
    of roads closer than ``limit``, or of its two roads closer than ``hairpin``), or None."""
    if G.degree(n) < 2:
        return None
    if G.degree(n) == 2 and _meeting_angle(G, n, cache) < hairpin:
        return min(((n, w) for w in G.neighbors(n)), key=lambda e: road_keep_weight(G, *e))
    angles = departure_angles(G, n, cache=cache)
    for k, (a1, w1) in enumerate(angles):
        a2, w2 = angles[(k + 1) % len(angles)]
        if (a2 - a1) % (2 * math.pi) < limit:
            return min(((n, w1), (n, w2)), key=lambda e: road_keep_weight(G, *e))
    return None


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


def _ring_nodes(G: nx.Graph, tolerance: float = 1.0) -> set:
    """The nodes of every road :func:`on_perimeter`, all roads measured in one vectorised
    pass (one call per road cost 80 ms on a learned 10 km map)."""
    edges = edge_list(G)
    if not edges:
        return set()
    coords = [np.asarray(data["coords"], dtype=float) for _, _, data in edges]
    owner = np.repeat(np.arange(len(edges)), [len(c) for c in coords])
    away = ~(_perimeter_offset(G, np.concatenate(coords)) < tolerance)
    along = np.bincount(owner[away], minlength=len(edges)) == 0
    return {n for (u, v, _), hit in zip(edges, along.tolist(), strict=True) if hit
            for n in (u, v)}


def prune_stubs(G: nx.Graph, max_length: float, margin: float,
                nodes: set | None = None) -> set:
    """Remove dead-end roads shorter than ``max_length`` or ending within ``margin`` of the map
    border (roads cut off by the border), and nodes left without a road, sweeping the nodes
    in order until none is left, so chains of stubs go too.

    Whether a node goes depends on its own roads alone, so a sweep visits only the nodes
    with at most one road at its start and those that lost one since they were looked at
    (as :func:`remove_sharp_angles` does); ``nodes``: the first sweep only those of them.
    Returns the nodes whose roads changed."""
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

    ends = (n for n, degree in G.degree() if degree <= 1) if nodes is None else \
        [n for n in nodes if n in G and G.degree(n) <= 1]
    return _sweep(ends, visit)


def keep_largest_component(G: nx.Graph) -> None:
    """The component filter: keep the component holding the perimeter ring road, else the
    largest. Every block the density fill splits closes against the ring; once fragments of a
    learned skeleton are reconnected, a cluster of them can outnumber the ring's component in
    nodes, and keeping it left a 2 km map with 0.15 km² of blocks."""
    for comp in components_main_first(G)[1:]:
        G.remove_nodes_from(comp)


def components_main_first(G: nx.Graph, comps: list[set] | None = None) -> list[set]:
    """Connected components (or the node sets ``comps``), the one holding the most of the
    perimeter ring first, then by size (ties: lowest node id)."""
    comps = list(nx.connected_components(G)) if comps is None else comps
    if len(comps) <= 1:
        return comps
    ring = _ring_nodes(G)
    return sorted(comps, key=lambda c: (len(c & ring), len(c), -min(c)), reverse=True)


def turn_angles(coords: np.ndarray) -> np.ndarray:
    """Heading change (radians, 0..π) at each interior vertex of a polyline."""
    d = np.diff(coords, axis=0)
    heading = np.arctan2(d[:, 1], d[:, 0])
    return np.abs((np.diff(heading) + np.pi) % (2 * np.pi) - np.pi)


#: A fillet's tangents take at most this share of each leg of its corner, so that the fillets
#: of two corners on one leg never overlap.
FILLET_SHARE = 0.45


def round_corners(coords: np.ndarray, max_turn_deg: float, radius: float) -> np.ndarray:
    """Replace every vertex that turns by more than ``max_turn_deg`` with a quadratic Bézier
    fillet (tangents of ``radius`` metres, less on short legs), so lanes offset from the
    centreline do not fold over at sharp bends."""
    coords = _distinct(coords)
    if len(coords) < 3:
        return coords
    limit = math.radians(max_turn_deg)
    turns = turn_angles(coords)
    if turns.max() <= limit:
        return coords
    out = [coords[:1]]
    for k in range(1, len(coords) - 1):
        a, b, c = coords[k - 1], coords[k], coords[k + 1]
        if turns[k - 1] <= limit:
            out.append(coords[k:k + 1])
            continue
        ab, bc = np.hypot(*(b - a)), np.hypot(*(c - b))
        r = min(radius, FILLET_SHARE * ab, FILLET_SHARE * bc)
        p0, p2 = b + (a - b) * (r / ab), b + (c - b) * (r / bc)
        t = np.linspace(0.0, 1.0, max(3, int(math.degrees(turns[k - 1]) / 10) + 2))[:, None]
        out.append((1 - t) ** 2 * p0 + 2 * (1 - t) * t * b + t**2 * p2)
    out.append(coords[-1:])
    return np.concatenate(out)


def _distinct(coords: np.ndarray) -> np.ndarray:
    """``coords`` without points within a micrometre of the one before."""
    return coords[np.r_[True, np.hypot(*np.diff(coords, axis=0).T) > 1e-6]]


def without_jogs(coords: np.ndarray, max_turn_deg: float, least_radius: float) -> np.ndarray:
    """``coords`` with every corner that turns more than ``max_turn_deg`` given the room its
    fillet (:func:`round_corners`) needs for a radius of ``least_radius``: where the leg to
    an interior neighbour is shorter, that neighbour goes, or, when it is such a corner too,
    the two become one at the middle of their leg; shortest leg first.

    Such pairs are one bend drawn as a jog (a step of the traced skeleton) or a corner where
    two roads were joined at a dissolved junction next to a vertex of a traced curve.
    Filleted one by one, such a corner gets a radius of a few metres or less, and lanes
    offset from the centreline fold over (CommonRoad's self-intersecting lanelets, paper
    §III-D). A fillet with tangents ``t`` turning by ``θ`` has a least radius of
    t·cos²(θ/2)/sin(θ/2)."""
    coords = _distinct(coords)
    limit = math.radians(max_turn_deg)
    while len(coords) >= 4:
        half_turns = np.r_[0.0, turn_angles(coords) / 2, 0.0]
        sharp = half_turns > limit / 2
        needs = np.where(sharp, least_radius * np.sin(half_turns) / np.cos(half_turns) ** 2
                         / FILLET_SHARE, 0.0)
        legs = np.hypot(*np.diff(coords, axis=0).T)
        short = legs < np.maximum(needs[:-1], needs[1:])
        short[[0, -1]] = False  # a road's end node stays
        if not short.any():
            break
        k = np.flatnonzero(short)[np.argmin(legs[short])]
        if sharp[k] and sharp[k + 1]:
            coords = np.vstack([coords[:k], (coords[k] + coords[k + 1]) / 2, coords[k + 2:]])
        else:
            coords = np.delete(coords, k if sharp[k + 1] else k + 1, axis=0)
    return coords


def smooth_bends(G: nx.Graph, max_turn_deg: float = 30.0, radius: float = 20.0) -> None:
    """Round the sharp bends of every road (perimeter corners, joins at dissolved nodes),
    jogs first merged into one corner (:func:`without_jogs`) unless that brings the road
    within another's clearance (:func:`.clearance.roads_too_close`).

    Most roads are smooth already (clean-up runs several times): one vectorised pass finds the
    roads that clearly have no repeated point and no sharp bend, which :func:`round_corners`
    would return unchanged; the others, and any near those limits, go through it."""
    roads = edge_list(G)
    if not roads:
        return
    straighten_road_ends(G)
    jogged = {}
    for k in np.flatnonzero(_maybe_sharp([data["coords"] for _, _, data in roads],
                                         max_turn_deg)):
        u, v, data = roads[k]
        coords = data["coords"]
        merged = without_jogs(coords, max_turn_deg, LANE_CONFIGS[data["road_class"]].min_radius)
        if len(merged) < len(_distinct(coords)):
            jogged[tuple(sorted((u, v)))] = coords
        data["coords"] = round_corners(merged, max_turn_deg, radius)
    if jogged:
        for pair in roads_too_close(G):
            for e in set(pair) & jogged.keys():
                G.edges[e]["coords"] = round_corners(jogged.pop(e), max_turn_deg, radius)
    straighten_road_ends(G)  # fillets of bends close to a junction


#: Roads leave their junctions straight for this many metres beyond their half width. A
#: vertex a metre from the node (left by a merge of close junctions or a snapped end), or a
#: bend rounded just before the junction, makes a hook that SUMO takes for the road's
#: direction: netconvert then cut a road's lanes past the junction's centre, or let them
#: curve into a neighbour's, and lanes offset from the hook fold over.
STRAIGHT_END = 5.0


def straighten_road_ends(G: nx.Graph) -> None:
    """Drop every vertex of a road within :data:`STRAIGHT_END` plus the road's half width
    (metres along it) of either end node."""
    for _, _, data in edge_list(G):
        c = data["coords"]
        if len(c) < 3:
            continue
        reach = STRAIGHT_END + half_width(data["road_class"])
        step = np.hypot(*np.diff(c, axis=0).T)
        if step[0] >= reach and step[-1] >= reach:
            continue
        along = np.r_[0.0, np.cumsum(step)]
        keep = (along >= reach) & (along <= along[-1] - reach)
        keep[0] = keep[-1] = True
        data["coords"] = c[keep]


def _maybe_sharp(coords: list, max_turn_deg: float) -> np.ndarray:
    """Per polyline, whether it may have a step of 1e-6 m or less or a vertex turning more
    than ``max_turn_deg`` (with margins, so that rounding can only add roads, never miss
    one)."""
    owner = np.repeat(np.arange(len(coords)), [len(c) for c in coords])
    step = np.diff(np.concatenate(coords), axis=0)
    inside = owner[1:] == owner[:-1]  # steps between two roads are not steps
    step, step_owner = step[inside], owner[1:][inside]
    short = np.hypot(step[:, 0], step[:, 1]) <= 2e-6
    heading = np.arctan2(step[:, 1], step[:, 0])
    pair = step_owner[1:] == step_owner[:-1]
    turn = np.abs((np.diff(heading) + np.pi) % (2 * np.pi) - np.pi)
    sharp = pair & (turn > math.radians(max_turn_deg) - 1e-6)
    n = len(coords)
    return (np.bincount(step_owner[short], minlength=n)
            + np.bincount(step_owner[1:][sharp], minlength=n)) > 0


def remove_close_roads(G: nx.Graph) -> set:
    """Remove, of every pair of roads closer than their lanes allow (:mod:`.clearance`), the
    road less worth keeping (:func:`road_keep_weight`); returns the nodes whose roads
    changed."""
    touched: set = set()
    for a, b in roads_too_close(G):
        if G.has_edge(*a) and G.has_edge(*b):
            road = min(a, b, key=lambda e: (*road_keep_weight(G, *e), e))
            G.remove_edge(*road)
            touched.update(road)
    return touched


def clean(G: nx.Graph, min_edge: float, min_angle: float, stub: float, margin: float,
          keep_largest: bool = True, min_block_area: float = 0.0,
          changed: set | None = None) -> None:
    """The whole clean-up, repeated until nothing changes. ``keep_largest=False`` keeps every
    component: the clean-up before A* reconnection, which may join them (paper §III-C).
    ``min_block_area``: open blocks smaller than this (:func:`open_tiny_blocks`), then clean
    again.

    Junctions close together are merged in the first round only: no pass moves or adds a
    node, so none come close later. Each later round looks for short roads and sharp angles
    only at the nodes whose roads the round before changed (each pass returns them): every
    other road and node was looked at since it last changed. (The later rounds change a few
    roads each, and measuring the whole map again was most of their time.) Roads too close to
    another (:func:`remove_close_roads`) are looked for once the other passes change nothing:
    that check measures every pair of neighbouring roads, and most rounds change a few.
    ``changed``: ``G`` was cleaned, and since then only these nodes' roads changed."""
    bearings: dict = {}
    order = node_order(G)  # nodes are only removed here
    settled = False
    for round_ in range(20):
        before = (G.number_of_nodes(), G.number_of_edges())
        touched = merge_close_nodes(G, min_edge * 0.8) if round_ == 0 and changed is None \
            else set()
        touched |= contract_short_edges(G, min_edge, nodes=changed, order=order)
        cut = remove_sharp_angles(G, min_angle, bearings,
                                  nodes=None if changed is None else changed | touched)
        touched |= cut
        touched |= prune_stubs(G, stub, margin,
                               nodes=None if changed is None else changed | touched)
        # Only a removed road can split a component (a merge, a pruned dead end or a join
        # cannot), and this removes whole components: no other node changes.
        if keep_largest and (changed is None or round_ == 0 or cut):
            keep_largest_component(G)
        touched |= dissolve_degree_two(G, min_angle, bearings)
        if (G.number_of_nodes(), G.number_of_edges()) == before:
            touched = remove_close_roads(G)
            if not touched:
                settled = True
                break
            if keep_largest:
                keep_largest_component(G)
        changed = touched
    if min_block_area > 0:
        opened = open_tiny_blocks(G, min_block_area)
        if opened:
            clean(G, min_edge, min_angle, stub, margin, keep_largest,
                  changed={n for road in opened for n in road} if settled else None)
            return
    smooth_bends(G)


#: A block smaller than this is a sliver between junctions, not a city block: netconvert's
#: junction shapes swallow its sides. A 146 m² triangle of 16-26 m roads by the ring road of a
#: learned map left roads 0 m long between overlapping junctions; cars locked up there and,
#: after a teleport, one hit another. :func:`open_tiny_blocks` removes its least road.
MIN_BLOCK_AREA = 500.0


def open_tiny_blocks(G: nx.Graph, min_area: float = MIN_BLOCK_AREA) -> list[tuple]:
    """Remove from each block (face) smaller than ``min_area`` the road least worth keeping
    (:func:`_edge_weight`: never the ring, lowest class, shortest); returns those roads."""
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


#: A road can still turn back on itself after the clean-up (``metrics.sharp_bends``): a sharp
#: corner inside a skeleton road, or two roads joined at a dissolved node whose rounded ends
#: overshoot each other by a metre. Lanes offset from such a bend fold over each other.
#: :func:`cut_sharp_bends` cuts across each where its two arms are BEND_CHORD metres apart, so
#: that, rounded, it turns no sharper than a bend of the metric's reach.
BEND_CHORD = 14.0
BEND_CUT_STEP = 2.0  # metres: the cut widens in these steps until the arms are that far apart


#: netconvert keeps a road's shape as the plain files give it (0.01 m) less every point closer
#: than POSITION_EPS (0.1 m) to the point kept before it (``removeDoublePoints``), walking the
#: shape from one end or the other (of 260 edges of one net, 258 came out as one of the two
#: walks gives them). A corner rounded in steps of a few centimetres can turn sharper there:
#: 119.9° in our graph, 120.2° in the net, on one map of 200. Bends within NET_BEND_MARGIN_DEG
#: of the limit in either walk's shape are cut too.
NET_DECIMALS, NET_POINT_EPS, NET_BEND_MARGIN_DEG = 2, 0.1, 3.0


def cut_sharp_bends(G: nx.Graph) -> None:
    """Cut across every sharp bend (see ``BEND_CHORD``) unless the cut would cross a road: the
    bends of the roads as they are and, cut on that shape, those that the road's shape in the
    net may have (:func:`net_shapes`)."""
    bent = sharp_bend_roads(G)
    near_limit = SHARP_BEND_DEG - NET_BEND_MARGIN_DEG
    in_net = {}
    for reverse in (False, True):
        found = sharp_bend_roads(G, near_limit, shapes=partial(net_shapes, reverse=reverse))
        for e in found:
            if e not in bent and e not in in_net:
                in_net[e] = net_shapes([G.edges[e]["coords"]], reverse=reverse)[0]
    if not bent and not in_net:
        return
    for e, shape in in_net.items():
        G.edges[e]["coords"] = shape
    roads = sorted_edge_list(G)
    edges = [(u, v) for u, v, _ in roads]
    tree = shapely.STRtree(road_lines(roads))
    for u, v in sorted([*bent, *in_net]):
        limit = near_limit if (u, v) in in_net else SHARP_BEND_DEG
        cut = round_corners(cut_across_bends(G.edges[u, v]["coords"], limit), 30.0, 20.0)
        line = shapely.LineString(cut)
        crossed = [edges[k] for k in tree.query(line, predicate="intersects")]
        if all(_touches_only_at_shared_nodes(G, line, (u, v), e) for e in crossed):
            G.edges[u, v]["coords"] = cut


def net_shapes(coords: list, reverse: bool = False) -> list:
    """The polylines as netconvert may store them (``NET_DECIMALS``, ``NET_POINT_EPS``; its
    walk from the last point with ``reverse``). Only polylines with two consecutive points
    that close lose points; the rest are rounded in one pass over all of them."""
    ends = np.cumsum([len(c) for c in coords])
    points = np.round(np.concatenate(coords), NET_DECIMALS)
    close = np.hypot(*np.diff(points, axis=0).T) < NET_POINT_EPS
    close[ends[:-1] - 1] = False  # the step from one polyline to the next
    out = np.split(points, ends[:-1])
    for k in np.unique(np.searchsorted(ends, np.flatnonzero(close), side="right")):
        walked = out[k][::-1] if reverse else out[k]
        kept = _without_double_points(walked)
        out[k] = kept[::-1] if reverse else kept
    return out


def _without_double_points(pts: np.ndarray) -> np.ndarray:
    """SUMO's ``PositionVector::removeDoublePoints(POSITION_EPS)``: a point closer than that to
    the last kept one goes, but the end stays and the point kept before it goes."""
    keep = [0]
    for i in range(1, len(pts)):
        if math.hypot(*(pts[i] - pts[keep[-1]])) < NET_POINT_EPS:
            if i == len(pts) - 1:
                if len(keep) > 1:
                    keep.pop()
                keep.append(i)
            continue
        keep.append(i)
    return pts[keep]


def cut_across_bends(coords: np.ndarray, turn_deg: float = SHARP_BEND_DEG) -> np.ndarray:
    """``coords`` with each bend sharper than ``turn_deg`` cut across where its arms are
    ``BEND_CHORD`` apart (or, a bend near the end, from the end node on)."""
    limit = math.radians(turn_deg)
    for _ in range(4):
        centre = sharp_bend_at(coords, limit, SHARP_BEND_REACH_M)
        if centre is None:
            break
        line = shapely.LineString(coords)
        half = BEND_CUT_STEP
        while True:
            a, b = max(centre - half, 0.0), min(centre + half, line.length)
            if (a == 0.0 and b == line.length) or \
                    line.interpolate(a).distance(line.interpolate(b)) >= BEND_CHORD:
                break
            half += BEND_CUT_STEP
        head = shapely.ops.substring(line, 0.0, a).coords if a > 0.0 else coords[:1]
        tail = shapely.ops.substring(line, b, line.length).coords if b < line.length \
            else coords[-1:]
        coords = np.vstack([head, tail])
    return coords


def _touches_only_at_shared_nodes(G: nx.Graph, line, road: tuple, other: tuple) -> bool:
    if set(road) == set(other):
        return True
    contact = line.intersection(shapely.LineString(G.edges[other]["coords"]))
    shared = set(road) & set(other)
    if shared:
        contact = contact.difference(
            shapely.MultiPoint([G.nodes[n]["xy"] for n in shared]).buffer(0.5))
    return contact.is_empty
