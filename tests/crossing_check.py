"""An independent check for roads that cross or overlap without a junction in a SUMO net.

It shares no code with the generator or with ``roadweaver_sumo.validate.overlaps``: it reads
``map.net.xml`` with sumolib and asks, for every pair of road edges, whether their centrelines
(or their lanes' outlines) meet outside the shapes of the junctions at their ends. Used by
``tests/test_crossings.py`` and ``bench/crossings.py``.
"""

from __future__ import annotations

import shapely
import sumolib

JUNCTION_MARGIN = 0.5  # metres around a junction shape that still count as the junction


def crossings(net_path, lanes: bool = False) -> list[tuple[str, str]]:
    """Edge id pairs whose centrelines (``lanes=False``) or lane outlines (``lanes=True``)
    intersect outside the junction areas of their end nodes; the two directions of one road
    (same end nodes, reversed) are not compared with each other."""
    net = sumolib.net.readNet(str(net_path))
    edges = [e for e in net.getEdges() if e.getFunction() == ""]
    geoms, owners = [], []
    for e in edges:
        if lanes:
            for lane in e.getLanes():
                geoms.append(shapely.LineString(lane.getShape()).buffer(
                    lane.getWidth() / 2 - 0.2, cap_style="flat"))
                owners.append(e)
        else:
            geoms.append(shapely.LineString(e.getShape()))
            owners.append(e)
    area = {}
    for node in net.getNodes():
        shape = node.getShape()
        zone = shapely.Polygon(shape) if len(shape) >= 3 else shapely.Point(node.getCoord())
        area[node.getID()] = shapely.make_valid(zone).buffer(JUNCTION_MARGIN + (0 if len(shape) >= 3 else 1.0))
    tree = shapely.STRtree(geoms)
    found = set()
    for i, j in zip(*tree.query(geoms, predicate="intersects")):
        a, b = owners[i], owners[j]
        if i >= j or a is b:
            continue
        ends_a = (a.getFromNode().getID(), a.getToNode().getID())
        ends_b = (b.getFromNode().getID(), b.getToNode().getID())
        if ends_a == ends_b[::-1]:
            continue
        contact = geoms[i].intersection(geoms[j])
        for n in {*ends_a, *ends_b}:
            contact = contact.difference(area[n])
        if not contact.is_empty and (contact.area > 0.5 if lanes else True):
            found.add(tuple(sorted((a.getID(), b.getID()))))
    return sorted(found)
