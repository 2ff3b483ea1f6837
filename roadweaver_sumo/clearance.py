"""Roads keep the clearance their lanes need: no two roads closer than their half widths.

A planar graph can still hide roads that a driver sees overlap: two centrelines 2 m apart never
cross, yet the lanes around them lie on top of each other, and SUMO, OpenDRIVE and lanelet2
readers then see lanes that cross without a junction (issue 33). So the clean-up treats a road
that runs inside another road's clearance, away from the junctions they share, like one that
meets another at too sharp an angle (paper §III-C, clean-up): the road less worth keeping goes,
and the density control places local roads elsewhere.

The clearance of two roads is the sum of their half widths (lanes x lane width of their class,
``hdmap.lanes.LANE_CONFIGS``, a lane more on a turn bay's road: ``hdmap.turn_bays``), a sidewalk
on each road's side of the gap (``hdmap.lanes.SIDEWALK_WIDTH``) and :data:`MARGIN`. The
sidewalks count whether or not the map draws them: asking for ``--sidewalks`` must not move a
road, and a map without them keeps the verge real streets have. The expansion's clean-up keeps
roads apart by it, and the turn bays are only added where their wider roads keep it too. Near a
junction two roads are close by nature: within :data:`JUNCTION_REACH` clearances of a junction
node of either road they may come closer (the junction's shape covers that ground in every
export); beyond it they may not, and two roads that leave a junction side by side and stay so
are an overlap.
"""

from __future__ import annotations

import networkx as nx
import numpy as np
import shapely

from .hdmap.lanes import LANE_CONFIGS, SIDEWALK_WIDTH, lanes_of
from .roadgraph import sorted_edge_list

MARGIN = 1.0  # metres of open ground between the outer edges of two roads' sidewalks
ROADSIDES = 2 * SIDEWALK_WIDTH  # the two roads' sidewalks facing each other
MIN_CONTACT = 0.5  # metres: shorter contacts are numerical touches at a junction's rim
#: Two roads that leave a junction at the clean-up's least angle (30°) are a clearance apart
#: 1.93 clearances out: a junction's area reaches twice the clearance of the roads compared.
JUNCTION_REACH = 2.0


def half_width(road_class: str) -> float:
    """Metres from a road's centreline to the outer edge of its lanes."""
    return LANE_CONFIGS[road_class].half_width


def clearance(class_a: str, class_b: str) -> float:
    """Least distance in metres between the centrelines of two roads of these classes."""
    return half_width(class_a) + half_width(class_b) + ROADSIDES + MARGIN


def roads_too_close(G: nx.Graph, among: set | None = None) -> list[tuple[tuple, tuple]]:
    """Pairs of roads (edges, each sorted) that come within their clearance of each other
    outside the junction areas near them (:func:`_outside_junctions`); with ``among`` (sorted
    edges), only the pairs with one of those roads. A bend node (degree 2) of one road is no
    junction of the other, nor is a dead end: a dead end whose last metres lie on another
    road is exactly such an overlap.

    All pairs are measured at once (shapely's array functions): the pairs whose free parts
    (outside the discs) stay a clearance apart go first, the rest are confirmed by the
    length of road inside the other's clearance."""
    roads = sorted_edge_list(G)
    if len(roads) < 2:
        return []
    edges = [(u, v) if u <= v else (v, u) for u, v, _ in roads]
    lines = np.array([shapely.LineString(data["coords"]) for _, _, data in roads])
    half = np.array([_half_width(data) for _, _, data in roads])
    widest = 2 * half.max() + ROADSIDES + MARGIN
    asked = np.arange(len(edges)) if among is None else np.flatnonzero(
        [edge in among for edge in edges])
    i, j = shapely.STRtree(lines).query(lines[asked], predicate="dwithin", distance=widest)
    i, j = np.unique(np.sort([asked[i], j], axis=0), axis=1)
    i, j = i[i < j], j[i < j]
    reach = half[i] + half[j] + ROADSIDES + MARGIN
    near = shapely.distance(lines[i], lines[j]) < reach
    i, j, reach = i[near], j[near], reach[near]
    on_lanes = _dead_end_on_lanes(G, edges, i, j, half, lines)
    free_i, free_j = _outside_junctions(G, edges, i, j, reach, lines)
    near = (shapely.distance(free_i, lines[j]) < reach) | (shapely.distance(free_j, lines[i]) < reach)
    pairs = [(edges[a], edges[b]) for a, b in zip(i[on_lanes].tolist(), j[on_lanes].tolist(),
                                                    strict=True)]
    near &= ~on_lanes
    for a, b, r, fa, fb in zip(i[near].tolist(), j[near].tolist(), reach[near].tolist(),
                               free_i[near], free_j[near], strict=True):
        inside = max(fa.intersection(lines[b].buffer(r, quad_segs=4)).length,
                     fb.intersection(lines[a].buffer(r, quad_segs=4)).length)
        if inside >= MIN_CONTACT:
            pairs.append((edges[a], edges[b]))
    return pairs


def _dead_end_on_lanes(G: nx.Graph, edges: list[tuple], i: np.ndarray, j: np.ndarray,
                       half: np.ndarray, lines: np.ndarray) -> np.ndarray:
    """Per pair of roads (``edges[i]``, ``edges[j]``, half widths ``half``), whether a dead end
    of either lies so close to the other road that their lanes meet there. No junction shape
    covers a dead end, so this is an overlap even within a junction area of
    :func:`_outside_junctions`: a road cut off by the map edge 20 m from the junction where it
    leaves a three-lane arterial at 33 degrees ran on the arterial's lanes all its length
    (learned grid, density 20, seed 8: SUMO's junction there could not cover it)."""
    touch = half[i] + half[j] + MARGIN
    hit = np.zeros(len(i), dtype=bool)
    for a, b in ((i, j), (j, i)):
        for side in range(2):
            ends = [edges[k][side] for k in a.tolist()]
            dead = np.array([G.degree(n) == 1 for n in ends], dtype=bool)
            if dead.any():
                points = shapely.points([G.nodes[n]["xy"] for n, d in zip(ends, dead) if d])
                hit[dead] |= shapely.distance(points, lines[b[dead]]) < touch[dead]
    return hit


def crowded(G: nx.Graph, made: dict) -> set:
    """What made the roads that come within another road's clearance (``made``: sorted edge
    -> what made that road, a turn bay or a roundabout): the makings to leave out before
    trying again without them."""
    return {made[e] for pair in roads_too_close(G, among=set(made)) for e in pair if e in made}


def _half_width(data: dict) -> float:
    """Metres from a road's centreline to the outer edge of its lanes on its wider side."""
    return LANE_CONFIGS[data["road_class"]].width * (lanes_of(data) + ("bay_to" in data))


def _outside_junctions(G: nx.Graph, edges: list[tuple], i: np.ndarray, j: np.ndarray,
                       reach: np.ndarray, lines: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per pair of roads (``edges[i]``, ``edges[j]``, clearance ``reach``) both roads less the
    ground around junctions where they may come close: :data:`JUNCTION_REACH` clearances
    around the nodes they share (but dead ends), where they leave a junction side by side,
    and one clearance around the other intersections of either (a road's own junction is no
    licence for a passing road to run close to it beyond that). A pair has at most four
    such nodes: the discs are cut away slot by slot, all pairs at once."""
    crossing = [{n for n in e if G.degree(n) >= 3} for e in edges]
    centre = np.full((len(i), 4, 2), np.nan)
    radius = np.zeros((len(i), 4))
    for k, (a, b, r) in enumerate(zip(i.tolist(), j.tolist(), reach.tolist(), strict=True)):
        shared = {n for n in set(edges[a]) & set(edges[b]) if G.degree(n) >= 2}
        discs = [(n, JUNCTION_REACH * r) for n in sorted(shared)]
        discs += [(n, r) for n in sorted((crossing[a] | crossing[b]) - shared)]
        for slot, (n, size) in enumerate(discs):
            centre[k, slot], radius[k, slot] = G.nodes[n]["xy"], size
    free_i, free_j = lines[i].copy(), lines[j].copy()
    for slot in range(4):
        has = ~np.isnan(centre[:, slot, 0])
        disc = shapely.buffer(shapely.points(centre[has, slot]), radius[has, slot], quad_segs=4)
        free_i[has] = shapely.difference(free_i[has], disc)
        free_j[has] = shapely.difference(free_j[has], disc)
    return free_i, free_j
