"""Roads keep the clearance their lanes need: no two roads closer than their half widths.

A planar graph can still hide roads that a driver sees overlap: two centrelines 2 m apart never
cross, yet the lanes around them lie on top of each other, and SUMO, OpenDRIVE and lanelet2
readers then see lanes that cross without a junction (issue 33). So the clean-up treats a road
that runs inside another road's clearance, away from the junctions they share, like one that
meets another at too sharp an angle (paper §III-C, clean-up): the road less worth keeping goes,
and the density control places local roads elsewhere.

The clearance of two roads is the sum of their half widths (lanes x lane width of their class,
``hdmap.lanes.LANE_CONFIGS``) plus :data:`MARGIN`. Near a junction two roads are close by
nature: within :data:`JUNCTION_REACH` clearances of a junction node of either road they may
come closer (the junction's shape covers that ground in every export); beyond it they may not,
and two roads that leave a junction side by side and stay so are an overlap.
"""

from __future__ import annotations

import networkx as nx
import numpy as np
import shapely

from ..hdmap.lanes import LANE_CONFIGS
from ..roadgraph import sorted_edge_list

MARGIN = 1.0  # metres of open ground between the outer edges of two roads' lanes
MIN_CONTACT = 0.5  # metres: shorter contacts are numerical touches at a junction's rim
#: Two roads that leave a junction at the clean-up's least angle (30°) are a clearance apart
#: 1.93 clearances out: a junction's area reaches twice the clearance of the roads compared.
JUNCTION_REACH = 2.0


def clearance(class_a: str, class_b: str) -> float:
    """Least distance in metres between the centrelines of two roads of these classes."""
    return LANE_CONFIGS[class_a].half_width + LANE_CONFIGS[class_b].half_width + MARGIN


def roads_too_close(G: nx.Graph) -> list[tuple[tuple, tuple]]:
    """Pairs of roads (edges, each sorted) that come within their clearance of each other
    anywhere but on the way into a junction: the overlaps a driver would see."""
    roads = sorted_edge_list(G)
    if len(roads) < 2:
        return []
    edges = [(u, v) for u, v, _ in roads]
    classes = [data["road_class"] for _, _, data in roads]
    lines = np.array([shapely.LineString(data["coords"]) for _, _, data in roads])
    widest = 2 * max(cfg.half_width for cfg in LANE_CONFIGS.values()) + MARGIN
    left, right = shapely.STRtree(lines).query(lines, predicate="dwithin", distance=widest)
    pairs = []
    for i, j in zip(left.tolist(), right.tolist(), strict=True):
        if i >= j:
            continue
        reach = clearance(classes[i], classes[j])
        if shapely.distance(lines[i], lines[j]) >= reach:
            continue
        if _overlap_away_from_junctions(G, edges[i], lines[i], edges[j], lines[j], reach):
            pairs.append((edges[i], edges[j]))
    return pairs


def _overlap_away_from_junctions(G: nx.Graph, a: tuple, line_a, b: tuple, line_b,
                                 reach: float) -> bool:
    """Whether a stretch of one road lies within ``reach`` of the other outside the junction
    areas of both roads' junction nodes (degree >= 2): discs of :data:`JUNCTION_REACH` times
    ``reach``. A dead end is no junction: a dead end whose last metres lie on another road is
    exactly such an overlap."""
    junctions = shapely.MultiPoint([G.nodes[n]["xy"] for n in {*a, *b} if G.degree(n) >= 2])
    area = junctions.buffer(JUNCTION_REACH * reach, quad_segs=4)
    for line, other in ((line_a, line_b), (line_b, line_a)):
        contact = line.intersection(other.buffer(reach, quad_segs=4)).difference(area)
        if any(piece.length >= MIN_CONTACT for piece in shapely.get_parts(contact)):
            return True
    return False
