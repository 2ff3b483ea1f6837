"""Junction angles (paper §III-C, clean-up): roads meeting too sharply at a node.

Where two roads leave a junction closer than the least angle, the minor one goes; at a node
with only two roads the limit is wider (:data:`HAIRPIN_ANGLE`), since joining them would make a
hairpin. Angles are measured as bearings a few metres out along each road
(:func:`departure_angles`), at the point GEOS's ``interpolate`` finds (:func:`point_along`).
"""

from __future__ import annotations

import math

import networkx as nx
import numpy as np
import shapely

from ..roadgraph import edge_coords, edge_list
from .node_sweep import sweep_nodes
from .perimeter import road_keep_weight

#: Two roads at a degree-2 node meeting at less than this (a turn of over 120° from one into
#: the other) would join into a hairpin: lanes offset from so tight a bend fold over each other,
#: and within a few metres of a junction SUMO's internal lanes cross (a 20 km learned map had
#: 35 collisions at one). :func:`remove_sharp_angles` drops the minor road instead.
HAIRPIN_ANGLE = 60.0
HAIRPIN_PROBES = (5.0, 20.0)  # metres out along both roads: a bend close to the node counts too


def meeting_angle(G: nx.Graph, n: int) -> float:
    """The smaller angle (radians) between the two roads of degree-2 node ``n``, the sharpest
    of those measured ``HAIRPIN_PROBES`` out."""
    sharpest = math.pi
    for probe in HAIRPIN_PROBES:
        (a1, _), (a2, _) = departure_angles(G, n, probe)
        sharpest = min(sharpest, (a2 - a1) % (2 * math.pi), (a1 - a2) % (2 * math.pi))
    return sharpest


def departure_angles(G: nx.Graph, n: int, probe: float = 20.0) -> list[tuple[float, int]]:
    """(bearing, neighbour) of each road leaving ``n``, measured ``probe`` metres out."""
    out = []
    for w in G.neighbors(n):
        c = edge_coords(G, n, w)
        qx, qy = point_along(c, probe)
        out.append((math.atan2(qy - float(c[0, 1]), qx - float(c[0, 0])), w))
    return sorted(out)


def point_along(c: np.ndarray, probe: float) -> tuple[float, float]:
    """The point ``min(probe, half the length)`` along polyline ``c`` (n x 2): GEOS's
    ``interpolate``, the very point a LineString's ``interpolate`` gives."""
    line = shapely.linestrings(c)
    at = min(probe, 0.5 * shapely.length(line))
    x, y = shapely.get_coordinates(shapely.line_interpolate_point(line, at))[0].tolist()
    return x, y


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

    sweep_nodes(_maybe_sharp_nodes(G, limit, hairpin), visit)


def _maybe_sharp_nodes(G: nx.Graph, limit: float, hairpin: float) -> list:
    """The nodes that may have a pair of roads for :func:`_sharp_pair_road` to drop: every
    road's bearings at both ends measured in one vectorised pass (GEOS's ``interpolate`` as in
    :func:`departure_angles`, numpy's ``arctan2``; compared with a margin, so a node can only
    be looked at needlessly)."""
    edges = edge_list(G)
    if not edges:
        return []
    points = np.concatenate([data["coords"] for _, _, data in edges])
    sizes = np.array([len(data["coords"]) for _, _, data in edges])
    roads = shapely.linestrings(points, indices=np.repeat(np.arange(len(edges)), sizes))
    ways = np.concatenate([roads, shapely.reverse(roads)])  # from each road's start, then its end
    last = np.cumsum(sizes) - 1
    ends = points[np.r_[last - sizes + 1, last]]
    starts = [data["start"] for _, _, data in edges]
    node = np.array(starts + [v if s == u else u for (u, v, _), s in zip(edges, starts,
                                                                         strict=True)])
    half = 0.5 * shapely.length(ways)
    wide, near = (_tightest(node, _bearings(ways, ends, np.minimum(probe, half)))
                  for probe in (HAIRPIN_PROBES[1], HAIRPIN_PROBES[0]))
    nodes, degree = np.unique(node, return_counts=True)
    margin = 1e-9
    sharp = ((degree >= 3) & (wide < limit + margin)) | (
        (degree == 2) & (np.minimum(wide, near) < hairpin + margin))
    return nodes[sharp].tolist()


def _bearings(ways: np.ndarray, ends: np.ndarray, at: np.ndarray) -> np.ndarray:
    """The bearing from each of ``ends`` to the point ``at`` metres along its line in ``ways``."""
    q = shapely.get_coordinates(shapely.line_interpolate_point(ways, at))
    return np.arctan2(q[:, 1] - ends[:, 1], q[:, 0] - ends[:, 0])


def _tightest(node: np.ndarray, bearing: np.ndarray) -> np.ndarray:
    """Per node (in increasing id), the smallest angle from one of its roads (``bearing`` where
    ``node`` is it) to the next round it (2π at a dead end)."""
    order = np.lexsort((bearing, node))
    node, bearing = node[order], bearing[order]
    head = np.flatnonzero(np.r_[True, node[1:] != node[:-1]])
    tail = np.r_[head[1:], len(node)] - 1
    gap = np.r_[np.diff(bearing), np.inf]
    gap[tail] = np.inf  # from a node's last road to the next node's first: no gap
    return np.minimum(bearing[head] - bearing[tail] + 2 * math.pi, np.minimum.reduceat(gap, head))


def _sharp_pair_road(G: nx.Graph, n: int, limit: float, hairpin: float) -> tuple | None:
    """The road :func:`remove_sharp_angles` drops at ``n`` (the minor road of its first pair
    of roads closer than ``limit``, or of its two roads closer than ``hairpin``), or None."""
    if G.degree(n) < 2:
        return None
    if G.degree(n) == 2 and meeting_angle(G, n) < hairpin:
        return min(((n, w) for w in G.neighbors(n)), key=lambda e: road_keep_weight(G, *e))
    angles = departure_angles(G, n)
    for k, (a1, w1) in enumerate(angles):
        a2, w2 = angles[(k + 1) % len(angles)]
        if (a2 - a1) % (2 * math.pi) < limit:
            return min(((n, w1), (n, w2)), key=lambda e: road_keep_weight(G, *e))
    return None
