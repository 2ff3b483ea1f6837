"""Left-turn bays on the approaches to traffic lights (issue 36: lanes per class and demand).

At a signalised junction of real towns, left-turners wait in a lane of their own that opens
on the left a few dozen metres before the stop line, so that they do not hold up the traffic
going straight; a regression suite then has the situations bays make: choosing the lane
before the junction, a bay that fills and spills back, left-turners waiting for oncoming
traffic beside moving cars.

A bay is a road of its own in the road graph: the last ``BAY_LENGTH`` metres of the approach
are split off at a two-arm *taper* node, and the driving direction of that piece that arrives
at the light has one lane more than its class (``Road.bay``): the leftmost, which alone turns
left there (``movements.lane_plan``: one left-turn lane, the others straight on). At the taper
node the through lanes move one lane to the right over ``TAPER_LENGTH`` metres (the junction
there is that long), and the bay continues the old leftmost lane: the geometry of a real bay.
Every format sees the same thing: an edge that gains a lane (SUMO), a road whose lane count
changes across a junction (OpenDRIVE), lanelets that fork (lanelet2). Density and the realism
figures count only junctions of degree other than 2, so taper nodes change neither.
"""

from __future__ import annotations

import networkx as nx
import numpy as np
import shapely
from shapely.ops import substring

from .control import junction_control
from .geometry import dedupe, signed_angles
from .movements import SHARP_LEFT_MAX, STRAIGHT_MAX

BAY_LENGTH = 90.0  # m from the signalised junction's centre to the taper node
TAPER_LENGTH = 30.0  # m: the taper junction, over which the through lanes move aside
MIN_LEFT_OVER = 60.0  # m of road left beyond the taper node
BAY_CLASSES = ("arterial", "collector")
HEADING_PROBE = 10.0  # m along a road used to measure its direction at a junction


def add_turn_bays(G: nx.Graph, rules: str, traffic_lights: bool = True) -> nx.Graph:
    """``G`` with a bay road split off every approach to a traffic light that has a left
    turn there, is of a ``BAY_CLASSES`` class and long enough; the bay road's edge carries
    ``bay_to`` (the signalised node) and each taper node ``taper=True``. ``G`` itself is
    returned where no approach gets a bay, else a copy."""
    wanted: dict[tuple[int, int], list[int]] = {}
    for node in sorted(G.nodes):
        arms = sorted(G.edges(node))
        classes = [G.edges[e]["road_class"] for e in arms]
        if junction_control(classes, rules, traffic_lights) != "traffic_light":
            continue
        for (u, v), has_left in zip(arms, _left_turns(G, node, arms), strict=True):
            if has_left and G.edges[u, v]["road_class"] in BAY_CLASSES:
                wanted.setdefault(tuple(sorted((u, v))), []).append(node)
    bays = {edge: ends for edge, ends in wanted.items()
            if _length(G, edge) >= len(ends) * BAY_LENGTH + MIN_LEFT_OVER}
    if not bays:
        return G
    G = G.copy()
    next_node = max(G.nodes) + 1
    for (u, v), ends in sorted(bays.items()):
        data = G.edges[u, v]
        line = shapely.LineString(data["coords"] if data["start"] == u else data["coords"][::-1])
        cuts = [BAY_LENGTH if end == u else line.length - BAY_LENGTH for end in ends]
        stops = sorted(cuts)
        nodes = [u, *range(next_node, next_node + len(stops)), v]
        next_node += len(stops)
        for taper, s in zip(nodes[1:-1], stops, strict=True):
            point = line.interpolate(s)
            G.add_node(taper, xy=(point.x, point.y), taper=True)
        bounds = [0.0, *stops, line.length]
        G.remove_edge(u, v)
        for k in range(len(nodes) - 1):
            a, b = nodes[k], nodes[k + 1]
            piece = dedupe(np.asarray(substring(line, bounds[k], bounds[k + 1]).coords))
            attrs = {"coords": piece, "road_class": data["road_class"], "start": a}
            if a in ends or b in ends:
                attrs["bay_to"] = a if a in ends else b
            G.add_edge(a, b, **attrs)
    return G


def _left_turns(G: nx.Graph, node: int, arms: list[tuple[int, int]]) -> list[bool]:
    """Whether traffic arriving along each of ``arms`` can turn left at ``node``: another arm
    leaves between ``STRAIGHT_MAX`` and ``SHARP_LEFT_MAX`` to the left of its way ahead."""
    leaving = np.array([_leaving(G, node, arm) for arm in arms])
    found = []
    for k, direction in enumerate(leaving):
        angles = signed_angles(-direction, np.delete(leaving, k, axis=0))
        found.append(bool(np.any((angles > STRAIGHT_MAX) & (angles <= SHARP_LEFT_MAX))))
    return found


def _leaving(G: nx.Graph, node: int, arm: tuple[int, int]) -> np.ndarray:
    """Unit direction in which road ``arm`` leaves ``node``."""
    data = G.edges[arm]
    coords = np.asarray(data["coords"] if data["start"] == node else data["coords"][::-1])
    line = shapely.LineString(coords)
    ahead = line.interpolate(min(HEADING_PROBE, line.length / 2))
    step = np.array([ahead.x, ahead.y]) - coords[0]
    return step / np.hypot(*step)


def _length(G: nx.Graph, edge: tuple[int, int]) -> float:
    return float(shapely.LineString(G.edges[edge]["coords"]).length)
