"""Pedestrian crossings as SUMO built them, carried back onto the HD map (issue 36, "one
truth"): their outlines, for OpenDRIVE's crosswalk objects.

The crossings are asked for in the connection file (``export.sumo_plain.crossings``) but
netconvert places them: it fits each to its junction's shape and the widths of the lanes it
crosses. Reading the result back gives OpenDRIVE the crossings the simulated pedestrians
walk on, not a second guess of where they lie.
"""

from __future__ import annotations

from pathlib import Path
from typing import NamedTuple

import numpy as np
import shapely
from lxml import etree


class Crosswalk(NamedTuple):
    """A crossing: SUMO's id (``":n12_c0"``), the road it crosses and its outline (corner
    points, counter-clockwise, not closed)."""

    id: str
    road: int
    outline: np.ndarray


def read_crossings(net_path: Path) -> list[Crosswalk]:
    """Every crossing of ``net_path``: its lane's centre line widened to its width."""
    found = []
    for _, edge in etree.iterparse(str(net_path), tag="edge"):
        if edge.get("function") == "crossing":
            lane = edge.find("lane")
            centre = [tuple(map(float, p.split(","))) for p in lane.get("shape").split()]
            area = shapely.LineString(centre).buffer(float(lane.get("width")) / 2,
                                                     cap_style="flat")
            corners = np.asarray(shapely.geometry.polygon.orient(area).exterior.coords)[:-1]
            road = int(edge.get("crossingEdges").split()[0][1:].rsplit("_", 1)[0])
            found.append(Crosswalk(edge.get("id"), road, corners))
        edge.clear()
    return found
