"""Bus lines with stops (issue 36, "road users"): buses that cross the map along its main
roads both ways, stopping every few hundred metres, in ``bus_lines.rou.xml`` and
``bus_stops.add.xml``.

A rule regression suite needs the situations a bus makes: a vehicle standing at a stop in
the right lane, cars changing lanes or queueing behind it, a long vehicle turning at
junctions. A line runs between the two ends of the map's main road network farthest apart
(edges of the highest priority, which are the arterials: a real line follows the main
roads), there on the fastest route for buses that turns only at traffic lights where it can
and back on the reverse one; a stop
(``STOP_LENGTH_M`` on the right-most lane buses may use) lies on the first edge of the route
after every ``STOP_SPACING_M`` that is long enough to hold it. Buses leave both terminals
every ``HEADWAY_S`` over the demand's duration and wait ``DWELL_S`` at each stop. Further
lines take the farthest pair of ends ``TERMINALS_APART_M`` from earlier lines' terminals.
"""

from __future__ import annotations

import math
from itertools import combinations
from pathlib import Path

import networkx as nx
import numpy as np
import sumolib
from lxml import etree
from scipy.spatial import ConvexHull

from ..errors import RoadweaverError
from .demand import WAIT_AT_STOP_LINE
from .xmlfile import write_xml

ROUTES_FILE, STOPS_FILE = "bus_lines.rou.xml", "bus_stops.add.xml"
STOP_SPACING_M, STOP_LENGTH_M = 400.0, 20.0
HEADWAY_S, DWELL_S = 600.0, 20.0
TERMINALS_APART_M = 500.0
TURN_PENALTY_S = 300.0
BUS = "bus"


def write_bus_lines(folder: Path, lines: int, duration: float,
                    net_file: str = "map.net.xml", asked: bool = True) -> dict:
    """Write ``lines`` bus lines for the net in ``folder``; return what they hold (lines,
    stops, route length) for the report. Where the map's main roads have room for fewer
    lines, a one-line error if the user ``asked`` for them; else (the default line) the
    lines there is room for, none and no files on a map too small for one (an 800 m map
    may have no two main road ends 500 m apart)."""
    folder = Path(folder)
    net = sumolib.net.readNet(str(folder / net_file))
    graph = _bus_graph(net)
    routes, stops = etree.Element("routes"), etree.Element("additional")
    etree.SubElement(routes, "vType", id=BUS, vClass=BUS, **WAIT_AT_STOP_LINE)
    used: list = []  # the terminals of earlier lines
    length = 0.0
    for line in range(lines):
        there = _line_route(net, graph, used)
        if there is None and not asked:
            lines = line
            break
        if there is None:
            raise RoadweaverError(f"--bus-lines {lines}: the map has main roads for only {line} "
                                  "line(s); ask for fewer")
        back = _bus_route(net, graph, _reverse(there[-1]), _reverse(there[0]))
        for name, edges in ((f"line{line}_there", there), (f"line{line}_back", back or [])):
            if not edges:
                continue
            route = etree.SubElement(routes, "route", id=name,
                                     edges=" ".join(e.getID() for e in edges))
            for stop_id, lane, start in _stops(edges, f"{name}_stop"):
                etree.SubElement(stops, "busStop", id=stop_id, lane=lane,
                                 startPos=f"{start:.2f}", endPos=f"{start + STOP_LENGTH_M:.2f}")
                etree.SubElement(route, "stop", busStop=stop_id, duration=f"{DWELL_S:g}")
            length += sum(e.getLength() for e in edges)
        used += [_middle(there[0]), _middle(there[-1])]
    if not lines:
        return {"lines": 0, "stops": 0, "route_length_m": 0.0}
    for route in routes.findall("route"):
        etree.SubElement(routes, "flow", id=route.get("id"), type=BUS, route=route.get("id"),
                         begin="0", end=f"{duration:g}", period=f"{HEADWAY_S:g}")
    write_xml(routes, folder / ROUTES_FILE)
    write_xml(stops, folder / STOPS_FILE)
    return {"lines": lines, "stops": len(stops), "route_length_m": round(length, 1)}


def _line_route(net, graph: nx.DiGraph, used: list):
    """The fastest bus route between the two main-road edges farthest apart (two-way edges
    of the highest priority; the farthest pair lies on the convex hull of their middles),
    leaving the first towards the second and the second away from the first, at least
    ``TERMINALS_APART_M`` from the terminals ``used`` by earlier lines; None if no such pair
    is connected."""
    ends = sorted((e for e in net.getEdges() if e.allows(BUS) and _reverse(e) is not None
                   and all(math.dist(_middle(e), t) >= TERMINALS_APART_M for t in used)),
                  key=lambda e: e.getID())
    if len(ends) < 2:
        return None
    top = max(e.getPriority() for e in ends)
    ends = [e for e in ends if e.getPriority() == top] if sum(
        e.getPriority() == top for e in ends) >= 2 else ends
    middles = np.array([_middle(e) for e in ends])
    hull = ends if len(ends) < 4 else [ends[k] for k in sorted(ConvexHull(middles).vertices)]
    pairs = sorted(combinations(hull, 2), key=lambda p: (-_distance(*p), p[0].getID(),
                                                         p[1].getID()))
    for a, b in pairs:
        start = min((a, _reverse(a)), key=lambda e: _gap(e.getToNode(), b))
        end = max((b, _reverse(b)), key=lambda e: _gap(e.getToNode(), a))
        path = _bus_route(net, graph, start, end)
        if path and len(path) >= 2:
            return path
    return None


def _bus_route(net, graph: nx.DiGraph, start, end) -> list | None:
    """The quickest route for a bus from edge ``start`` to edge ``end`` on ``graph``
    (:func:`_bus_graph`), or None."""
    try:
        ids = nx.shortest_path(graph, start.getID(), end.getID(), weight="weight")
    except (nx.NetworkXNoPath, nx.NodeNotFound):
        return None
    return [net.getEdge(e) for e in ids]


def _bus_graph(net) -> nx.DiGraph:
    """The edges buses may use, linked where a bus may turn from one into the next, each
    link weighted by the time to drive the next edge plus ``TURN_PENALTY_S`` for a turn off
    the road ahead that no traffic light governs: a 12 m bus waiting inside an unsignalised
    junction to turn left, or sweeping through it, was hit by cars and buses waiting or
    passing there (3 collisions in one of 30 sweep scenarios). Real lines, too, follow the
    main roads and turn at lights."""
    graph = nx.DiGraph()
    for edge in net.getEdges():
        if not edge.allows(BUS):
            continue
        for after, links in edge.getOutgoing().items():
            if not after.allows(BUS) or not any(c.allows(BUS) for c in links):
                continue
            direction = links[0].getDirection()
            signalised = edge.getToNode().getType() == "traffic_light"
            turn = direction not in ("s", "S") and not signalised
            cost = after.getLength() / after.getSpeed() + (TURN_PENALTY_S if turn else 0.0)
            graph.add_edge(edge.getID(), after.getID(), weight=cost)
    return graph


def _stops(edges, prefix: str):
    """(stop id, lane id, start position) of the stops along ``edges``: on the first edge
    long enough after each ``STOP_SPACING_M`` driven, mid-edge, in the right-most lane
    buses may use."""
    travelled, due = 0.0, 0.0
    found = []
    for edge in edges:
        room = edge.getLength() - 2 * STOP_LENGTH_M
        if travelled >= due and room > 0:
            lane = next(lane for lane in edge.getLanes() if lane.allows(BUS))
            start = (edge.getLength() - STOP_LENGTH_M) / 2
            found.append((f"{prefix}{len(found)}", lane.getID(), start))
            due = travelled + STOP_SPACING_M
        travelled += edge.getLength()
    return found


def _reverse(edge):
    """The edge of the same road the other way, or None (a one-way road)."""
    for candidate in edge.getToNode().getOutgoing():
        if candidate.getToNode() is edge.getFromNode() and not candidate.isSpecial():
            return candidate
    return None


def _distance(a, b) -> float:
    (ax, ay), (bx, by) = _middle(a), _middle(b)
    return math.hypot(ax - bx, ay - by)


def _gap(node, edge) -> float:
    (x, y), (ex, ey) = node.getCoord(), _middle(edge)
    return math.hypot(x - ex, y - ey)


def _middle(edge):
    shape = edge.getShape()
    return shape[len(shape) // 2]
