"""Junction angles (paper §III-C, clean-up): roads meeting too sharply at a node.

Where two roads leave a junction closer than the least angle, the minor one goes; at a node
with only two roads the limit is wider (:data:`HAIRPIN_ANGLE`), since joining them would make a
hairpin. Angles are measured as bearings a few metres out along each road
(:func:`departure_angles`), the point found exactly as GEOS's ``interpolate`` finds it
(:func:`point_along`), so that no last-bit difference flips a test.
"""

from __future__ import annotations

import math

import networkx as nx
import numba as nb
import numpy as np

from ..compiled import F8, F8_1D, F8_2D, F8_2D_ANY, I8_1D, compiled
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

    sweep_nodes(_maybe_sharp_nodes(G, limit, hairpin), visit)


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
    if G.degree(n) == 2 and meeting_angle(G, n) < hairpin:
        return min(((n, w) for w in G.neighbors(n)), key=lambda e: road_keep_weight(G, *e))
    angles = departure_angles(G, n)
    for k, (a1, w1) in enumerate(angles):
        a2, w2 = angles[(k + 1) % len(angles)]
        if (a2 - a1) % (2 * math.pi) < limit:
            return min(((n, w1), (n, w2)), key=lambda e: road_keep_weight(G, *e))
    return None
