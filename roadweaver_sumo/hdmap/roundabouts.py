"""Roundabouts (issue 36): a ring with its own lane, traffic circulating counter-clockwise,
entries yielding to it.

Towns build roundabouts where collector roads meet local streets or each other: junctions of
three or four arms without a light, the arms well spread round them. A rule suite needs
them: entering traffic yields to the ring, exits are right turns, and the ring carries traffic
past every arm.

The junction's node is replaced by a ring of ``RING_RADIUS`` (the centreline of its one
lane): each arm ends where it meets the circle, at a ring node of three arms (the arm, the
ring in, the ring out), and one-way collector roads run between consecutive ring nodes
counter-clockwise (right-hand traffic). The ring nodes carry ``roundabout`` (the replaced
node's id): SUMO is told the ring is a roundabout (``export.sumo_plain``), which makes every
entry yield to the ring, and the road-node count takes a roundabout as one junction
(``metrics.road_node_count``), so the map's density stays what was asked for.
"""

from __future__ import annotations

import math

import networkx as nx
import numpy as np
import shapely
from shapely.ops import substring

from .. import clearance  # a module: clearance imports hdmap.lanes, which loads this package
from .control import ControlPlan
from .geometry import dedupe

RING_RADIUS = 15.0  # m: a compact urban roundabout, about 34 m across its outer edge
RING_CLASS = "collector"
ARM_CLASSES = ("collector", "local")  # two-lane arterials would merge into the one ring lane
MIN_ARM_LEFT = 40.0  # m of each arm beyond the ring
MIN_GAP = math.radians(60.0)  # the arms at least this far apart round the junction
MIN_SPACING = 250.0  # m between two roundabouts
BORDER = 100.0  # m: no roundabout nearer the map's edge
RING_STEP = 3.0  # m between the ring's polyline vertices


def add_roundabouts(G: nx.Graph, count: int, plan: ControlPlan) -> nx.Graph:
    """``G`` with up to ``count`` junctions turned into roundabouts: those of three or four
    collector or local arms without a light (``plan``) where a collector meets, nor a kind a
    junction mix asked for, the most collector arms and arms first, ``MIN_SPACING`` apart;
    one whose ring or arms come within another road's clearance
    (``clearance.crowded``) is left out. ``G`` itself where none is made."""
    if count <= 0:
        return G
    chosen: list[int] = []
    for node in sorted(G.nodes, key=lambda n: _rank(G, n)):
        if len(chosen) == count:
            break
        xy = np.asarray(G.nodes[node]["xy"])
        if _fits(G, node, plan) and all(
                np.hypot(*(xy - G.nodes[other]["xy"])) >= MIN_SPACING for other in chosen):
            chosen.append(node)
    while chosen:
        ringed, ring_of = _build(G, chosen)
        crowded = clearance.crowded(ringed, ring_of)
        if not crowded:
            return ringed
        chosen = [node for node in chosen if node not in crowded]
    return G


def _rank(G: nx.Graph, node: int) -> tuple:
    classes = [G.edges[e]["road_class"] for e in G.edges(node)]
    return (-classes.count("collector"), -len(classes), node)


def _fits(G: nx.Graph, node: int, plan: ControlPlan) -> bool:
    """Whether ``node`` can be a roundabout: 3 or 4 arms of ``ARM_CLASSES``, one a collector,
    no light, away from the map's edge, arms that leave the ring once, ``MIN_GAP`` apart and
    ``MIN_ARM_LEFT`` long beyond it, to distinct other junctions."""
    arms = sorted(G.edges(node))
    classes = [G.edges[e]["road_class"] for e in arms]
    x, y = G.nodes[node]["xy"]
    if not (3 <= len(arms) <= 4 and set(classes) <= set(ARM_CLASSES) and "collector" in classes
            and plan.control(node, classes) != "traffic_light" and not plan.counts_for_mix(node)
            and min(x, y, G.graph["width"] - x, G.graph["height"] - y) >= BORDER
            and len({v for _, v in arms}) == len(arms)):
        return False
    ports = [_port(G, node, arm) for arm in arms]
    if any(port is None for port in ports):
        return False
    angles = np.sort([angle for angle, _ in ports])
    gaps = np.diff(np.r_[angles, angles[0] + 2 * math.pi])
    return bool(gaps.min() >= MIN_GAP)


def _port(G: nx.Graph, node: int, arm: tuple[int, int]):
    """(angle round the ring, the arm beyond it as a polyline from the ring) where ``arm``
    leaves the ring, or None where it leaves it more than once or too short."""
    data = G.edges[arm]
    coords = data["coords"] if data["start"] == node else data["coords"][::-1]
    line = shapely.LineString(coords)
    circle = shapely.Point(coords[0]).buffer(RING_RADIUS, quad_segs=64).exterior
    meets = [part for part in shapely.get_parts(line.intersection(circle)) if not part.is_empty]
    if len(meets) != 1 or line.length - line.project(meets[0]) < MIN_ARM_LEFT:
        return None
    beyond = dedupe(np.asarray(substring(line, line.project(meets[0]), line.length).coords))
    start = beyond[0] - coords[0]
    return math.atan2(start[1], start[0]), beyond


def _build(G: nx.Graph, chosen: list[int]):
    """A copy of ``G`` with the ``chosen`` junctions made roundabouts; returns it and, per
    new road (sorted edge), the junction it was made for."""
    G = G.copy()
    made = {}
    next_node = max(G.nodes) + 1
    for node in chosen:
        centre = np.asarray(G.nodes[node]["xy"], dtype=float)
        ports = sorted(((*_port(G, node, (node, far)), far, G.edges[node, far])
                        for far in sorted(G[node])), key=lambda port: port[0])
        G.remove_node(node)
        ring = list(range(next_node, next_node + len(ports)))
        next_node += len(ports)
        for r, (_, beyond, far, data) in zip(ring, ports, strict=True):
            G.add_node(r, xy=(float(beyond[0][0]), float(beyond[0][1])), roundabout=node)
            G.add_edge(r, far, **{**data, "coords": beyond, "start": r})
            made[(min(r, far), max(r, far))] = node
        for k, (angle, *_) in enumerate(ports):  # counter-clockwise, one way
            a, b = ring[k], ring[(k + 1) % len(ring)]
            end = ports[(k + 1) % len(ports)][0]
            sweep = (end - angle) % (2 * math.pi)
            t = angle + np.linspace(0.0, sweep, max(3, math.ceil(sweep * RING_RADIUS / RING_STEP)))
            arc = centre + RING_RADIUS * np.column_stack([np.cos(t), np.sin(t)])
            arc[0], arc[-1] = G.nodes[a]["xy"], G.nodes[b]["xy"]
            G.add_edge(a, b, coords=arc, road_class=RING_CLASS, start=a, one_way=True,
                       roundabout=node)
            made[(min(a, b), max(a, b))] = node
    return G, made
