"""Pedestrian crossings and walking areas as SUMO built them, carried back onto the HD map
(issue 36, "one truth"): the crossings' outlines for OpenDRIVE's crosswalk objects, and which
sidewalk and crossing ends each walking area joins, for lanelet2's pedestrian network.

The crossings are asked for in the connection file (``export.sumo_plain.crossings``) but
netconvert places them: it fits each to its junction's shape and the widths of the lanes it
crosses, and joins sidewalks and crossings by walking areas. Reading the result back gives
the other formats the crossings the simulated pedestrians walk on, not a second guess.
"""

from __future__ import annotations

from collections import defaultdict
from pathlib import Path
from typing import NamedTuple

import numpy as np
import shapely
from lxml import etree


class Crosswalk(NamedTuple):
    """A crossing: SUMO's id (``":n12_c0"``), the road it crosses, its centre line (from
    where pedestrians enter it to where they leave, as SUMO's lane runs), its width and its
    outline (corner points, counter-clockwise, not closed)."""

    id: str
    road: int
    centre: np.ndarray
    width: float
    outline: np.ndarray


def read_crossings(net_path: Path) -> tuple[list[Crosswalk], dict[str, list[tuple]]]:
    """Every crossing of ``net_path`` (its lane's centre line widened to its width), and per
    walking area the ends it joins: ``(kind, id, end)`` with kind ``sidewalk`` (a sidewalk
    lane id) or ``crossing``, and end ``start`` or ``end`` of that lane."""
    crossings, areas = [], defaultdict(list)
    for _, element in etree.iterparse(str(net_path), tag=("edge", "connection")):
        if element.tag == "edge" and element.get("function") == "crossing":
            lane = element.find("lane")
            centre = np.array([tuple(map(float, p.split(","))) for p in
                               lane.get("shape").split()])
            width = float(lane.get("width"))
            area = shapely.LineString(centre).buffer(width / 2, cap_style="flat")
            corners = np.asarray(shapely.geometry.polygon.orient(area).exterior.coords)[:-1]
            road = int(element.get("crossingEdges").split()[0][1:].rsplit("_", 1)[0])
            crossings.append(Crosswalk(element.get("id"), road, centre, width, corners))
        elif element.tag == "connection":
            source, target = element.get("from"), element.get("to")
            if "_w" in target and target.startswith(":"):  # into a walking area
                areas[target].append(_port(source, element.get("fromLane"), "end"))
            elif "_w" in source and source.startswith(":"):  # out of a walking area
                areas[source].append(_port(target, element.get("toLane"), "start"))
        element.clear()
    return crossings, {area: sorted(set(ports)) for area, ports in sorted(areas.items())}


def _port(edge: str, lane: str, end: str) -> tuple[str, str, str]:
    if edge.startswith(":"):
        return ("crossing", edge, end)
    return ("sidewalk", f"{edge}_{lane}", end)
