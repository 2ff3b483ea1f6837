"""HD map to ASAM OpenDRIVE 1.7 (``map.xodr``), written from the HD map's lane graph only.

* Every HD map road becomes a ``<road>`` (same id, name ``r<id>``) whose reference line is the
  HD map's reference line, lines and arcs (``hdmap.reference``), written as they are;
  ``f`` lanes are right lanes ``-1..-n``, ``b`` lanes left lanes ``1..n`` (HD map index 0, the
  outermost lane, is ``-n`` / ``n``). Both ends link to junctions (chapter "Road linkage").
* Every connector lane becomes a one-lane connecting road (ids after the roads, name = the
  connector id) whose reference line is the connector's Bezier as an exact ``paramPoly3``
  (a U-turn: its half circle, an ``arc``);
  a ``laneOffset`` of half the (linearly changing) width centres lane ``-1`` on it.
* Junction ids have a range of their own: junction of node ``n`` (name ``n<n>``) has id
  ``base + n``, ``base`` one past the highest road or connecting road id. Readers such as
  CARLA decide whether a road lies in a junction by looking its ``junction`` attribute up
  among *road* ids; with shared numbers, lanes that end at a junction get no successor there.
* Road ``<type>`` is ``town`` (the OpenDRIVE 1.4 set, which every reader knows: older ones,
  such as opendrive2lanelet, reject the 1.7 ``townArterial``...); the HD map road class is
  kept in a ``<userData code="roadClass">`` of that type.
* Every junction gets one ``<connection>`` per connecting road, ``contactPoint="start"`` and
  one ``laneLink`` (chapter "Junctions", rule junctions.connection.one_connection_element);
  connecting roads carry road- and lane-level predecessor and successor links. Lanes of roads
  that end in junctions carry no ``<link>`` (rule road.lane.link.no_link): their links are the
  junction's laneLinks and the connecting roads' lane links.
* Right of way as SUMO decided it (``hdmap.right_of_way``): a traffic light, stop or yield
  sign per approach that has one, a ``<controller>`` per traffic light, and junction
  ``<priority>`` records (which connecting road yields to which), so that a reader that knows
  no signs still knows who goes first. Without SUMO's decision (an HD map not yet through
  netconvert) none of these are written.

Output is deterministic: sorted ids, fixed decimals, fixed header date.
"""

from __future__ import annotations

import itertools
from collections import defaultdict
from collections.abc import Iterator
from functools import cache
from pathlib import Path
from xml.sax.saxutils import escape

import numpy as np

from ..hdmap.model import HDMap, Lane, Road, edge_id
from ..hdmap.reference import Piece
from ..hdmap.right_of_way import approach_control, approaches
from ..projection import tmerc
from .opendrive_geometry import DECIMALS, bezier_pieces

CURVATURE_DECIMALS = 15  # an arc's end moves by length^2 / 2 times the curvature's rounding
INDENT = "  "  # the indent of the written file
DATE = "2025-01-01T00:00:00"  # fixed, so that two runs write the same bytes
ROAD_TYPE = "town"  # OpenDRIVE 1.4 road type: known to every reader (see the module docstring)
MARK_WIDTH = 0.12  # m
SIGNAL_SETBACK = 1.0  # m before the road end
QUOTE = {'"': "&quot;"}  # escaped in attribute values besides &, <, >
SIGNAL_COUNTRY = "DE"  # StVO sign codes: the catalogue CARLA's landmarks and esmini know
SIGNAL_TYPES = {"traffic_light": "1000001", "stop": "206", "all_way_stop": "206",
                "yield": "205"}


def write_opendrive(hd: HDMap, path: Path) -> Path:
    """Write ``hd`` as OpenDRIVE 1.7 to ``path`` (parent folders created); return the path.

    Written as text lines, element by element (:func:`opendrive_lines`), never the whole
    document at once: a large map's file runs to hundreds of megabytes. The elements are flat
    records of numbers and ids, so plain formatting writes them as an XML library would
    (two-space indent, empty elements closed with ``/>``), several times faster than building
    an element tree first."""
    lines = opendrive_lines(hd)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("w", encoding="utf-8", newline="\n") as file:
        file.write("<?xml version='1.0' encoding='UTF-8'?>\n<OpenDRIVE>\n")
        for chunk in lines:
            file.write("\n".join(chunk))
            file.write("\n")
        file.write("</OpenDRIVE>\n")
    return path


def opendrive_lines(hd: HDMap) -> Iterator[list[str]]:
    """The children of ``<OpenDRIVE>`` of ``hd`` as lists of lines: header, roads, connecting
    roads, controllers, junctions, in that (schema) order.

    Ids, traffic lights and connector geometry are worked out at once, so that errors come
    before the file is opened; each road and junction is formatted only when its turn
    comes."""
    connecting = connecting_road_ids(hd)
    junctions = junction_ids(hd)
    signals, controllers = _signals(hd)
    crosswalks = defaultdict(list)
    for crosswalk in hd.crosswalks:
        crosswalks[crosswalk.road].append(crosswalk)
    connectors = hd.connectors()
    return itertools.chain(
        [_header(hd)],
        (_road(hd, hd.roads[rid], signals.get(rid, []), junctions, crosswalks.get(rid, []))
         for rid in sorted(hd.roads)),
        (_connecting_road(hd, lane, piece, connecting[lane.id], junctions[lane.junction])
         for lane, piece in zip(connectors, _connector_pieces(connectors), strict=True)),
        controllers,
        (_junction(hd, jid, junctions[jid], connecting)
         for jid in sorted(hd.junctions) if hd.junctions[jid].connectors))


def connecting_road_ids(hd: HDMap) -> dict[str, int]:
    """OpenDRIVE road id of each connector lane: numbered after the roads, junction order."""
    first = max(hd.roads, default=-1) + 1
    return {lane.id: first + k for k, lane in enumerate(hd.connectors())}


def junction_ids(hd: HDMap) -> dict[int, int]:
    """OpenDRIVE junction id of each HD map junction (node): the node id plus one past the
    highest road or connecting road id, so that no junction id is also a road id."""
    base = max(hd.roads, default=-1) + 1 + len(hd.connectors())
    return {node: base + node for node in hd.junctions}


def xodr_lane_id(hd: HDMap, lane: Lane) -> int:
    """OpenDRIVE lane id: ``f`` lanes right (``-1`` innermost), ``b`` lanes left (``1``
    innermost), a sidewalk outermost; a connector is lane ``-1`` of its connecting road."""
    if lane.kind == "connector":
        return -1
    road = hd.roads[lane.road]
    inner_rank = len(road.lanes(lane.direction)) + bool(road.sidewalk_width) - lane.index
    return -inner_rank if lane.direction == "f" else inner_rank


def _num(x: float, decimals: int = DECIMALS) -> str:
    """Fixed-decimal formatting, without ``-0``."""
    text = f"{x:.{decimals}f}"
    return text[1:] if text[0] == "-" and not text.strip("-0.") else text



def _attributes(attrs: dict) -> str:
    """`` key="value"`` for each attribute: floats with fixed decimals, text escaped as an XML
    writer escapes attribute values, ids and counts as they are."""
    return "".join(f' {key}="{_text(value)}"' for key, value in attrs.items())


def _text(value) -> str:
    if isinstance(value, float):
        return _num(value)
    if isinstance(value, str):
        return escape(value, QUOTE)
    return str(value)


def _element(depth: int, tag: str, attrs: dict, children: list[str] = ()) -> list[str]:
    """The lines of ``<tag ...>`` at ``depth`` (indent levels) around the lines of its
    ``children`` (already indented one level deeper), or ``<tag .../>`` without children."""
    opening = f"{INDENT * depth}<{tag}{_attributes(attrs)}"
    if not children:
        return [opening + "/>"]
    return [opening + ">", *children, f"{INDENT * depth}</{tag}>"]


def _header(hd: HDMap) -> list[str]:
    """``<header>`` with the map extent and a transverse Mercator geo-reference centred on
    the local origin (chapter "Georeferencing": PROJ string)."""
    reference = []
    if hd.geo_origin is not None:
        proj = f"{tmerc(hd.geo_origin)} +no_defs"
        reference = [f"{INDENT * 2}<geoReference><![CDATA[{proj}]]></geoReference>"]
    return _element(1, "header", {"revMajor": 1, "revMinor": 7, "name": "roadweaver-sumo",
                                  "version": "1.0", "date": DATE, "north": float(hd.height),
                                  "south": 0.0, "east": float(hd.width), "west": 0.0,
                                  "vendor": "roadweaver-sumo"}, reference)


def _road_attributes(rid: int, name: str, junction: int, pieces: list[Piece]) -> dict:
    """A ``<road>``'s attributes: as long as its plan view, right-hand traffic."""
    return {"id": rid, "name": name, "junction": junction,
            "length": float(sum(p.length for p in pieces)), "rule": "RHT"}


def _plan_view(pieces: list[Piece]) -> list[str]:
    """``<planView>``: one ``<geometry>`` per piece (chapter "Geometry"), a line, an arc or
    a normalised ``paramPoly3``."""
    lines = []
    for p in pieces:
        if p.kind == "line":
            shape = _element(4, "line", {})
        elif p.kind == "arc":
            shape = _element(4, "arc", {"curvature": _num(p.curvature, CURVATURE_DECIMALS)})
        else:
            coefficients = {f"{c}{axis}": value for axis, values in (("U", p.u), ("V", p.v))
                            for c, value in zip("abcd", values, strict=True)}
            shape = _element(4, "paramPoly3", coefficients | {"pRange": "normalized"})
        lines += _element(3, "geometry", {"s": p.s, "x": p.x, "y": p.y, "hdg": p.hdg,
                                          "length": p.length}, shape)
    return _element(2, "planView", {}, lines)


def _road(hd: HDMap, road: Road, signals: list, junctions: dict[int, int],
          crosswalks: list = ()) -> list[str]:
    """A road between two junctions (their ids ``junctions``): its two driving directions as
    right and left lanes, the crosswalks over it, its signals."""
    ends = [(tag, node) for tag, node in (("predecessor", road.from_node),
                                          ("successor", road.to_node))
            if hd.junctions[node].connectors]  # a junction without connectors is not written
    link = [line for tag, node in ends
            for line in _element(3, tag, {"elementType": "junction",
                                          "elementId": junctions[node]})]
    children = [*(_element(2, "link", {}, link) if link else []),
                *_type(road.road_class, road.speed), *_plan_view(road.plan), *_lanes(hd, road)]
    if crosswalks:
        children += _element(2, "objects", {}, [line for crosswalk in crosswalks
                                                for line in _crosswalk(road, crosswalk)])
    if signals:
        children += _element(2, "signals", {}, [line for signal in signals for line in signal])
    return _element(1, "road", _road_attributes(road.id, f"r{road.id}", -1, road.plan), children)


@cache  # one per road class: formatted once
def _type(road_class: str, speed: float) -> tuple[str, ...]:
    """``<type>`` ``town`` with the class speed limit (chapter "Road type") and the HD map
    road class as ``<userData>`` (chapter "Ancillary data")."""
    return tuple(_element(2, "type", {"s": 0.0, "type": ROAD_TYPE},
                    [*_element(3, "speed", {"max": float(speed), "unit": "m/s"}),
                     *_element(3, "userData", {"code": "roadClass", "value": road_class})]))


def _lanes(hd: HDMap, road: Road) -> list[str]:
    """``<lanes>``: one lane section, left lanes outermost (id n) first and right lanes
    innermost (id -1) first (descending ids)."""
    solid = road.road_class == "arterial" or road.one_way
    centre = _element(5, "lane", {"id": 0, "type": "none"}, _mark("solid" if solid else "broken"))
    walks = {d: [edge_id(road.id, d) + "_0"] if road.sidewalk_width else [] for d in "fb"}
    section = [*(_side(hd, "left", walks["b"] + road.lanes("b")) if road.lanes("b") else []),
               *_element(4, "center", {}, centre),
               *_side(hd, "right", [*reversed(road.lanes("f")), *walks["f"]])]
    offset = []  # a one-way road's driving lanes are centred on the reference line
    if road.one_way:
        width = len(road.lanes("f")) * road.lane_width
        offset = _element(3, "laneOffset", {"s": 0.0, "a": width / 2.0, "b": 0.0, "c": 0.0,
                                            "d": 0.0})
    return _element(2, "lanes", {}, [*offset,
                                     *_element(3, "laneSection", {"s": 0.0}, section)])


def _side(hd: HDMap, tag: str, lane_ids) -> list[str]:
    """``<left>`` or ``<right>`` with its lanes: constant width, the outer road mark (solid
    on the outermost driving lane), speed limit; a sidewalk (type ``sidewalk``) its width. No
    ``<link>``: the road ends in junctions at both ends (rule road.lane.link.no_link)."""
    lanes = []
    for lane_id in lane_ids:
        if lane_id in hd.sidewalks:
            lane = hd.sidewalks[lane_id]
            lanes += _element(5, "lane", {"id": xodr_lane_id(hd, lane), "type": "sidewalk"},
                              _width(float(lane.width), 0.0))
            continue
        lane = hd.lanes[lane_id]
        lanes += _element(5, "lane", {"id": xodr_lane_id(hd, lane), "type": "driving"},
                          _lane_records(float(lane.width), lane.right_neighbour is None,
                                        float(lane.speed)))
    return _element(4, tag, {}, lanes)


@cache  # the same few lines for every lane of a class: formatted once
def _lane_records(width: float, outermost: bool, speed: float) -> tuple[str, ...]:
    """A road lane's constant width, road mark (solid on the outermost lane) and speed."""
    return (*_width(width, 0.0), *_mark("solid" if outermost else "broken"), *_speed(speed))


def _mark(kind: str) -> list[str]:
    """A white road mark on the lane's outer border (``broken`` lines may be crossed)."""
    return _element(6, "roadMark", {"sOffset": 0.0, "type": kind, "weight": "standard",
                                    "color": "standard", "width": MARK_WIDTH,
                                    "laneChange": "both" if kind == "broken" else "none"})


def _width(a: float, b: float) -> list[str]:
    """``<width>``: linear width ``a + b s``."""
    return _element(6, "width", {"sOffset": 0.0, "a": a, "b": b, "c": 0.0, "d": 0.0})


def _speed(speed: float) -> list[str]:
    return _element(6, "speed", {"sOffset": 0.0, "max": speed, "unit": "m/s"})


def _contact(lane: Lane, arriving: bool) -> str:
    """Which end of its road a road lane touches the junction with: ``f`` lanes arrive at the
    reference line's end and leave from its start, ``b`` lanes the other way round."""
    return "end" if (lane.direction == "f") == arriving else "start"


def _connector_pieces(connectors: list[Lane]) -> list[Piece]:
    """Each connector's one plan-view piece: its Bezier as an exact ``paramPoly3`` (all
    converted at once), or the half circle of a U-turn (``lane.plan``) as an ``arc``."""
    curved = [lane for lane in connectors if lane.plan is None]
    beziers = iter(bezier_pieces(np.array([lane.bezier for lane in curved]).reshape(-1, 4, 2)))
    return [lane.plan[0] if lane.plan is not None else next(beziers) for lane in connectors]


def _connecting_road(hd: HDMap, lane: Lane, piece: Piece, rid: int, jid: int) -> list[str]:
    """A connector as a one-lane connecting road inside its junction ``jid`` (chapter
    "Junctions": connecting roads) along ``piece``, linked to its incoming and outgoing road
    and lanes. Its width changes linearly along it; a lane offset of half the width centres
    the lane on the reference line."""
    incoming, outgoing = hd.lanes[lane.predecessors[0]], hd.lanes[lane.successors[0]]
    link = [*_element(3, "predecessor", {"elementType": "road", "elementId": incoming.road,
                                         "contactPoint": _contact(incoming, arriving=True)}),
            *_element(3, "successor", {"elementType": "road", "elementId": outgoing.road,
                                       "contactPoint": _contact(outgoing, arriving=False)})]
    width = float(lane.width)
    slope = (float(lane.end_width) - width) / piece.length
    lane_link = [*_element(7, "predecessor", {"id": xodr_lane_id(hd, incoming)}),
                 *_element(7, "successor", {"id": xodr_lane_id(hd, outgoing)})]
    right = _element(5, "lane", {"id": -1, "type": "driving"},
                     [*_element(6, "link", {}, lane_link), *_width(width, slope),
                      *_speed(float(lane.speed))])
    section = [*_element(4, "center", {}, _element(5, "lane", {"id": 0, "type": "none"})),
               *_element(4, "right", {}, right)]
    lanes = [*_element(3, "laneOffset", {"s": 0.0, "a": width / 2.0, "b": slope / 2.0,
                                         "c": 0.0, "d": 0.0}),
             *_element(3, "laneSection", {"s": 0.0}, section)]
    return _element(1, "road", _road_attributes(rid, lane.id, jid, [piece]),
                    [*_element(2, "link", {}, link), *_type(lane.road_class, lane.speed),
                     *_plan_view([piece]), *_element(2, "lanes", {}, lanes)])


def _junction(hd: HDMap, node: int, jid: int, connecting: dict[str, int]) -> list[str]:
    """``<junction>`` ``jid`` of node ``node``: one connection per connecting road, from its
    incoming road; a ``<priority>`` record for each pair of connecting roads where the one
    (``low``) yields to the other (``high``) as SUMO decided (``hdmap.right_of_way``); the
    junction's traffic light controller."""
    junction = hd.junctions[node]
    children = []
    for k, lane_id in enumerate(junction.connectors):
        incoming = hd.lanes[hd.lanes[lane_id].predecessors[0]]
        children += _element(2, "connection", {"id": k, "incomingRoad": incoming.road,
                                               "connectingRoad": connecting[lane_id],
                                               "contactPoint": "start"},
                             _element(3, "laneLink", {"from": xodr_lane_id(hd, incoming),
                                                      "to": -1}))
    for lane_id in junction.connectors:
        for prohibitor in hd.lanes[lane_id].yields_to:
            children += _element(2, "priority", {"high": connecting[prohibitor],
                                                 "low": connecting[lane_id]})
    if any(hd.lanes[c].traffic_light for c in junction.connectors):
        children += _element(2, "controller", {"id": node, "type": "0", "sequence": 0})
    return _element(1, "junction", {"id": jid, "name": f"n{node}", "type": "default"}, children)


def _crosswalk(road: Road, crosswalk) -> list[str]:
    """A crosswalk ``<object>`` with SUMO's outline of the crossing (``hdmap.crossings``) as
    ``cornerLocal`` points (the outline CARLA reads), anchored on the reference line at the
    road's end nearest to it: the crossing lies in the junction, beyond the lanes' end."""
    points, tangents = road.reference
    centre = crosswalk.outline.mean(axis=0)
    at_end = np.hypot(*(points[-1] - centre)) < np.hypot(*(points[0] - centre))
    origin, ahead = (points[-1], tangents[-1]) if at_end else (points[0], tangents[0])
    left = np.array([-ahead[1], ahead[0]])
    corners = [_element(5, "cornerLocal", {"id": k, "u": float((p - origin) @ ahead),
                                            "v": float((p - origin) @ left), "z": 0.0,
                                            "height": 0.0})
               for k, p in enumerate(crosswalk.outline)]
    length = sum(p.length for p in road.plan)
    return _element(3, "object", {"id": crosswalk.id, "name": crosswalk.id, "type": "crosswalk",
                                  "s": length if at_end else 0.0, "t": 0.0, "zOffset": 0.0,
                                  "hdg": 0.0, "orientation": "none"},
                    _element(4, "outline", {"id": 0, "closed": "true"},
                             [line for corner in corners for line in corner]))


def _signals(hd: HDMap) -> tuple[dict[int, list[list[str]]], list[list[str]]]:
    """Signals per road (road id -> the lines of its ``<signal>`` elements) and one
    ``<controller>`` per traffic light listing its lights (chapter "Signals": controllers).

    Each approach gets the signal of its control as SUMO decided it
    (``right_of_way.approach_control``): a traffic light, a stop sign (also at all-way
    stops, where every approach has one) or a yield sign, in the StVO catalogue that CARLA
    and esmini read (``SIGNAL_TYPES``). It stands right of the approach, ``SIGNAL_SETBACK``
    before the road's end, valid for all lanes of that direction. Approaches with right of
    way, or right before left (no sign in the towns whose rules we follow), get none; their
    junction's ``<priority>`` records say who yields."""
    signals, lights = defaultdict(list), defaultdict(list)
    controlled = [(node, lanes, approach_control(hd, lanes))
                  for (node, _), lanes in approaches(hd).items()]
    controlled = [approach for approach in controlled if approach[2] is not None]
    for sid, (node, lanes, control) in enumerate(controlled):
        lane = hd.lanes[lanes[0]]
        road = hd.roads[lane.road]
        signals[road.id].append(_signal(road, lane.direction, sid, node, control))
        if control == "traffic_light":
            lights[node] += _element(2, "control", {"signalId": sid, "type": "0"})
    controllers = [_element(1, "controller", {"id": node, "name": f"n{node}"}, lights[node])
                   for node in sorted(lights)]
    return signals, controllers


def _signal(road: Road, direction: str, sid: int, node: int, control: str) -> list[str]:
    """The signal of ``control`` for driving direction ``direction`` of ``road``
    (orientation ``+`` faces traffic along the reference line)."""
    length = sum(p.length for p in road.plan)
    setback = min(SIGNAL_SETBACK, length / 2.0)
    n = len(road.lanes(direction))
    side = -1.0 if direction == "f" else 1.0
    lanes = (-n, -1) if direction == "f" else (1, n)
    light = control == "traffic_light"
    return _element(3, "signal", {"s": length - setback if direction == "f" else setback,
                                  "t": side * (n * road.lane_width + 0.5), "id": sid,
                                  "name": f"n{node}_r{road.id}_{direction}",
                                  "dynamic": "yes" if light else "no",
                                  "orientation": "+" if direction == "f" else "-",
                                  "zOffset": 2.0 if light else 1.5, "country": SIGNAL_COUNTRY,
                                  "type": SIGNAL_TYPES[control], "subtype": "-1",
                                  "height": 0.9 if light else 0.6,
                                  "width": 0.3 if light else 0.6},
                    _element(4, "validity", {"fromLane": lanes[0], "toLane": lanes[1]}))
