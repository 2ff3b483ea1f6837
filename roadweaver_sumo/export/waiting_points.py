"""Waiting points inside junctions that stand in a foe's path, moved back to the stop line.

A car that must yield inside a junction (a left-turner letting oncoming traffic pass) stops at
SUMO's waiting point: the internal junction that netconvert puts where its path meets the
foes'. Where two paths meet at a shallow angle (a left turn off a road that bends through the
junction, or the staggered lane ends of a junction netconvert builds only as wide as its
narrowest road), that point can lie within a metre of a foe lane's centre line, and the
waiting car's front is then in the way of the cars it waits for (junction collisions of the
quality sweeps; ``docs/learned.md``). Such a connection gets ``contPos="0"``: its cars wait at
the stop line instead. Only these few connections: moving every left turn's waiting point
back cost capacity and made left-turners strand at traffic lights.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import shapely
from lxml import etree

#: A waiting point nearer a foe lane's centre line than this blocks it (a car is 1.8 m wide:
#: measured waiting points of sound junctions are 1.3 m or more from their foes' lanes).
MIN_FOE_GAP_M = 1.0


def crowded_connections(net_file: Path, min_gap: float = MIN_FOE_GAP_M) -> list[dict]:
    """``from``/``to``/``fromLane``/``toLane`` of every connection whose waiting point lies
    nearer than ``min_gap`` to a foe's internal lane, in the order of the net file."""
    root = etree.parse(str(net_file)).getroot()
    shapes = {lane.get("id"): lane.get("shape") for lane in root.iter("lane")}
    crowded_vias = set()
    for junction in root.iter("junction"):
        if junction.get("type") != "internal":
            continue
        incoming = junction.get("incLanes", "").split()
        foes = [lane for lane in junction.get("intLanes", "").split()
                if lane not in incoming and lane in shapes]
        if not foes or not incoming:
            continue
        point = shapely.Point(float(junction.get("x")), float(junction.get("y")))
        gap = min(point.distance(_line(shapes[lane])) for lane in foes)
        if gap < min_gap:
            crowded_vias.add(incoming[0])  # the internal lane that leads to the waiting point
    return [{key: c.get(key) for key in ("from", "to", "fromLane", "toLane")}
            for c in root.iter("connection") if c.get("via") in crowded_vias]


def _line(shape: str) -> shapely.LineString:
    return shapely.LineString(np.array([p.split(",") for p in shape.split()], dtype=float))


def wait_at_stop_line(connection_file: Path, connections: list[dict]) -> int:
    """Give the listed connections of a plain ``.con.xml`` ``contPos="0"``; returns how many
    were found."""
    tree = etree.parse(str(connection_file))
    wanted = {tuple(c[k] for k in ("from", "to", "fromLane", "toLane")) for c in connections}
    found = 0
    for c in tree.getroot().iter("connection"):
        if (c.get("from"), c.get("to"), c.get("fromLane"), c.get("toLane")) in wanted:
            c.set("contPos", "0")
            found += 1
    tree.write(str(connection_file), pretty_print=True, xml_declaration=True, encoding="UTF-8")
    return found
