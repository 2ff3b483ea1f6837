"""Dead-end streets (issue 35): as many as real towns have, and as unevenly.

Away from the border 5-33 % of a real 2 km tile's road nodes are dead ends (p10-p90, median
15 %, more in sparse towns): cul-de-sacs, streets that stop at a park, a rail line or a river.
The A* reconnection joins the skeleton's dead ends (paper §III-C) and the density fill
(:mod:`.fill`) makes only roads across a block, so our maps sat at 11-13 % whatever the town.
:func:`add_dead_ends` cuts local roads short that the map does not need for its connections:
the road keeps the part from one junction and stops inside the block. The junction it left was
a T, which becomes a bend, so the map trades a T-junction for a dead end and its road-node
count (its density) stays as it was.
"""

from __future__ import annotations

import math

import networkx as nx
import numpy as np
import shapely

from ..metrics import road_node_count
from ..roadgraph import add_road, edge_coords, edge_length
from .bends import smooth_bends, turn_angles
from .chords import substring_coords
from .cleanup import dissolve_degree_two
from .fill import on_cycle
from .junction_angles import meeting_angle

#: the share of road nodes away from the border that are dead ends falls with the density:
#: on 153 real 2 km tiles its median is 0.28 at 20-40 road nodes/km², 0.18 at 40-60, 0.11 at
#: 60-90 and 0.07 at 90-130 (suburbs end in cul-de-sacs, centres do not): median
#: DEAD_END_AT_1 - DEAD_END_PER_LOG * ln(density), drawn per map within DEAD_END_SPREAD of it
#: (the tiles' p10-p90 lie about 0.1 either side) and kept within DEAD_END_LIMITS. A share
#: drawn from 0.05-0.30 at every density left our sparse maps with 0.16 (real 0.28).
DEAD_END_AT_1, DEAD_END_PER_LOG, DEAD_END_SPREAD = 0.824, 0.16, 0.10
DEAD_END_LIMITS = (0.02, 0.35)
#: the share of its road a dead end keeps, from the junction it keeps, drawn per road: real
#: inner dead ends are 30 / 81 / 248 m long (p10 / p50 / p90, 2 km tiles of four regions), a
#: fixed 0.6 of the road made ours 58 / 103 / 185 m
KEPT_SHARES = (0.2, 0.8)
MIN_KEPT = 25.0  # metres: room for the junction it leaves and its own turnaround
#: metres a dead end stops short of the road it was cut from: twice the widest clearance
#: between two roads (``clearance``), as the T it left is gone
END_GAP = 30.0
#: degrees the T's two other roads may turn where they become one road: they join at the
#: T's node, and a bend sharper than a road's may not be roundable there
MAX_JOIN_TURN = 30.0
END_STRAIGHT, END_TURN = 20.0, math.radians(5.0)  # a dead end's last metres turn less


def dead_end_share(density: float, rng: np.random.Generator) -> float:
    """The share of dead ends for a map of ``density`` road nodes/km², drawn around that of
    real towns of that density."""
    median = DEAD_END_AT_1 - DEAD_END_PER_LOG * math.log(max(density, 1.0))
    return float(np.clip(median + rng.uniform(-DEAD_END_SPREAD, DEAD_END_SPREAD),
                         *DEAD_END_LIMITS))


def add_dead_ends(G: nx.Graph, rng: np.random.Generator, margin: float,
                  min_angle: float, density: float, share: float | None = None) -> int:
    """Cut local roads short until a share of the road nodes farther than ``margin`` from the
    map border (:func:`dead_end_share` of ``density``) are dead ends; each road is chosen at
    random among those that are on a cycle (the map stays connected), end in a T-junction
    whose other two roads run on nearly straight (the density stays, and the road they become
    has no sharp bend) and are long enough. ``share``: the share wanted instead (a city's,
    ``like``). Returns how many were cut."""
    drawn = dead_end_share(density, rng)  # drawn either way: the stream stays the same
    share = drawn if share is None else share
    want = round(share * road_node_count(G)) - len(_inner_dead_ends(G, margin))
    edges = sorted((min(u, v), max(u, v)) for u, v in G.edges
                   if G.edges[u, v]["road_class"] == "local"
                   and edge_length(G, u, v) - END_GAP >= MIN_KEPT)
    flips = (rng.random(len(edges)) < 0.5).tolist()  # which junction a road keeps
    shares = rng.uniform(*KEPT_SHARES, len(edges)).tolist()
    roads = [(v, u) if flip else (u, v) for (u, v), flip in zip(edges, flips, strict=True)]
    cut = 0
    for k in rng.permutation(len(roads)).tolist():
        if cut >= want:
            break
        keep, drop = roads[k]
        if not (G.has_edge(keep, drop) and G.degree(keep) >= 3 and G.degree(drop) == 3
                and on_cycle(G, keep, drop)):
            continue
        road = edge_coords(G, keep, drop)
        line = shapely.LineString(road)
        kept = min(max(shares[k] * line.length, MIN_KEPT), line.length - END_GAP)
        part = substring_coords(line, 0.0, kept)
        if turn_angles(substring_coords(line, kept - END_STRAIGHT, kept)).sum() > END_TURN:
            continue  # a dead end in a bend: its corner could not be rounded any more
        if _near_border(G, part[-1], margin):
            continue
        road_class = G.edges[keep, drop]["road_class"]
        G.remove_edge(keep, drop)
        if meeting_angle(G, drop) < math.pi - math.radians(MAX_JOIN_TURN):
            add_road(G, keep, drop, road, road_class)  # the T's other roads would not join
            continue
        end = max(G) + 1
        G.add_node(end, xy=(float(part[-1][0]), float(part[-1][1])))
        add_road(G, keep, end, part, road_class)
        cut += 1
    if cut:
        dissolve_degree_two(G, min_angle)
        smooth_bends(G)
    return cut


def _inner_dead_ends(G: nx.Graph, margin: float) -> list:
    return [n for n, degree in G.degree()
            if degree == 1 and not _near_border(G, G.nodes[n]["xy"], margin)]


def _near_border(G: nx.Graph, xy, margin: float) -> bool:
    x, y = xy
    return min(x, y, G.graph["width"] - x, G.graph["height"] - y) < margin
