"""Merging junctions (paper §III-C, clean-up): two junctions a road engineer would draw as one.

Junctions closer than a radius are merged even without a road between them, and the two ends
of a road too short to carry lanes (or too short between two junctions for their areas) are
merged, pass after pass. A merge moves the dropped node's roads onto the kept one, the node on
the perimeter ring or else the busier (:func:`_keep_and_drop`), and straightens a road that
would then turn back on itself next to the node (:func:`unhooked`).
"""

from __future__ import annotations

import math

import networkx as nx
import numpy as np
from scipy.spatial import cKDTree

from ..roadgraph import add_road, edge_coords, edge_length, sorted_edge_list
from .perimeter import on_ring
from .planar import higher_class


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
    ring_u, ring_v = on_ring(G, u), on_ring(G, v)
    if ring_u != ring_v:
        return (u, v) if ring_u else (v, u)
    return (u, v) if G.degree(u) >= G.degree(v) else (v, u)
