"""Clean-up of the planar road graph (paper §III-C): remove what a road engineer would not draw.

Near-duplicate junctions are merged, slivers of road contracted, junction angles that are too
sharp resolved by dropping the minor road, stubs that run off the map pruned, fragments
outside the main component dropped, roads within another's clearance removed, and degree-2
nodes dissolved into longer roads; passes repeat until nothing changes. Then corners are
rounded (:mod:`.bends`).
"""

from __future__ import annotations

import heapq
import math

import networkx as nx
import numba as nb
import numpy as np
import shapely
import shapely.ops
from scipy.spatial import cKDTree

from ..compiled import F8, F8_1D, F8_2D, F8_2D_ANY, I8_1D, compiled
from ..roadgraph import (
    add_road,
    edge_coords,
    edge_length,
    edge_list,
    sorted_edge_list,
)
from ..skeleton.model import PERIMETER_INSET
from .bends import smooth_bends
from .clearance import roads_too_close
from .planar import CLASS_RANK, higher_class, road_lines


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
                         junction_gap: float = MIN_JUNCTION_GAP) -> None:
    """Merge the two ends of every road shorter than ``min_length``, and of every road between
    two junctions shorter than ``junction_gap`` (the busier end stays), pass after pass until
    none is left: a merge can make the roads at the kept node short."""
    longest = max(junction_gap, min_length)
    merged = True
    while merged:
        merged = False
        edges = sorted_edge_list(G)
        for k in np.flatnonzero(_maybe_shorter([data["coords"] for _, _, data in edges],
                                               longest)).tolist():
            u, v, _ = edges[k]
            if not G.has_edge(u, v):
                continue
            limit = junction_gap if G.degree(u) >= 3 and G.degree(v) >= 3 else min_length
            if edge_length(G, u, v) < max(limit, min_length):
                merge_nodes(G, *_keep_and_drop(G, u, v))
                merged = True


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


def merge_close_nodes(G: nx.Graph, radius: float) -> None:
    """Merge junctions closer than ``radius`` even when no road joins them directly, pair by
    pair in node order. A merge keeps the kept node where it is and makes no node, so the
    close pairs are found once; a pair whose node has gone is skipped."""
    nodes = sorted(G.nodes)
    if len(nodes) < 2:
        return
    pts = np.array([G.nodes[n]["xy"] for n in nodes])
    dropped: set = set()
    for i, j in sorted(cKDTree(pts).query_pairs(radius)):
        if nodes[i] in dropped or nodes[j] in dropped:
            continue
        keep, drop = _keep_and_drop(G, nodes[i], nodes[j])
        merge_nodes(G, keep, drop)
        dropped.add(drop)


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


def _meeting_angle(G: nx.Graph, n: int) -> float:
    """The smaller angle (radians) between the two roads of degree-2 node ``n``, the sharpest
    of those measured ``HAIRPIN_PROBES`` out."""
    sharpest = math.pi
    for probe in HAIRPIN_PROBES:
        (a1, _), (a2, _) = departure_angles(G, n, probe)
        sharpest = min(sharpest, (a2 - a1) % (2 * math.pi), (a1 - a2) % (2 * math.pi))
    return sharpest


def dissolve_degree_two(G: nx.Graph, min_angle_deg: float = 0.0) -> None:
    """Join the two roads at a degree-2 node into one, unless that would duplicate a road or
    the two meet at less than ``min_angle_deg`` or ``HAIRPIN_ANGLE`` (the joined road would
    double back: that V is :func:`remove_sharp_angles`' to resolve).

    A join keeps the degree of every other node (its ends trade a road for a road), so the
    nodes of degree 2 are found once."""
    limit = math.radians(max(min_angle_deg, HAIRPIN_ANGLE))
    for n in sorted(n for n, degree in G.degree() if degree == 2):
        a, b = sorted(G.neighbors(n))
        if a == b or G.has_edge(a, b):
            continue
        if _meeting_angle(G, n) < limit:
            continue
        ca, cb = edge_coords(G, a, n), edge_coords(G, n, b)
        cls = higher_class(G.edges[a, n]["road_class"], G.edges[n, b]["road_class"])
        G.remove_node(n)
        add_road(G, a, b, np.vstack([ca, cb[1:]]), cls)


def departure_angles(G: nx.Graph, n: int, probe: float = 20.0) -> list[tuple[float, int]]:
    """(bearing, neighbour) of each road leaving ``n``, measured ``probe`` metres out."""
    out = []
    for w in G.neighbors(n):
        c = edge_coords(G, n, w)
        qx, qy = point_along(c, probe)
        out.append((math.atan2(qy - float(c[0, 1]), qx - float(c[0, 0])), w))
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


def remove_sharp_angles(G: nx.Graph, min_angle_deg: float) -> None:
    """Drop the minor road of every pair meeting at a node at less than ``min_angle_deg``,
    sweeping the nodes in order until none is left.

    Degree-2 nodes count too, up to ``HAIRPIN_ANGLE``: two roads left in a V (a third road at
    the node removed) would otherwise be joined into one road that doubles back on itself, a
    hairpin whose lanes fold over each other (a learned map had one 3 m from its own junction,
    and a car hit).

    Whether a node has a pair to drop depends on its own roads alone, so the first sweep
    visits only the nodes that may have one (:func:`_maybe_sharp_nodes`), and each later one
    only the nodes that lost a road since they were last looked at: every other node would
    find nothing."""
    limit = math.radians(min_angle_deg)
    hairpin = math.radians(max(min_angle_deg, HAIRPIN_ANGLE))

    def visit(n):
        road = _sharp_pair_road(G, n, limit, hairpin)
        if road is None:
            return ()
        G.remove_edge(*road)
        return road

    _sweep(_maybe_sharp_nodes(G, limit, hairpin), visit)


def _sweep(nodes, visit) -> None:
    """Visit ``nodes`` in order, and again every node that ``visit`` (which returns the nodes
    whose roads it changed) touches: later in the same sweep if it comes after the node
    visited, else in the next sweep; until a sweep touches no node it already passed."""
    todo = sorted(nodes)  # a sorted list is a heap
    while todo:
        queued, again = set(todo), set()
        while todo:
            n = heapq.heappop(todo)
            for m in visit(n):
                if m <= n:
                    again.add(m)  # already visited in this sweep: the next one
                elif m not in queued:
                    heapq.heappush(todo, m)
                    queued.add(m)
        todo = sorted(again)


def _maybe_sharp_nodes(G: nx.Graph, limit: float, hairpin: float) -> list:
    """The nodes that may have a pair of roads for
    :func:`_sharp_pair_road` to drop: every road's bearings at both ends measured in one
    compiled pass (the same steps as :func:`departure_angles`, compared with a margin, so a
    node can only be looked at needlessly)."""
    edges = edge_list(G)
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
    return node[order[head[sharp]]].tolist()


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


def _sharp_pair_road(G: nx.Graph, n: int, limit: float, hairpin: float) -> tuple | None:
    """The road :func:`remove_sharp_angles` drops at ``n`` (the minor road of its first pair
    of roads closer than ``limit``, or of its two roads closer than ``hairpin``), or None."""
    if G.degree(n) < 2:
        return None
    if G.degree(n) == 2 and _meeting_angle(G, n) < hairpin:
        return min(((n, w) for w in G.neighbors(n)), key=lambda e: road_keep_weight(G, *e))
    angles = departure_angles(G, n)
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
    pass."""
    edges = edge_list(G)
    if not edges:
        return set()
    coords = [np.asarray(data["coords"], dtype=float) for _, _, data in edges]
    owner = np.repeat(np.arange(len(edges)), [len(c) for c in coords])
    away = ~(_perimeter_offset(G, np.concatenate(coords)) < tolerance)
    along = np.bincount(owner[away], minlength=len(edges)) == 0
    return {n for (u, v, _), hit in zip(edges, along.tolist(), strict=True) if hit
            for n in (u, v)}


def prune_stubs(G: nx.Graph, max_length: float, margin: float) -> None:
    """Remove dead-end roads shorter than ``max_length`` or ending within ``margin`` of the map
    border (roads cut off by the border), and nodes left without a road, sweeping the nodes
    in order until none is left, so chains of stubs go too.

    Whether a node goes depends on its own roads alone, so a sweep visits only the nodes
    with at most one road at its start and those that lost one since they were looked at
    (as :func:`remove_sharp_angles` does)."""
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

    _sweep([n for n, degree in G.degree() if degree <= 1], visit)


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




def remove_close_roads(G: nx.Graph) -> bool:
    """Remove, of every pair of roads closer than their lanes allow (:mod:`.clearance`), the
    road less worth keeping (:func:`road_keep_weight`); returns whether one went."""
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

