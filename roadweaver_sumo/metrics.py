"""Topology and orientation measures of an undirected road graph (DESIGN.md, "Metrics").

All functions take a graph in the RoadGraph convention (node ``xy``, edge ``coords``). Road
nodes are nodes whose degree is not 2: intersections and dead ends, a roundabout's ring nodes
counted as the one junction they are (as a planner, or osmnx's consolidated intersections,
counts it). The same definitions are used by the generator's density control, by the validation
report and by the tests.
"""

from __future__ import annotations

import math

import networkx as nx
import numpy as np
import shapely
from shapely.strtree import STRtree

from .roadgraph import resample_roads

BEARING_BINS = 36
#: A road's direction at a junction is taken to the point this far along it (metres).
JUNCTION_REACH_M = 20.0
#: Step (m) at which roads are resampled for their curvature: it hides digitising jitter.
CURVATURE_STEP_M = 20.0


def road_node_count(G: nx.Graph) -> int:
    """Number of nodes whose degree is not 2 (intersections and dead ends), a roundabout's
    ring nodes (node attribute ``roundabout``) counted as the one junction they are."""
    return junction_count(G, (n for n, d in G.degree() if d != 2))


def junction_count(G: nx.Graph, nodes) -> int:
    """How many junctions ``nodes`` are: one per node, one per roundabout."""
    return len({G.nodes[n].get("roundabout", ("node", n)) for n in nodes})


def density(G: nx.Graph, area_km2: float) -> float:
    """Road nodes per km² of map area."""
    return road_node_count(G) / area_km2


def lcc_ratio(G: nx.Graph) -> float:
    """Share of road nodes in the largest connected component (1.0 for an empty graph)."""
    total = road_node_count(G)
    if total == 0:
        return 1.0
    best = max((G.subgraph(c) for c in nx.connected_components(G)), key=road_node_count)
    return road_node_count(best) / total


def dead_end_ratio(G: nx.Graph) -> float:
    """Share of road nodes of degree 1."""
    total = road_node_count(G)
    return sum(1 for _, d in G.degree() if d == 1) / total if total else 0.0


def cycle_ratio(G: nx.Graph) -> float:
    """Share of road nodes that lie on at least one cycle.

    A node lies on a cycle exactly when it belongs to a biconnected component with a cycle,
    i.e. one that is more than a single bridge edge.
    """
    total = road_node_count(G)
    if total == 0:
        return 0.0
    on_cycle: set = set()
    for comp in nx.biconnected_components(G):
        if len(comp) >= 3:
            on_cycle |= comp
    return junction_count(G, (n for n in on_cycle if G.degree(n) != 2)) / total


def crossings_without_junction(G: nx.Graph, tolerance: float = 0.5) -> int:
    """Pairs of roads whose centrelines meet anywhere other than at a shared end node.

    Two edges that share a node may touch there; any other contact farther than ``tolerance``
    metres from their shared nodes is a crossing that has no junction.
    """
    edges = list(G.edges)
    if len(edges) < 2:
        return 0
    lines = [shapely.LineString(G.edges[e]["coords"]) for e in edges]
    tree = STRtree(lines)
    left, right = tree.query(lines, predicate="intersects")
    count = 0
    for i, j in zip(left, right):
        if i >= j:
            continue
        contact = lines[i].intersection(lines[j])
        shared = set(edges[i]) & set(edges[j])
        if shared:
            nodes = shapely.MultiPoint([G.nodes[n]["xy"] for n in shared])
            contact = contact.difference(nodes.buffer(tolerance))
        if not contact.is_empty:
            count += 1
    return count


def bearing_histogram(G: nx.Graph, bins: int = BEARING_BINS) -> np.ndarray:
    """Length-weighted histogram of segment bearings, counted in both directions.

    As in osmnx (Boeing 2019, "Urban spatial order"): bearings are compass angles, every segment
    counts once per direction, and bins are centred on 0°, 10°, ... so a north-south street falls
    in the middle of a bin rather than on an edge.
    """
    segments = [np.diff(G.edges[e]["coords"], axis=0) for e in G.edges]
    if not segments:
        return np.zeros(bins)
    d = np.concatenate(segments)
    length = np.hypot(d[:, 0], d[:, 1])
    bearing = np.degrees(np.arctan2(d[:, 0], d[:, 1])) % 360.0
    both = np.concatenate([bearing, (bearing + 180.0) % 360.0])
    weights = np.concatenate([length, length])
    width = 360.0 / bins
    idx = np.floor(((both + width / 2) % 360.0) / width).astype(int) % bins
    return np.bincount(idx, weights=weights, minlength=bins)


def bearing_entropy(G: nx.Graph, bins: int = BEARING_BINS) -> float:
    """Shannon entropy (nats) of the length-weighted bearing histogram; grid ≈ 1.39, uniform 3.58."""
    hist = bearing_histogram(G, bins)
    total = hist.sum()
    if total <= 0:
        return 0.0
    p = hist[hist > 0] / total
    return float(-(p * np.log(p)).sum())


def orientation_order(G: nx.Graph, bins: int = BEARING_BINS) -> float:
    """Boeing's orientation order φ = 1 − ((H − ln 4)/(ln 36 − ln 4))²: 1 for a perfect grid."""
    h = bearing_entropy(G, bins)
    h_min, h_max = math.log(4), math.log(bins)
    return 1.0 - ((h - h_min) / (h_max - h_min)) ** 2


#: A road that turns by more than SHARP_BEND_DEG within SHARP_BEND_REACH_M metres of its length
#: doubles back: lanes offset from it fold over each other, and near a junction SUMO's internal
#: lanes there crossed (the collisions of a 20 km map were all at such hooks).
def mean_curvature(G: nx.Graph, step: float = CURVATURE_STEP_M) -> float:
    """Mean absolute curvature of the centrelines, rad/km: total heading change along every road
    (resampled every ``step`` metres, which hides digitising jitter) per km of road."""
    pts, owner = resample_roads(G, step)
    if len(pts) < 2:
        return 0.0
    same = owner[1:] == owner[:-1]
    d = np.diff(pts, axis=0)
    length = float((np.hypot(*d.T) * same).sum())
    turn = np.abs(np.mod(np.diff(np.arctan2(d[:, 1], d[:, 0])) + math.pi, 2 * math.pi) - math.pi)
    total = float(turn[same[1:] & same[:-1]].sum())
    return 1000.0 * total / length if length > 0 else 0.0


SHARP_BEND_DEG = 120.0
SHARP_BEND_REACH_M = 12.0
#: steps shorter than this have no direction of their own: a net's coordinates are rounded
#: to 0.01 m, and a 0.01 m step between two points of a smooth bend pointed along an axis
#: (learned grid d20 s9: 0° in a bend from 97° to 92°, counted as a 120° turn within 12 m)
MIN_STEP_M = 0.05


def sharp_bends(G: nx.Graph) -> int:
    """Roads whose direction changes by more than ``SHARP_BEND_DEG`` within
    ``SHARP_BEND_REACH_M`` metres (between two steps at most that far apart along the road,
    or at one vertex)."""
    return len(sharp_bend_roads(G))


def sharp_bend_roads(G: nx.Graph, turn_deg: float = SHARP_BEND_DEG,
                     reach_m: float = SHARP_BEND_REACH_M, shapes=None) -> list:
    """The edges counted by :func:`sharp_bends`; with ``shapes`` (polylines -> polylines), of
    the roads as that function gives them.

    The change is taken over the steps, so a bend rounded into many tiny segments counts as one
    turn. One vectorised pass over all roads sums the turning within ``reach_m`` after each
    step; only roads where that sum passes the limit are looked at step by step."""
    limit = math.radians(turn_deg)
    edges = list(G.edges)
    coords = [G.edges[e]["coords"] for e in edges]
    if not coords:
        return []
    if shapes is not None:
        coords = shapes(coords)
    owner = np.repeat(np.arange(len(coords)), [len(c) for c in coords])
    step = np.diff(np.concatenate(coords), axis=0)
    length = np.hypot(*step.T)
    inside = (owner[1:] == owner[:-1]) & (length >= MIN_STEP_M)
    step, length, owner = step[inside], length[inside], owner[1:][inside]
    turn = (np.diff(np.arctan2(step[:, 1], step[:, 0])) + math.pi) % (2 * math.pi) - math.pi
    turn[owner[1:] != owner[:-1]] = 0.0  # no turn from one road into the next
    swept = np.r_[0.0, np.cumsum(np.abs(turn))]
    # where each step starts and ends along the roads laid end to end, a gap wider than
    # reach_m between two roads; steps i..j-1 are compared when step j - 1 starts within
    # reach_m of the end of step i (a corner at one vertex always counts)
    end = np.cumsum(length) + owner * (2.0 * reach_m)
    start = end - length
    last = np.searchsorted(start, end + reach_m, side="right")
    maybe = np.unique(owner[swept[last - 1] - swept > limit])
    return [edges[k] for k in maybe if sharp_bend_at(coords[k], limit, reach_m) is not None]


def sharp_bend_at(coords: np.ndarray, limit: float, reach_m: float) -> float | None:
    """Where (metres along) the polyline first turns by more than ``limit`` radians within
    ``reach_m`` metres: the middle between the two steps that differ most; None if nowhere."""
    step = np.diff(coords, axis=0)
    length = np.hypot(*step.T)
    step, length = step[length >= MIN_STEP_M], length[length >= MIN_STEP_M]
    heading = np.unwrap(np.arctan2(step[:, 1], step[:, 0]))
    if len(heading) < 2:
        return None
    end = np.cumsum(length)
    last = np.searchsorted(end - length, end + reach_m, side="right")
    swept = np.r_[0.0, np.cumsum(np.abs(np.diff(heading)))]  # an upper bound of the change
    for i in np.flatnonzero(swept[last - 1] - swept > limit):
        change = np.abs(heading[i:last[i]] - heading[i])
        j = i + int(np.argmax(change))
        if change[j - i] > limit:
            return float(end[i] + end[j] - length[j]) / 2.0
    return None


def graph_metrics(G: nx.Graph, area_km2: float) -> dict:
    """All road-graph measures above, as one JSON-ready dict."""
    return {
        "road_nodes": road_node_count(G),
        "density": density(G, area_km2),
        "lcc_ratio": lcc_ratio(G),
        "dead_end_ratio": dead_end_ratio(G),
        "cycle_ratio": cycle_ratio(G),
        "crossings_without_junction": crossings_without_junction(G),
        "bearing_entropy": bearing_entropy(G),
        "orientation_order": orientation_order(G),
        "sharp_bends": sharp_bends(G),
    }
