"""Waiting points inside junctions that stand in a foe's path, moved back to the stop line.

A car that must yield inside a junction (a left-turner letting oncoming traffic pass) stops at
SUMO's waiting point: the internal junction that netconvert puts where its path meets the
foes'. Where two paths meet at a shallow angle (a left turn off a road that bends through the
junction, or the staggered lane ends of a junction netconvert builds only as wide as its
narrowest road), that point can lie within a metre of a foe lane's centre line, and the
waiting car's front is then in the way of the cars it waits for (junction collisions in the
quality sweeps, ``bench/quality_sweep.py``). Such a connection gets ``contPos="0"``: its cars wait at
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
    nearer than ``min_gap`` to a foe's internal lane, in the order of the net file. (The
    distances are measured in one shapely call: a 10 km net has ~36,000 foe lanes.)"""
    root = etree.parse(str(net_file)).getroot()
    shapes = {lane.get("id"): lane.get("shape") for lane in root.iter("lane")}
    vias, points, foe_shapes, owner = [], [], [], []
    for junction in root.iter("junction"):
        if junction.get("type") != "internal":
            continue
        incoming = junction.get("incLanes", "").split()
        foes = [shapes[lane] for lane in junction.get("intLanes", "").split()
                if lane not in incoming and lane in shapes]
        if not foes or not incoming:
            continue
        owner += [len(vias)] * len(foes)
        vias.append(incoming[0])  # the internal lane that leads to the waiting point
        points.append((float(junction.get("x")), float(junction.get("y"))))
        foe_shapes += foes
    if not vias:
        return []
    gaps = shapely.distance(shapely.points(np.array(points))[owner], _lines(foe_shapes))
    starts = np.flatnonzero(np.r_[True, np.diff(owner) != 0])
    nearest = np.minimum.reduceat(gaps, starts)
    crowded_vias = {vias[k] for k in np.flatnonzero(nearest < min_gap).tolist()}
    return [{key: c.get(key) for key in ("from", "to", "fromLane", "toLane")}
            for c in root.iter("connection") if c.get("via") in crowded_vias]


def _lines(shapes: list[str]) -> np.ndarray:
    """SUMO ``shape`` strings ("x,y x,y ...") as LineStrings, from one shapely call."""
    counts = [shape.count(" ") + 1 for shape in shapes]
    xy = np.array(" ".join(shapes).replace(",", " ").split(), dtype=float).reshape(-1, 2)
    return shapely.linestrings(xy, indices=np.repeat(np.arange(len(shapes)), counts))


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
