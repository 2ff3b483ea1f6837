"""Corners and bends of single roads (paper §III-C, §III-D): fillets at sharp corners, jogs
merged, straight road ends at junctions, and bends that double back cut across.

Lanes are offset from a road's centreline: at a corner tighter than the lanes' half width they
fold over each other, in SUMO's net, in OpenDRIVE readers and in lanelet2 polygons alike.
"""

from __future__ import annotations

import math
from functools import partial

import networkx as nx
import numpy as np
import shapely
import shapely.ops

from ..clearance import half_width, roads_too_close
from ..hdmap.lanes import LANE_CONFIGS
from ..metrics import SHARP_BEND_DEG, SHARP_BEND_REACH_M, sharp_bend_at, sharp_bend_roads
from ..roadgraph import (
    edge_list,
    sorted_edge_list,
)
from .planar import road_lines


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


#: Two corners that turn the same way are not made one corner turning more than this (radians):
#: the two corners of a U a few metres wide would become one vertex doubling back, which
#: rounding cannot save (``metrics.sharp_bends``).
FOLD = math.radians(SHARP_BEND_DEG)


def without_jogs(coords: np.ndarray, max_turn_deg: float, least_radius: float) -> np.ndarray:
    """``coords`` with every corner that turns more than ``max_turn_deg`` given the room its
    fillet (:func:`round_corners`) needs for a radius of ``least_radius``: where the leg to
    an interior neighbour is shorter, that neighbour goes, or, when it is such a corner too,
    the two become one at the middle of their leg (unless that one would turn more than
    :data:`FOLD`: a U stays a U); shortest leg first.

    Such pairs are one bend drawn as a jog (a step of the traced skeleton) or a corner where
    two roads were joined at a dissolved junction next to a vertex of a traced curve.
    Filleted one by one, such a corner gets a radius of a few metres or less, and lanes
    offset from the centreline fold over (CommonRoad's self-intersecting lanelets, paper
    §III-D). A fillet with tangents ``t`` turning by ``θ`` has a least radius of
    t·cos²(θ/2)/sin(θ/2)."""
    coords = _distinct(coords)
    limit = math.radians(max_turn_deg)
    kept: set[bytes] = set()  # legs between two corners that one corner would fold back
    while len(coords) >= 4:
        half_turns = np.r_[0.0, turn_angles(coords) / 2, 0.0]
        sharp = half_turns > limit / 2
        needs = np.where(sharp, least_radius * np.sin(half_turns) / np.cos(half_turns) ** 2
                         / FILLET_SHARE, 0.0)
        legs = np.hypot(*np.diff(coords, axis=0).T)
        short = legs < np.maximum(needs[:-1], needs[1:])
        short[[0, -1]] = False  # a road's end node stays
        if kept:
            short &= [coords[k:k + 2].tobytes() not in kept for k in range(len(legs))]
        if not short.any():
            break
        k = np.flatnonzero(short)[np.argmin(legs[short])]
        if sharp[k] and sharp[k + 1]:
            middle = (coords[k] + coords[k + 1]) / 2
            if turn_angles(np.array([coords[k - 1], middle, coords[k + 2]]))[0] > FOLD:
                kept.add(coords[k:k + 2].tobytes())  # a U of two corners stays a U
                continue
            coords = np.vstack([coords[:k], middle, coords[k + 2:]])
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
        for pair in roads_too_close(G, among=jogged.keys()):
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
