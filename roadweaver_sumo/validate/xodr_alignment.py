"""Endpoint alignment of an OpenDRIVE file, measured from the file alone (DESIGN.md "Metrics":
endpoint alignment error in the ``.xodr``).

This reader shares nothing with the writer: it evaluates the plan view (lines, arcs,
``paramPoly3`` in either ``pRange``; ASAM OpenDRIVE 1.7 chapter "Geometry"), lane offsets and
lane width polynomials (chapter "Lanes") to place the centre of every lane end, then measures
the distance between the two ends of every link: each junction connection's ``laneLink``
(incoming road end to connecting road contact point, chapter "Junctions") and each lane
``predecessor``/``successor`` on a road linked to another road.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from lxml import etree

Poly = tuple[float, float, float, float, float]  # start (s or sOffset), a, b, c, d
GEOMETRY_KINDS = ("line", "spiral", "arc", "poly3", "paramPoly3")


@dataclass
class XodrRoad:
    """What the alignment needs of one ``<road>``: plan view, lane offsets, lane widths per
    lane section, and links (``elementType``, ``elementId``, ``contactPoint``)."""

    id: str
    length: float
    geometries: list[etree._Element]
    offsets: list[Poly]
    sections: list[tuple[float, dict[int, list[Poly]]]]
    links: dict[str, tuple[str, str, str | None]] = field(default_factory=dict)
    lane_links: dict[int, dict[str, list[int]]] = field(default_factory=dict)


def _poly(elem: etree._Element, start: str) -> Poly:
    return (float(elem.get(start)), *(float(elem.get(k)) for k in "abcd"))


def _value(records: list[Poly], x: float) -> float:
    """The polynomial record in force at ``x`` (last one starting at or before it)."""
    rec = records[0]
    for r in records:
        if r[0] <= x + 1e-9:
            rec = r
    d = x - rec[0]
    return rec[1] + rec[2] * d + rec[3] * d * d + rec[4] * d**3


def read_roads(path: Path) -> tuple[dict[str, XodrRoad], etree._Element]:
    """All roads of the file at ``path`` by id, and the document root."""
    root = etree.parse(str(path)).getroot()
    return {r.get("id"): _read_road(r) for r in root.iter("road")}, root


def _read_road(elem: etree._Element) -> XodrRoad:
    geometries = elem.find("planView").findall("geometry")
    road = XodrRoad(
        id=elem.get("id"),
        length=float(elem.get("length")),
        geometries=sorted(geometries, key=lambda g: float(g.get("s"))),
        offsets=[_poly(o, "s") for o in elem.iterfind("lanes/laneOffset")],
        sections=[],
    )
    for tag in ("predecessor", "successor"):
        link = elem.find(f"link/{tag}")
        if link is not None:
            road.links[tag] = (link.get("elementType", "road"), link.get("elementId"),
                               link.get("contactPoint"))
    sections = sorted(elem.iterfind("lanes/laneSection"), key=lambda sec: float(sec.get("s")))
    for section in sections:
        widths = {}
        for lane in section.iterfind("*/lane"):
            lane_id = int(lane.get("id"))
            if lane_id == 0:
                continue
            if lane.find("width") is None:
                raise ValueError(f"road {road.id} lane {lane_id}: only <width> lanes are read")
            widths[lane_id] = [_poly(w, "sOffset") for w in lane.iterfind("width")]
        road.sections.append((float(section.get("s")), widths))
    for tag, section in (("predecessor", sections[0]), ("successor", sections[-1])):
        for lane in section.iterfind("*/lane"):  # links at the road's ends only
            targets = [int(x.get("id")) for x in lane.iterfind(f"link/{tag}")]
            road.lane_links.setdefault(int(lane.get("id")), {})[tag] = targets
    return road


def reference_pose(road: XodrRoad, s: float) -> tuple[float, float, float]:
    """(x, y, heading) of the reference line at ``s``."""
    geometry = road.geometries[0]
    for g in road.geometries:
        if float(g.get("s")) <= s + 1e-9:
            geometry = g
    x0, y0, h0 = (float(geometry.get(k)) for k in ("x", "y", "hdg"))
    ds = s - float(geometry.get("s"))
    kind = next((c for c in geometry if c.tag in GEOMETRY_KINDS), None)
    if kind is None:
        raise ValueError(f"road {road.id}: a <geometry> without a shape")
    if kind.tag == "line" or (kind.tag == "arc" and float(kind.get("curvature")) == 0.0):
        return x0 + ds * math.cos(h0), y0 + ds * math.sin(h0), h0
    if kind.tag == "arc":
        k = float(kind.get("curvature"))
        h = h0 + k * ds
        return x0 + (math.sin(h) - math.sin(h0)) / k, y0 - (math.cos(h) - math.cos(h0)) / k, h
    if kind.tag == "paramPoly3":
        return _param_poly3_pose(kind, x0, y0, h0, ds, float(geometry.get("length")))
    raise ValueError(f"road {road.id}: <{kind.tag}> geometry is not supported")


def _param_poly3_pose(elem, x0: float, y0: float, h0: float, ds: float, length: float):
    """Pose on a ``paramPoly3``: p = ds (``arcLength``) or ds / length (``normalized``)."""
    p = ds / length if elem.get("pRange") == "normalized" else ds
    u = [float(elem.get(f"{c}U")) for c in "abcd"]
    v = [float(elem.get(f"{c}V")) for c in "abcd"]
    pu = u[0] + u[1] * p + u[2] * p * p + u[3] * p**3
    pv = v[0] + v[1] * p + v[2] * p * p + v[3] * p**3
    du = u[1] + 2 * u[2] * p + 3 * u[3] * p * p
    dv = v[1] + 2 * v[2] * p + 3 * v[3] * p * p
    c, s = math.cos(h0), math.sin(h0)
    return x0 + c * pu - s * pv, y0 + s * pu + c * pv, h0 + math.atan2(dv, du)


def lane_centre(road: XodrRoad, lane_id: int, s: float) -> np.ndarray:
    """Centre point of lane ``lane_id`` at ``s``: lane offset plus the widths of the lanes
    between it and the centre lane, plus half its own width, along the left normal."""
    start, widths = road.sections[0]
    for sec in road.sections:
        if sec[0] <= s + 1e-9:
            start, widths = sec
    side = 1 if lane_id > 0 else -1
    ds = s - start
    inner = sum(_value(widths[side * k], ds) for k in range(1, abs(lane_id)))
    t = (_value(road.offsets, s) if road.offsets else 0.0) + side * (
        inner + _value(widths[lane_id], ds) / 2.0)
    x, y, h = reference_pose(road, s)
    return np.array([x - t * math.sin(h), y + t * math.cos(h)])


def _end_s(road: XodrRoad, contact: str) -> float:
    return 0.0 if contact == "start" else road.length


def _junction_end(road: XodrRoad, junction: str, lane_id: int) -> str:
    """Which end of ``road`` touches ``junction``; where both do, the end its lane drives
    into (right lanes drive along the reference line)."""
    ends = [end for tag, end in (("predecessor", "start"), ("successor", "end"))
            if road.links.get(tag, ("", "", None))[:2] == ("junction", junction)]
    if len(ends) == 1:
        return ends[0]
    return "end" if lane_id < 0 else "start"


def linked_lane_ends(roads: dict[str, XodrRoad], root: etree._Element) -> list[tuple]:
    """Every linked pair of lane ends as ((road, lane, "start"|"end"), (road, lane, end)),
    from junction laneLinks and road-to-road lane links, each pair once, sorted."""
    pairs = set()
    for junction in root.iter("junction"):
        for conn in junction.iterfind("connection"):
            incoming, connecting = conn.get("incomingRoad"), conn.get("connectingRoad")
            if incoming is None or connecting is None:
                continue
            for link in conn.iterfind("laneLink"):
                a_lane, b_lane = int(link.get("from")), int(link.get("to"))
                a = (incoming, a_lane, _junction_end(roads[incoming], junction.get("id"), a_lane))
                pairs.add(tuple(sorted([a, (connecting, b_lane, conn.get("contactPoint"))])))
    for road in roads.values():
        for tag, end in (("predecessor", "start"), ("successor", "end")):
            kind, other, contact = road.links.get(tag, ("junction", None, None))
            if kind != "road":
                continue
            for lane_id, links in road.lane_links.items():
                for target in links[tag]:
                    pairs.add(tuple(sorted([(road.id, lane_id, end), (other, target, contact)])))
    return sorted(pairs)


def xodr_alignment(path: Path) -> dict:
    """Distance (m) between the centres of every pair of linked lane ends in the OpenDRIVE
    file at ``path``: ``count``, ``mean``, ``p95``, ``max`` (zeros when nothing is linked)."""
    roads, root = read_roads(path)
    gaps = []
    for (ra, la, ea), (rb, lb, eb) in linked_lane_ends(roads, root):
        pa = lane_centre(roads[ra], la, _end_s(roads[ra], ea))
        pb = lane_centre(roads[rb], lb, _end_s(roads[rb], eb))
        gaps.append(float(np.hypot(*(pa - pb))))
    if not gaps:
        return {"count": 0, "mean": 0.0, "p95": 0.0, "max": 0.0}
    g = np.asarray(gaps)
    return {"count": int(g.size), "mean": float(g.mean()), "p95": float(np.percentile(g, 95)),
            "max": float(g.max())}
