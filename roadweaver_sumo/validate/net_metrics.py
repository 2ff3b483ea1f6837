"""Metrics of a SUMO ``.net.xml`` (DESIGN.md "Metrics"): the shared road-graph metrics, junction-
and lane-level reachability, and how well consecutive lane shapes meet at junctions.

Reachability is counted with bitsets over the condensation (strongly connected components) of the
lane graph, processed in reverse topological order: linear in the graph size times n/64 words,
where all-pairs BFS would be quadratic in lanes.
"""

from __future__ import annotations

from collections.abc import Callable, Hashable, Iterable
from itertools import pairwise
from pathlib import Path

import networkx as nx
import numpy as np
import sumolib

from .. import metrics
from .netgraph import internal_chain, lane_graph, load_net, road_edges, road_graph, road_junctions
from .overlaps import net_overlaps
from .rule_coverage import rule_coverage


def net_metrics(net_path: Path, area_km2: float) -> dict:
    """All net-level figures of DESIGN.md "Metrics" for the net at ``net_path`` (area in km²)."""
    return loaded_net_metrics(load_net(net_path), area_km2)


def loaded_net_metrics(net: sumolib.net.Net, area_km2: float) -> dict:
    """:func:`net_metrics` of a net already read with :func:`netgraph.load_net`."""
    lanes = lane_graph(net)
    junctions = [n.getID() for n in road_junctions(net)]
    result = dict(metrics.graph_metrics(road_graph(net), area_km2))
    result.update(
        junctions=len(junctions),
        edges=len(road_edges(net)),
        lanes=lanes.number_of_nodes(),
        junction_reachability=junction_reachability(lanes, junctions),
        lane_reachability=lane_reachability(lanes),
        alignment=alignment_errors(net),
        # lanes drawn over each other outside junctions, not only centrelines that cross
        crossings_without_junction=len(net_overlaps(net)),
        rules=rule_coverage(net),
    )
    return result


def lane_reachability(lanes: nx.DiGraph) -> float:
    """Share of ordered lane pairs (a, b), a != b, with a drivable path from a to b."""
    return reachable_share(lanes, lanes.nodes, lanes.nodes, key=lambda n: n)


def junction_reachability(lanes: nx.DiGraph, junctions: list) -> float:
    """Share of ordered junction pairs (u, v), u != v, such that a car leaving u on some lane can
    drive to a lane entering v. Junctions without lanes count (as unreachable)."""
    D = lanes.copy()
    for j in junctions:
        D.add_node(("out", j))
        D.add_node(("in", j))
    for lane, data in lanes.nodes(data=True):
        D.add_edge(("out", data["from_junction"]), lane)
        D.add_edge(lane, ("in", data["to_junction"]))
    sources = [("out", j) for j in junctions]
    targets = [("in", j) for j in junctions]
    return reachable_share(D, sources, targets, key=lambda n: n[1])


def reachable_share(
    D: nx.DiGraph, sources: Iterable, targets: Iterable, key: Callable[[Hashable], Hashable]
) -> float:
    """Share of (source, target) pairs with key(source) != key(target) where the target is
    reachable from the source in ``D`` (1.0 when there are no such pairs)."""
    sources, targets = list(sources), list(targets)
    reach = _reach_bitsets(D, targets)
    target_index = {key(t): i for i, t in enumerate(targets)}
    reached = pairs = 0
    for s in sources:
        i = target_index.get(key(s))
        own = 0 if i is None else (reach[s] >> i) & 1
        reached += reach[s].bit_count() - own
        pairs += len(targets) - (i is not None)
    return reached / pairs if pairs else 1.0


def _reach_bitsets(D: nx.DiGraph, targets: list) -> dict:
    """For each node, an int whose bit i is set when ``targets[i]`` is reachable from it
    (a node reaches itself): one OR per condensation arc, children before parents."""
    C = nx.condensation(D)
    mapping = C.graph["mapping"]
    bits = [0] * C.number_of_nodes()
    for i, t in enumerate(targets):
        bits[mapping[t]] |= 1 << i
    for c in reversed(list(nx.topological_sort(C))):
        for child in C.successors(c):
            bits[c] |= bits[child]
    return {n: bits[c] for n, c in mapping.items()}


def alignment_errors(net: sumolib.net.Net) -> dict:
    """Gaps (m) where a connection's lanes should meet: from-lane end to first internal lane
    start, internal lane to internal lane, last internal lane end to to-lane start.
    Connections without internal lanes are not measured (nothing is drawn between the lanes)."""
    gaps = []
    for edge in road_edges(net):
        for conns in edge.getOutgoing().values():
            for conn in conns:
                chain = internal_chain(net, conn)
                if not chain:
                    continue
                shapes = [conn.getFromLane().getShape()]
                shapes += [lane.getShape() for lane in chain] + [conn.getToLane().getShape()]
                gaps += [_distance(a[-1], b[0]) for a, b in pairwise(shapes)]
    if not gaps:
        return {"count": 0, "mean": 0.0, "p95": 0.0, "max": 0.0}
    g = np.asarray(gaps)
    return {
        "count": int(g.size),
        "mean": float(g.mean()),
        "p95": float(np.percentile(g, 95)),
        "max": float(g.max()),
    }


def _distance(p, q) -> float:
    return float(np.hypot(p[0] - q[0], p[1] - q[1]))
