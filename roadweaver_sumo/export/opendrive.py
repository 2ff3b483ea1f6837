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
* Traffic-light junctions get a ``<controller>`` and one signal per incoming road direction.

Output is deterministic: sorted ids, fixed decimals, fixed header date.
"""

from __future__ import annotations

from collections import defaultdict
from pathlib import Path

import numpy as np

from ..hdmap.model import DIRECTIONS, HDMap, Lane, Road
from ..hdmap.reference import Piece
from .opendrive_geometry import DECIMALS, bezier_pieces
from .xmltext import Block, Element, PlacedBlock, cdata, escape, leaf, sub, write

CURVATURE_DECIMALS = 15  # an arc's end moves by length^2 / 2 times the curvature's rounding
DATE = "2025-01-01T00:00:00"  # fixed, so that two runs write the same bytes
ROAD_TYPE = "town"  # OpenDRIVE 1.4 road type: known to every reader (see the module docstring)
MARK_WIDTH = 0.12  # m
SIGNAL_SETBACK = 1.0  # m before the road end
SIGNAL_CATALOGUE = {"country": "DE", "type": "1000001", "subtype": "-1"}  # StVO traffic light


def write_opendrive(hd: HDMap, path: Path) -> Path:
    """Write ``hd`` as OpenDRIVE 1.7 to ``path`` (parent folders created); return the path."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    return write(opendrive_tree(hd), path)


def opendrive_tree(hd: HDMap) -> Element:
    """The ``<OpenDRIVE>`` element of ``hd``: header, roads, connecting roads, controllers,
    junctions, in that (schema) order."""
    rids = sorted(hd.roads)
    plans = {rid: hd.roads[rid].plan for rid in rids}
    connecting = connecting_road_ids(hd)
    junctions = junction_ids(hd)
    signals, controllers = _traffic_lights(hd, plans)
    root = Element("OpenDRIVE")
    root.append(_header(hd))
    for (rid, plan), view in zip(plans.items(), _plan_views(list(plans.values())), strict=True):
        root.append(_road(hd, hd.roads[rid], plan, view, signals.get(rid, []), junctions))
    connectors = hd.connectors()
    pieces, curves = _connector_pieces(connectors)
    geometries = _rows(_GEOMETRY, [p[1:6] for p in pieces])
    numbers = _connector_numbers(connectors, pieces)
    roads = [_connecting_road(hd, lane, connecting[lane.id], junctions[lane.junction], geometry,
                              curve, texts)
             for lane, geometry, curve, texts in zip(connectors, geometries, curves, numbers,
                                                     strict=True)]
    if roads:  # the root's children: lines one indent deep
        root.append(PlacedBlock("\n  ".join(roads)))
    root.extend(controllers)
    for jid in sorted(hd.junctions):
        if hd.junctions[jid].connectors:
            root.append(_junction(hd, jid, junctions[jid], connecting))
    return root


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
    innermost); a connector is lane ``-1`` of its connecting road."""
    if lane.kind == "connector":
        return -1
    inner_rank = len(hd.roads[lane.road].lanes(lane.direction)) - lane.index
    return -inner_rank if lane.direction == "f" else inner_rank


def _num(x: float, decimals: int = DECIMALS) -> str:
    """Fixed-decimal formatting, without ``-0``."""
    text = f"{x:.{decimals}f}"
    return text[1:] if text[0] == "-" and not text.strip("-0.") else text


def _rows(template: str, values, decimals: int = DECIMALS) -> list[str]:
    """``template`` with its ``{}`` filled by :func:`_num` of each row of ``values`` (m, k)."""
    rows = np.asarray(values, float)
    return [template.format(*(_num(v, decimals) for v in row))
            for row in (rows[:, None] if rows.ndim == 1 else rows).tolist()]


def _attrs(attrs: dict) -> str:
    """Attribute text: floats with fixed decimals, a trailing ``_`` dropped (``from_``)."""
    parts = []
    for key, value in attrs.items():
        if isinstance(value, float):
            value = _num(value)
        elif isinstance(value, str):
            value = escape(value)
        else:  # ids and counts: nothing to escape
            value = str(value)
        parts.append(f' {key.rstrip("_")}="{value}"')
    return "".join(parts)


_ZERO = _num(0.0)
_GEOMETRY = "<geometry" + "".join(f' {key}="{{}}"' for key in ("s", "x", "y", "hdg", "length")) + ">"
_PARAM_POLY3 = ("<paramPoly3" + "".join(f' {c}{axis}="{{}}"' for axis in "UV" for c in "abcd")
                + ' pRange="normalized"/>')
# A white road mark on a lane's outer border (``broken`` lines may be crossed).
_MARKS = {kind: leaf("roadMark", _attrs({"sOffset": 0.0, "type": kind, "weight": "standard",
                                         "color": "standard", "width": MARK_WIDTH,
                                         "laneChange": "both" if kind == "broken" else "none"}))
          for kind in ("solid", "broken")}


def _elem(tag: str, **attrs) -> Element:
    """A new element with formatted attributes."""
    return Element(tag, _attrs(attrs))


def _sub(parent: Element, tag: str, **attrs) -> Element:
    """A new child element with formatted attributes."""
    return sub(parent, tag, _attrs(attrs))


def _leaf(parent: Element, tag: str, **attrs) -> None:
    """A new childless child element with formatted attributes (cheaper than :func:`_sub`)."""
    parent.children.append(leaf(tag, _attrs(attrs)))


def _header(hd: HDMap) -> Element:
    """``<header>`` with the map extent and a transverse Mercator geo-reference centred on
    the local origin (chapter "Georeferencing": PROJ string)."""
    header = _elem("header", revMajor=1, revMinor=7, name="roadweaver-sumo", version="1.0",
                   date=DATE, north=float(hd.height), south=0.0, east=float(hd.width), west=0.0,
                   vendor="roadweaver-sumo")
    if hd.geo_origin is not None:
        lat, lon = hd.geo_origin
        proj = (f"+proj=tmerc +lat_0={lat} +lon_0={lon} +k=1 +x_0=0 +y_0=0 +ellps=WGS84"
                " +units=m +no_defs")
        sub(header, "geoReference").text = cdata(proj)
    return header


def _plan_views(plans: list[list[Piece]]) -> list[str]:
    """Each road's ``<planView>``: one ``<geometry>`` per line or arc piece (chapter
    "Geometry"), as one finished block in the file's two-space indent; the numbers of all
    roads are formatted at once (geometries are the file's most numerous element)."""
    pieces = [p for plan in plans for p in plan]
    geometries = iter(_rows("  " + _GEOMETRY, [p[1:6] for p in pieces]))
    arcs = iter(_rows('    <arc curvature="{}"/>',
                      [p.curvature for p in pieces if p.kind == "arc"], CURVATURE_DECIMALS))
    views = []
    for plan in plans:
        lines = ["<planView>"]
        for p in plan:
            lines.append(next(geometries))
            lines.append(next(arcs) if p.kind == "arc" else "    <line/>")
            lines.append("  </geometry>")
        lines.append("</planView>")
        views.append(Block("\n".join(lines)) if plan else "<planView/>")
    return views


def _road_element(rid: int, name: str, junction: int, pieces: list[Piece]) -> Element:
    """An empty ``<road>`` as long as its plan view, right-hand traffic."""
    length = sum(p.length for p in pieces)  # formatted inline (what _elem would write)
    return Element("road", f' id="{rid}" name="{escape(name)}" junction="{junction}"'
                           f' length="{_num(length)}" rule="RHT"')


def _road(hd: HDMap, road: Road, pieces: list[Piece], plan_view: str, signals: list,
          junctions: dict[int, int]) -> Element:
    """A road between two junctions (their ids ``junctions``): its two driving directions as
    right and left lanes."""
    elem = _road_element(road.id, f"r{road.id}", -1, pieces)
    ends = [(tag, node) for tag, node in (("predecessor", road.from_node),
                                          ("successor", road.to_node))
            if hd.junctions[node].connectors]  # a junction without connectors is not written
    if ends:
        link = _sub(elem, "link")
        for tag, node in ends:
            _leaf(link, tag, elementType="junction", elementId=junctions[node])
    _road_type(elem, road.road_class, road.speed)
    elem.children.append(plan_view)
    elem.children.append(_lanes(hd, road))
    if signals:
        _sub(elem, "signals").extend(signals)
    return elem


def _road_type(road: Element, road_class: str, speed: float) -> None:
    """``<type>`` ``town`` with the class speed limit (chapter "Road type") and the road
    class as user data."""
    kind = sub(road, "type", f' s="{_ZERO}" type="{ROAD_TYPE}"')
    kind.children.append(f'<speed max="{_num(float(speed))}" unit="m/s"/>')
    kind.children.append(_road_class(road_class))


def _road_class(road_class: str) -> str:
    """The HD map road class as ``<userData>`` (chapter "Ancillary data")."""
    return f'<userData code="roadClass" value="{escape(road_class)}"/>'


def _lanes(hd: HDMap, road: Road) -> Block:
    """``<lanes>``: one lane section, left lanes outermost (id n) first and right lanes
    innermost (id -1) first (descending ids), as one finished block in the file's two-space
    indent (lanes are the file's most numerous element after geometries)."""
    centre = _MARKS["solid" if road.road_class == "arterial" else "broken"]
    return Block("\n".join([
        "<lanes>", f'  <laneSection s="{_ZERO}">',
        *_side(hd, "left", road.lanes("b")),
        "    <center>", '      <lane id="0" type="none">', f"        {centre}", "      </lane>",
        "    </center>",
        *_side(hd, "right", reversed(road.lanes("f"))),
        "  </laneSection>", "</lanes>"]))


def _side(hd: HDMap, tag: str, lane_ids) -> list[str]:
    """The lines of ``<left>`` or ``<right>`` with its lanes: constant width, the outer road
    mark, speed limit. No ``<link>``: the road ends in junctions at both ends (rule
    road.lane.link.no_link)."""
    lines = []
    for lane in map(hd.lanes.__getitem__, lane_ids):
        mark = _MARKS["solid" if lane.index == 0 else "broken"]  # index 0: the outermost lane
        lines += [f'      <lane id="{xodr_lane_id(hd, lane)}" type="driving">',
                  f"        {_width(_num(float(lane.width)), _ZERO)}", f"        {mark}",
                  f"        {_speed(_num(float(lane.speed)))}", "      </lane>"]
    return [f"    <{tag}>", *lines, f"    </{tag}>"] if lines else [f"    <{tag}/>"]


def _width(a: str, b: str) -> str:
    """``<width>`` text: linear width ``a + b s``, both written (formatted inline: one per
    lane)."""
    return f'<width sOffset="{_ZERO}" a="{a}" b="{b}" c="{_ZERO}" d="{_ZERO}"/>'


def _speed(speed: str) -> str:
    return f'<speed sOffset="{_ZERO}" max="{speed}" unit="m/s"/>'


def _contact(lane: Lane, arriving: bool) -> str:
    """Which end of its road a road lane touches the junction with: ``f`` lanes arrive at the
    reference line's end and leave from its start, ``b`` lanes the other way round."""
    return "end" if (lane.direction == "f") == arriving else "start"


def _connector_pieces(connectors: list[Lane]) -> tuple[list[Piece], list[str]]:
    """Each connector's one plan-view piece and the line that gives its shape: its Bezier as an
    exact ``paramPoly3``, or the half circle of a U-turn (``lane.plan``) as an ``arc``."""
    curved = [lane for lane in connectors if lane.plan is None]
    beziers = iter(bezier_pieces(np.array([lane.bezier for lane in curved]).reshape(-1, 4, 2)))
    pieces = [lane.plan[0] if lane.plan is not None else next(beziers) for lane in connectors]
    polys = iter(_rows(_PARAM_POLY3, [(*p.u, *p.v) for p in pieces if p.kind == "paramPoly3"]))
    arcs = iter(_rows('<arc curvature="{}"/>', [p.curvature for p in pieces if p.kind == "arc"],
                      CURVATURE_DECIMALS))
    return pieces, [next(arcs) if p.kind == "arc" else next(polys) for p in pieces]


def _connector_numbers(connectors: list[Lane], pieces: list[Piece]) -> list[list[str]]:
    """Per connecting road its length, speed, lane offset (a, b) and width (a, b: linear
    along s) as written: formatted all at once (see :func:`_rows`)."""
    width, end_width, speed = np.array([(lane.width, lane.end_width, lane.speed)
                                        for lane in connectors], float).reshape(-1, 3).T
    length = np.array([p.length for p in pieces], float)
    slope = (end_width - width) / length
    values = np.column_stack([length, speed, width / 2.0, slope / 2.0, width, slope])
    return [row.split("\t") for row in _rows("\t".join(["{}"] * 6), values)]


def _connecting_road(hd: HDMap, lane: Lane, rid: int, jid: int, geometry: str, curve: str,
                     numbers: list[str]) -> str:
    """A connector as a one-lane connecting road inside its junction ``jid`` (chapter "Junctions":
    connecting roads), its ``<geometry>`` and ``<paramPoly3>`` (or ``<arc>``) lines ``geometry``
    and ``curve`` and its other ``numbers`` (:func:`_connector_numbers`), linked to its incoming
    and outgoing road and lanes.

    Written as finished text (the most numerous road of a map: building it element by
    element cost a third of the file's time), its lines after the first placed one two-space
    indent deep, as the root's children are: no re-indenting of 30k roads when written."""
    incoming, outgoing = hd.lanes[lane.predecessors[0]], hd.lanes[lane.successors[0]]
    length, speed, offset_a, offset_b, width, slope = numbers
    return (
        f'<road id="{rid}" name="{escape(lane.id)}" junction="{jid}"'
        f' length="{length}" rule="RHT">\n'
        f'    <link>\n'
        f'      <predecessor elementType="road" elementId="{incoming.road}"'
        f' contactPoint="{_contact(incoming, arriving=True)}"/>\n'
        f'      <successor elementType="road" elementId="{outgoing.road}"'
        f' contactPoint="{_contact(outgoing, arriving=False)}"/>\n'
        f'    </link>\n'
        f'    <type s="{_ZERO}" type="{ROAD_TYPE}">\n'
        f'      <speed max="{speed}" unit="m/s"/>\n'
        f'      {_road_class(lane.road_class)}\n'
        f'    </type>\n'
        f'    <planView>\n'
        f'      {geometry}\n'
        f'        {curve}\n'
        f'      </geometry>\n'
        f'    </planView>\n'
        f'    <lanes>\n'
        f'      <laneOffset s="{_ZERO}" a="{offset_a}" b="{offset_b}"'
        f' c="{_ZERO}" d="{_ZERO}"/>\n'
        f'      <laneSection s="{_ZERO}">\n'
        f'        <center>\n'
        f'          <lane id="0" type="none"/>\n'
        f'        </center>\n'
        f'        <right>\n'
        f'          <lane id="-1" type="driving">\n'
        f'            <link>\n'
        f'              <predecessor id="{xodr_lane_id(hd, incoming)}"/>\n'
        f'              <successor id="{xodr_lane_id(hd, outgoing)}"/>\n'
        f'            </link>\n'
        f'            {_width(width, slope)}\n'
        f'            {_speed(speed)}\n'
        f'          </lane>\n'
        f'        </right>\n'
        f'      </laneSection>\n'
        f'    </lanes>\n'
        f'  </road>')


def _junction(hd: HDMap, node: int, jid: int, connecting: dict[str, int]) -> Element:
    """``<junction>`` ``jid`` of node ``node``: one connection per connecting road, from its
    incoming road."""
    junction = hd.junctions[node]
    elem = _elem("junction", id=jid, name=f"n{node}", type="default")
    for k, lane_id in enumerate(junction.connectors):
        incoming = hd.lanes[hd.lanes[lane_id].predecessors[0]]
        # formatted inline (one connection per connector), as _sub and _leaf would
        connection = sub(elem, "connection", f' id="{k}" incomingRoad="{incoming.road}"'
                                             f' connectingRoad="{connecting[lane_id]}"'
                                             ' contactPoint="start"')
        connection.children.append(f'<laneLink from="{xodr_lane_id(hd, incoming)}" to="-1"/>')
    if junction.type == "traffic_light":
        _leaf(elem, "controller", id=node, type="0", sequence=0)
    return elem


def _traffic_lights(hd: HDMap, plans: dict[int, list[Piece]]):
    """Signals per road (dict road id -> ``<signal>`` elements) and one ``<controller>`` per
    traffic-light junction listing them (chapter "Signals": controllers). A signal stands
    right of each road direction arriving at the junction, ``SIGNAL_SETBACK`` before its end,
    valid for all lanes of that direction."""
    signals, controllers = defaultdict(list), []
    count = 0
    for jid in sorted(hd.junctions):
        junction = hd.junctions[jid]
        if junction.type != "traffic_light" or not junction.connectors:
            continue
        controller = _elem("controller", id=jid, name=f"n{jid}")
        for rid in junction.roads:
            road = hd.roads[rid]
            for direction in DIRECTIONS:
                if road.ends_at(direction) != jid:
                    continue
                signals[rid].append(_signal(road, direction, plans[rid], count, jid))
                _leaf(controller, "control", signalId=count, type="0")
                count += 1
        controllers.append(controller)
    return signals, controllers


def _signal(road: Road, direction: str, pieces: list[Piece], sid: int, jid: int):
    """One traffic light for driving direction ``direction`` of ``road`` (orientation ``+``
    faces traffic along the reference line)."""
    length = sum(p.length for p in pieces)
    setback = min(SIGNAL_SETBACK, length / 2.0)
    n = len(road.lanes(direction))
    side = -1.0 if direction == "f" else 1.0
    elem = _elem("signal", s=length - setback if direction == "f" else setback,
                 t=side * (n * road.lane_width + 0.5), id=sid,
                 name=f"n{jid}_r{road.id}_{direction}", dynamic="yes",
                 orientation="+" if direction == "f" else "-", zOffset=2.0,
                 **SIGNAL_CATALOGUE, height=0.9, width=0.3)
    lanes = (-n, -1) if direction == "f" else (1, n)
    _leaf(elem, "validity", fromLane=lanes[0], toLane=lanes[1])
    return elem
