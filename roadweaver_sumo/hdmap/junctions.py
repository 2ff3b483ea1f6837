"""Junctions: control type, trim radius and connector lane geometry (paper Algorithm 1:
RefineRoadGraph's junction-aware processing and ConstructJunctionConnections).

A connector is a cubic Bezier whose ends are exactly the incoming lane's end and the outgoing
lane's start, tangent to both, so the HD map's endpoint alignment error is zero by construction.
"""

from __future__ import annotations

import math
from collections import defaultdict

import numpy as np

from .control import ControlPlan
from .geometry import (
    bezier_controls,
    bezier_sample,
    bezier_sample_counts,
    boundary_offsets,
    end_directions,
    offset_along,
)
from .lanes import BEND_MARGIN, LaneEnds, half_width, lane_ends
from .model import HDMap, Junction, Lane, Road
from .reference import Piece, plan_points

MIN_RADIUS = 2.0  # m: room for a connector even where a road just continues (degree-2 nodes)
MARGIN = 1.0  # m: clearance added beyond the point where road edges meet
MIN_ANGLE = np.radians(30.0)  # junction angles below this are treated as 30 degrees
NEAR_STRAIGHT = np.radians(150.0)  # neighbouring roads this far apart do not overlap
HEADING_PROBE = 5.0  # m along a road used to measure its direction at a junction
LATERAL_ACCEL = 3.0  # m/s^2: connector speed limit sqrt(a * r_min) on tight turns
PIVOT_GAP = 1e-6  # m: a boundary whose ends are closer starts and ends at one point
#: Kerb radius (m) of a junction's corners, at the road's outer edge (the sidewalk's, where
#: there is one). It sets where a road's lanes end and so the junction's outline, which SUMO,
#: OpenDRIVE and lanelet2 all get (``export.sumo_plain``). On tight corners a right turn
#: crosses both crossings near the corner at an angle, and SUMO's drivers, who judge a
#: walker's distance along the crossing as if they crossed it square, pass walkers who then
#: step into the car's side: with 100 walkers on 50 maps, a touch on 7 at 4 m, 4 at 8 m.
CORNER_RADIUS = 8.0
CORNER_ANGLE = np.radians(60.0)  # corners sharper than this keep this one's tangent
PIVOT_CLEARANCE = 1e-7  # m: a U-turn arc's radius beyond its lane's half width (< PIVOT_GAP / 2)


def junction_trims(directions: np.ndarray, half_widths: np.ndarray, lane_widths: np.ndarray,
                   sizes: list[int], outer_widths: np.ndarray | None = None,
                   corners: np.ndarray | None = None) -> np.ndarray:
    """How far each road's lane ends stay back from its junction's centre, one per row:
    junction k's roads are the next ``sizes[k]`` rows of ``directions`` (unit, leaving the
    junction), ``half_widths`` and ``lane_widths``. A road takes what the corners on either
    side of it ask for, as netconvert cuts each edge; with one trim for all its roads, a
    light with one corner of 57 degrees was 57 m across, and cars merging on its 48 m
    internal lanes collided.

    Two neighbouring roads at angle ``a`` (clipped at 30 degrees) ask for two things. Their
    facing edges, at half widths ``w_i`` and ``w_j``, meet ``(w_j + w_i cos a) / sin a`` along
    road ``i``: the lanes end ``MARGIN`` beyond that. And the right turn between them, from the
    outer lane of one to the outer lane of the other (centres ``d = w - lane width / 2`` from
    the roads' centre lines, crossing ``(d_j + d_i cos a) / sin a`` along road ``i``), needs
    room for a fillet whose inner lane edge keeps ``BEND_MARGIN`` of radius: a tangent of
    ``(lane width / 2 + BEND_MARGIN) / tan(a / 2)``. Narrower room makes its inner edge fold
    over wherever a reader offsets lanes from the connector's centre line (OpenDRIVE readers:
    CommonRoad, pyxodr), the way a 120-degree right turn between arterials did. Roads at
    ``NEAR_STRAIGHT`` or more from their neighbour ask for nothing; dead ends keep room for a
    turnaround.

    A junction with ``corners`` (per junction: the kerb radius, metres, or 0) also rounds the
    corner between neighbouring roads at their outer edges (``outer_widths``: half widths with
    the sidewalk) with that radius, whose tangent ``radius / tan(a / 2)`` runs on from where
    the outer edges meet, ``(o_j + o_i cos a) / sin a`` along road ``i`` (on corners sharper
    than ``CORNER_ANGLE``, that corner's tangent): a local street's lanes end beyond the
    arterial's sidewalk, the arterial's beyond the local street's. That is the room
    netconvert gives a corner, and with it the crossings; without it a crossing took the
    whole of a local junction and cars turned over it on a 2 m radius, and at an acute
    corner the two crossings met and a car turning right crossed both at once into a walker.
    """
    if not sizes:
        return np.zeros(0)
    sizes = np.asarray(sizes)
    first = np.cumsum(sizes) - sizes
    group = np.repeat(np.arange(len(sizes)), sizes)
    bearing = np.arctan2(directions[:, 1], directions[:, 0])
    order = np.lexsort((bearing, group))  # ties keep their row order
    b, w, lane = bearing[order], half_widths[order], lane_widths[order]
    after = np.arange(1, len(b) + 1)  # each road's next one round its junction
    after[first + sizes - 1] = first
    gap = np.mod(b[after] - b, 2 * np.pi)
    near = (gap < NEAR_STRAIGHT) & (after != np.arange(len(b)))
    a = np.maximum(gap[near], MIN_ANGLE)
    wi, wj = w[near], w[after][near]
    li, lj = lane[near], lane[after][near]
    di, dj = wi - li / 2.0, wj - lj / 2.0
    edges = np.maximum(wj + wi * np.cos(a), wi + wj * np.cos(a)) / np.sin(a) + MARGIN
    turn = (np.maximum(dj + di * np.cos(a), di + dj * np.cos(a)) / np.sin(a)
            + (np.maximum(li, lj) / 2.0 + BEND_MARGIN) / np.tan(a / 2.0))
    # what the corner between each road and the next asks of that road, and of the next one
    mine, next_ones = np.full(len(b), MIN_RADIUS), np.full(len(b), MIN_RADIUS)
    mine[near] = next_ones[near] = np.maximum(np.maximum(edges, turn), MIN_RADIUS)
    if corners is not None:
        o = (half_widths if outer_widths is None else outer_widths)[order]
        oi, oj = o[near], o[after][near]
        tangent = (np.asarray(corners, dtype=float)[group[order]][near]
                   / np.tan(np.maximum(a, CORNER_ANGLE) / 2.0))
        mine[near] = np.maximum(mine[near], (oj + oi * np.cos(a)) / np.sin(a) + tangent)
        next_ones[near] = np.maximum(next_ones[near], (oi + oj * np.cos(a)) / np.sin(a) + tangent)
    before = np.empty_like(after)  # each road's previous one round its junction
    before[after] = np.arange(len(b))
    trims = np.empty(len(b))
    trims[order] = np.maximum(mine, next_ones[before])  # the corners after and before it
    dead_end = sizes == 1
    trims[first[dead_end]] = np.maximum(half_widths[first[dead_end]], MIN_RADIUS)
    return trims


def make_junctions(
    nodes: dict[int, tuple[float, float]], roads: dict[int, Road],
    plan: ControlPlan | None = None, tapers: dict[int, float] | None = None,
    rings: dict[int, int] | None = None,
) -> dict[int, Junction]:
    """One junction per node with its incident roads, control (``plan``, by default the default
    rule set's) and their trims (:func:`junction_trims`); ``tapers``: the taper nodes of turn
    bays (``turn_bays``) and the trim each needs, where the through lanes move aside;
    ``rings``: a roundabout's ring nodes (``roundabouts``) and the junction each replaced:
    priority junctions, whose entries yield to the ring, with no kerb corners."""
    plan, tapers, rings = plan or ControlPlan(), tapers or {}, rings or {}
    incident: dict[int, list[int]] = defaultdict(list)
    for road in roads.values():
        incident[road.from_node].append(road.id)
        incident[road.to_node].append(road.id)
    # the unit direction in which each road leaves each of its ends, measured a few metres out
    heads = end_directions([road.centreline for road in roads.values()], HEADING_PROBE)
    row = {rid: 2 * k for k, rid in enumerate(roads)}
    nodes_in_order = sorted(incident)
    incidents = [sorted(incident[node]) for node in nodes_in_order]
    dirs = heads[[row[r] + (roads[r].from_node != node)
                  for node, rids in zip(nodes_in_order, incidents, strict=True) for r in rids]]
    arms = [roads[r] for rids in incidents for r in rids]
    widths = np.array([half_width(road) for road in arms])
    corners = [0.0 if node in rings else CORNER_RADIUS for node in nodes_in_order]
    trims = iter(junction_trims(dirs, widths, np.array([road.lane_width for road in arms]),
                                [len(rids) for rids in incidents],
                                widths + [road.sidewalk_width for road in arms], corners).tolist())
    return {
        node: Junction(
            id=node,
            xy=(float(nodes[node][0]), float(nodes[node][1])),
            type="priority" if node in rings else plan.control(
                node, [roads[r].road_class for r in rids], [roads[r].lane_count for r in rids]),
            trims={r: max(next(trims), tapers.get(node, 0.0)) for r in rids},
            roads=rids,
            taper=node in tapers,
            roundabout=rings.get(node),
        )
        for node, rids in zip(nodes_in_order, incidents, strict=True)
    }


def add_connectors(hd: HDMap, plan: list[tuple[int, str, str, str]],
                   ends: LaneEnds | None = None) -> list[Lane]:
    """Create connector lanes for ``(node, incoming lane, outgoing lane, movement)`` entries,
    all Beziers computed in one vectorised batch (from ``ends``, the road lanes' ends, if
    given).

    A connector runs from the incoming lane's end to the outgoing lane's start, tangent to
    both; its width blends linearly between theirs so its boundaries meet theirs too, except
    that the inner boundary of a bend tighter than half the width is pulled in so that it never
    folds back (``geometry.boundary_offsets``); its speed is capped by its tightest curvature.
    Lane-graph links are set on the connector only
    (the road lanes learn about it in ``topology.link_connector``).
    """
    if not plan:
        return []
    ins = [hd.lanes[p[1]] for p in plan]
    outs = [hd.lanes[p[2]] for p in plan]
    if ends is None:
        ends = lane_ends({lane.id: lane for lane in ins + outs}.values())
    i = [ends.row[p[1]] for p in plan]
    o = [ends.row[p[2]] for p in plan]
    ctrl = bezier_controls(ends.end[i], ends.end_tangent[i], ends.start[o], ends.start_tangent[o])
    w0 = np.array([a.end_width for a in ins])
    w1 = np.array([b.width for b in outs])
    curves, turn_speed = _connector_curves(ctrl, w0, w1)
    lanes = []
    for k, ((node, in_id, out_id, movement), a, b, bezier) in enumerate(
            zip(plan, ins, outs, ctrl, strict=True)):
        junction = hd.junctions[node]
        (centre, left, right), turn, arcs = curves[k], float(turn_speed[k]), None
        if movement == "uturn":
            half_circle = _half_circle(ends.end[i[k]], ends.end_tangent[i[k]],
                                       ends.start[o[k]], a.end_width, b.width)
            if half_circle is not None:
                arcs, centre, left, right, turn = half_circle
                bezier = None
        left, right = _pivoted(left, right)
        lane = Lane(
            id=f"j{node}_{len(junction.connectors)}",
            kind="connector",
            road_class=a.road_class,
            width=a.end_width,
            end_width=b.width,
            speed=round(min(a.speed, b.speed, turn), 2),
            centre=centre,
            left=left,
            right=right,
            junction=node,
            movement=movement,
            bezier=bezier,
            plan=arcs,
            predecessors=[in_id],
            successors=[out_id],
        )
        hd.lanes[lane.id] = lane
        junction.connectors.append(lane.id)
        lanes.append(lane)
    return lanes


def folding_turns(connectors: list[Lane]) -> list[Lane]:
    """The ``connectors`` that turn (not U-turns, which pivot on purpose) more tightly than
    half their width anywhere: the HD map pulls their inner edge in, but a reader that offsets
    the lane from its centre line at constant width sees it fold over."""
    turns = [lane for lane in connectors if lane.bezier is not None and lane.movement != "uturn"]
    if not turns:
        return []
    _, _, curvature = bezier_sample(np.array([lane.bezier for lane in turns]))
    half = np.array([max(lane.width, lane.end_width) / 2.0 for lane in turns])
    return [lane for lane, fold in zip(turns, np.abs(curvature).max(axis=1) * half > 1.0,
                                       strict=True) if fold]


def _half_circle(start: np.ndarray, tangent: np.ndarray, end: np.ndarray, w0: float,
                 w1: float):
    """A U-turn from ``start`` (heading ``tangent``) to ``end`` on its left, heading back: the
    half circle between them, exact in every file (an OpenDRIVE arc), with its centre line,
    boundaries (widths blending from ``w0`` to ``w1``) and speed limit; None where ``end`` does
    not lie to the left. Between the two lanes beside a road's centre line its inner boundary
    is that centre line's end point (:func:`_pivoted`), as a Bezier's never quite was. There
    the arc's radius is held :data:`PIVOT_CLEARANCE` above the lane's half width: an OpenDRIVE
    lane whose inner border lies a rounding error beyond its arc's centre (radius below zero)
    sends esmini's map loader into an endless loop."""
    gap = float(tangent[0] * (end[1] - start[1]) - tangent[1] * (end[0] - start[0]))
    if gap <= 0.0:
        return None
    radius = gap / 2.0
    inner = max(w0, w1) / 2.0
    if abs(radius - inner) < PIVOT_CLEARANCE:  # the lane's inner boundary is the arc's centre
        radius = inner + PIVOT_CLEARANCE
    arc = Piece("arc", 0.0, float(start[0]), float(start[1]),
                math.atan2(float(tangent[1]), float(tangent[0])), math.pi * radius,
                curvature=1.0 / radius)
    centre, tangents = plan_points([arc], start, end)
    share = np.linspace(0.0, 1.0, len(centre))
    half = (w0 + (w1 - w0) * share) / 2.0
    return ([arc], centre, offset_along(centre, tangents, half),
            offset_along(centre, tangents, -half), math.sqrt(LATERAL_ACCEL * radius))


def _pivoted(left: np.ndarray, right: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The boundaries of a connector, the inner one held at its end point where it starts and
    ends at the same point.

    A U-turn between the two lanes beside a road's centre line (at a dead end) starts and ends
    its inner boundary on the same centre line point: any other inner boundary is a loop through
    that point, and the lane's outline (left and right boundary joined) touches itself there,
    an invalid polygon to shapely, CommonRoad and lanelet2 tools, whatever the curve's radius.
    The lane pivots on that point instead: its outline is the fan from it to the outer
    boundary."""
    sides = []
    for side in (left, right):
        if len(side) > 2 and np.hypot(*(side[-1] - side[0])) < PIVOT_GAP:
            side = np.repeat(side[:1], len(side), axis=0)
        sides.append(side)
    return sides[0], sides[1]


def _connector_curves(ctrl: np.ndarray, w0: np.ndarray, w1: np.ndarray):
    """Per connector (centre, left, right) polylines, and its speed limit from its tightest
    curvature; widths blend linearly from ``w0`` to ``w1``.

    Every connector is first sampled densely (``BEZIER_SAMPLES``): that fixes its speed and
    whether a tight bend pulls its inner boundary in. Connectors whose boundaries are plain
    offsets are then resampled with just enough points for their curve
    (``bezier_sample_counts``): a straight one needs two."""
    pts, tangents, curvature = bezier_sample(ctrl)
    n = pts.shape[1]
    half = (w0[:, None] + (w1 - w0)[:, None] * np.linspace(0.0, 1.0, n)) / 2.0
    left_d, right_d = boundary_offsets(curvature, half)
    turn_speed = np.sqrt(LATERAL_ACCEL / np.maximum(np.abs(curvature).max(axis=1), 1e-9))
    counts = bezier_sample_counts(ctrl)
    pulled = ~((left_d == half).all(axis=1) & (right_d == -half).all(axis=1))
    counts[pulled] = n
    curves = [None] * len(ctrl)
    for m in np.unique(counts).tolist():
        rows = np.flatnonzero(counts == m)
        if m == n:  # the dense samples stand
            p, t, left, right = pts[rows], tangents[rows], left_d[rows], right_d[rows]
        else:
            p, t, _ = bezier_sample(ctrl[rows], m)
            left = (w0[rows, None] + (w1 - w0)[rows, None] * np.linspace(0.0, 1.0, m)) / 2.0
            right = -left
        group = zip(p, offset_along(p, t, left), offset_along(p, t, right), strict=True)
        for row, curve in zip(rows.tolist(), group, strict=True):
            curves[row] = curve
    return curves, turn_speed
