"""Left-turn bays on the approaches to traffic lights (issue 36: lanes per class and demand).

At a signalised junction of real towns, left-turners wait in a lane of their own that opens
on the left a few dozen metres before the stop line, so that they do not hold up the traffic
going straight; a regression suite then has the situations bays make: choosing the lane
before the junction, a bay that fills and spills back, left-turners waiting for oncoming
traffic beside moving cars.

A bay is a road of its own in the road graph: the last ``BAY_LENGTH`` metres of the approach
(more where the light's junction is wide, as where arms meet at acute angles: a junction trim
takes at most ``lanes.MAX_TRIM_SHARE`` of a road, and the bay road must leave it all) are split
off at a two-arm *taper* node, and the driving direction of that piece that arrives
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

from .. import clearance  # a module: clearance imports hdmap.lanes, which loads this package
from .control import ControlPlan
from .geometry import dedupe, end_directions, signed_angles
from .junctions import CORNER_RADIUS, HEADING_PROBE, junction_trims
from .lanes import LANE_CONFIGS, MAX_TRIM_SHARE, SIDEWALK_WIDTH, lanes_of
from .movements import SHARP_LEFT_MAX, STRAIGHT_MAX

BAY_LENGTH = 90.0  # m from the signalised junction's centre to the taper node
TAPER_LENGTH = 30.0  # m: the taper junction, over which the through lanes move aside
MIN_LEFT_OVER = 60.0  # m of road left beyond the taper node
BAY_CLASSES = ("arterial", "collector")
#: a junction grows by up to this factor where a turn would fold (``build.WIDEN_FACTOR`` ** 2)
GROWTH_ROOM = 1.6


def add_turn_bays(G: nx.Graph, plan: ControlPlan) -> nx.Graph:
    """``G`` with a bay road split off every approach to a traffic light that has a left
    turn there, is of a ``BAY_CLASSES`` class and long enough; the bay road's edge carries
    ``bay_to`` (the signalised node) and each taper node ``taper=True``. A bay whose wider
    road would come within another road's clearance (``clearance.crowded``) is left
    out. ``G`` itself is returned where no approach gets a bay, else a copy."""
    wanted: dict[tuple[int, int], dict[int, float]] = {}  # edge -> {light: bay length}
    for node in sorted(G.nodes):
        arms = sorted(G.edges(node))
        classes = [G.edges[e]["road_class"] for e in arms]
        if plan.control(node, classes) != "traffic_light":
            continue
        leaving = np.array([_leaving(G, node, arm) for arm in arms])
        bayed = [has_left and cls in BAY_CLASSES
                 for has_left, cls in zip(_left_turns(leaving), classes, strict=True)]
        length = _bay_length(leaving, classes, [lanes_of(G.edges[e]) for e in arms], bayed)
        for (u, v), bay in zip(arms, bayed, strict=True):
            if bay:
                wanted.setdefault(tuple(sorted((u, v))), {})[node] = length
    bays = {edge: ends for edge, ends in wanted.items()
            if _length(G, edge) >= sum(ends.values()) + MIN_LEFT_OVER}
    while bays:  # leave out the bays whose wider road comes too close to another road
        split, bay_of = _split(G, bays)
        crowded = clearance.crowded(split, bay_of)
        if not crowded:
            return split
        bays = {edge: ends for edge, ends in bays.items() if edge not in crowded}
    return G


def _split(G: nx.Graph, bays: dict[tuple[int, int], dict[int, float]]):
    """A copy of ``G`` with each edge of ``bays`` split at a taper node the bay length
    before each light it leads to; returns it and, per bay road (sorted edge), its edge in
    ``G``."""
    G = G.copy()
    bay_of = {}
    next_node = max(G.nodes) + 1
    for (u, v), ends in sorted(bays.items()):
        data = G.edges[u, v]
        line = shapely.LineString(data["coords"] if data["start"] == u else data["coords"][::-1])
        cuts = [s if end == u else line.length - s for end, s in ends.items()]
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
            attrs = {**data, "coords": piece, "start": a}
            if a in ends or b in ends:
                attrs["bay_to"] = a if a in ends else b
                bay_of[(min(a, b), max(a, b))] = (u, v)
            G.add_edge(a, b, **attrs)
    return G, bay_of


def _bay_length(leaving: np.ndarray, classes: list[str], lanes: list[int],
                bayed: list[bool]) -> float:
    """How long the bay roads of one light's junction are: ``BAY_LENGTH``, or long enough
    that their trim at the junction (its radius with the bays' extra lanes, and room to grow)
    stays within ``MAX_TRIM_SHARE`` of them), its corners rounded as if the roads had
    sidewalks: long enough either way."""
    lane_widths = np.array([LANE_CONFIGS[c].width for c in classes])
    widths = lane_widths * (np.array(lanes) + np.array(bayed))
    radius = junction_trims(leaving, widths, lane_widths, [len(classes)],
                            widths + SIDEWALK_WIDTH, [CORNER_RADIUS]).max()
    return max(BAY_LENGTH, GROWTH_ROOM * radius / MAX_TRIM_SHARE)


def _left_turns(leaving: np.ndarray) -> list[bool]:
    """Whether traffic arriving along each arm of a junction (``leaving``: the unit directions
    in which they leave it) can turn left: another arm leaves between ``STRAIGHT_MAX`` and
    ``SHARP_LEFT_MAX`` to the left of its way ahead."""
    found = []
    for k, direction in enumerate(leaving):
        angles = signed_angles(-direction, np.delete(leaving, k, axis=0))
        found.append(bool(np.any((angles > STRAIGHT_MAX) & (angles <= SHARP_LEFT_MAX))))
    return found


def _leaving(G: nx.Graph, node: int, arm: tuple[int, int]) -> np.ndarray:
    """Unit direction in which road ``arm`` leaves ``node``, measured as the junctions do."""
    data = G.edges[arm]
    coords = data["coords"] if data["start"] == node else data["coords"][::-1]
    return end_directions([coords], HEADING_PROBE)[0]


def _length(G: nx.Graph, edge: tuple[int, int]) -> float:
    return float(shapely.LineString(G.edges[edge]["coords"]).length)
