"""Roads that cross or overlap without a junction, as a driver (and every other simulator) sees
them: lanes drawn on top of each other outside any junction area (DESIGN.md "Metrics",
crossings without junction).

Two centrelines can stay apart while the lanes around them overlap, so the check is made on the
lanes' outlines: each lane is its centre line buffered by half its width. Two outlines of
different roads may touch only inside the junction areas at their ends. In a SUMO net those
areas are the junctions' shapes; in the HD map the discs that road lanes are trimmed back to.
"""

from __future__ import annotations

import numpy as np
import shapely
import sumolib

from ..hdmap.model import HDMap
from .netgraph import road_edges

#: Lane outlines are shrunk by this much on each side, so that two lanes that only share a
#: boundary line (the two directions of one road, or neighbours at a junction's rim) do not
#: count; an overlap of less than this is not one a driver would notice either.
SLACK = 0.1  # metres
MIN_AREA = 0.5  # m²: shapely's last-bit slivers between outlines that share a rim
PEDESTRIAN_ONLY = frozenset({"pedestrian"})  # a sidewalk's permissions
RIM = 1.0  # metres beyond an HD map junction's trim radius where lane ends' corners may meet


def net_overlaps(net: sumolib.net.Net) -> list[tuple[str, str]]:
    """Pairs of edges (ids, sorted; the two directions of one road never pair) whose lane
    outlines overlap outside the shapes of the junctions at their ends. Lanes for vehicles
    only: sidewalks of two roads meeting at an acute angle run into each other before the
    junction, as paved corners do (pedestrians walk on either)."""
    outlines, owners = [], []
    for edge in road_edges(net):
        for lane in edge.getLanes():
            if lane.getPermissions() <= PEDESTRIAN_ONLY:
                continue
            outlines.append(_outline(lane.getShape(), lane.getWidth()))
            owners.append(edge)
    junction_area = {node.getID(): _junction_area(node) for node in net.getNodes()}
    pairs: set = set()
    for i, j in _touching(outlines):
        a, b = owners[i], owners[j]
        if a is b or _reverse(a, b) or (a.getID(), b.getID()) in pairs:
            continue
        ends = {a.getFromNode().getID(), a.getToNode().getID(),
                b.getFromNode().getID(), b.getToNode().getID()}
        overlap = outlines[i].intersection(outlines[j])
        overlap = overlap.difference(shapely.union_all([junction_area[n] for n in ends]))
        if overlap.area > MIN_AREA:
            pairs.add(tuple(sorted((a.getID(), b.getID()))))
    return sorted(pairs)


def hdmap_overlaps(hd: HDMap) -> list[tuple[int, int]]:
    """Pairs of roads (ids) whose road lanes overlap outside the junctions they share: in the
    HD map a road lane ends where its junction's disc (the trim radius) begins, and the
    corners of two lanes' ends may meet at its rim, within :data:`RIM` of it."""
    lanes = [lane for lane in hd.lanes.values() if lane.kind == "road"]
    outlines = [_outline(lane.centre, 0.5 * (lane.width + lane.end_width)) for lane in lanes]
    pairs: set = set()
    for i, j in _touching(outlines):
        a, b = hd.roads[lanes[i].road], hd.roads[lanes[j].road]
        if a.id == b.id or (min(a.id, b.id), max(a.id, b.id)) in pairs:
            continue
        overlap = outlines[i].intersection(outlines[j])
        for node in {a.from_node, a.to_node} & {b.from_node, b.to_node}:
            junction = hd.junctions[node]
            overlap = overlap.difference(shapely.Point(junction.xy).buffer(junction.radius + RIM))
        if overlap.area > MIN_AREA:
            pairs.add((min(a.id, b.id), max(a.id, b.id)))
    return sorted(pairs)


def _outline(centre, width: float):
    half = max(0.5 * width - SLACK, 0.05)
    return shapely.LineString(np.asarray(centre, dtype=float)[:, :2]).buffer(
        half, cap_style="flat", quad_segs=4)


def _touching(outlines: list) -> list[tuple[int, int]]:
    """Index pairs (i < j) of outlines that intersect."""
    geoms = np.array(outlines)
    left, right = shapely.STRtree(geoms).query(geoms, predicate="intersects")
    keep = left < right
    return list(zip(left[keep].tolist(), right[keep].tolist(), strict=True))


def _reverse(a, b) -> bool:
    """The two directions of one road (a road graph has one road per pair of junctions)."""
    return a.getFromNode() is b.getToNode() and a.getToNode() is b.getFromNode()


def _junction_area(node):
    shape = node.getShape()
    if len(shape) >= 3:
        polygon = shapely.Polygon([p[:2] for p in shape])
        if not polygon.is_valid:
            polygon = shapely.make_valid(polygon)
        return polygon.buffer(SLACK)
    return shapely.Point(node.getCoord()[:2]).buffer(SLACK)
