"""HD map to SUMO plain XML (``map.nod.xml``, ``map.edg.xml``, ``map.con.xml``) for netconvert.

One SUMO edge per road direction (``r7_f`` along the reference line, ``r7_b`` against it), whose
shape is the road's centreline in driving direction: SUMO's default ``spreadType="right"`` puts
the lanes right of it, as in the HD map, so SUMO lane ``r7_f_0`` is HD map lane ``r7_f_0``. A
one-way road has only its ``f`` edge, its lanes centred on the shape (``spreadType="center"``).

Connections come from the HD map's lane graph only. netconvert keeps exactly the connections
given for an edge that has any, but guesses all (U-turns included) for an edge that has none;
an edge without outgoing lanes in the lane graph is therefore declared with an empty
``<connection from="..."/>``, so that the ``.net.xml`` never holds a connection we did not make.
"""

from __future__ import annotations

import math
from collections import Counter
from pathlib import Path

import numpy as np
import shapely
from lxml import etree

from ..hdmap.model import DIRECTIONS, HDMap, edge_id
from ..projection import tmerc

XSI = "http://www.w3.org/2001/XMLSchema-instance"
NO_LANE_CHANGE = "emergency"  # the classes that may change lanes inside a junction
METRES_PER_DEGREE = 111_320.0  # at the equator; only used for the informative origBoundary


def node_id(node: int) -> str:
    """SUMO node id of a junction, e.g. ``"n12"``."""
    return f"n{node}"


def _num(x: float) -> str:
    """Fixed two-decimal formatting, without ``-0.00``."""
    return f"{round(float(x), 2) + 0.0:.2f}"


def _points(coords) -> list[str]:
    """``x,y`` per point, each number as :func:`_num` writes it (``%.2f`` rounds as ``round``
    does; what would print as ``-0.00`` is zeroed first), a whole line at once."""
    xy = np.asarray(coords, dtype=float)
    xy = np.where((xy > -0.005) & (xy <= 0.0), 0.0, xy)
    return list(map("%.2f,%.2f".__mod__, map(tuple, xy.tolist())))


def _root(tag: str, schema: str) -> etree._Element:
    return etree.Element(tag, {f"{{{XSI}}}noNamespaceSchemaLocation":
                               f"http://sumo.dlr.de/xsd/{schema}"}, nsmap={"xsi": XSI})


def _add_location(root: etree._Element, hd: HDMap) -> None:
    """Geo-reference: a transverse Mercator projection centred on the map's origin (0, 0),
    so SUMO's x/y are our local metres and sumo-gui / sumolib can report lat/lon."""
    lat, lon = hd.geo_origin
    dlat = hd.height / METRES_PER_DEGREE
    dlon = hd.width / (METRES_PER_DEGREE * math.cos(math.radians(lat)))
    etree.SubElement(root, "location", {
        "netOffset": "0.00,0.00",
        "convBoundary": f"0.00,0.00,{_num(hd.width)},{_num(hd.height)}",
        "origBoundary": f"{lon:.6f},{lat:.6f},{lon + dlon:.6f},{lat + dlat:.6f}",
        "projParameter": tmerc(hd.geo_origin),
    })


BORDER_M = 1.0  # a dead end this close to the map border is where a road left the map
#: Corner radius (m) of a junction with sidewalks, at the sidewalk's outer edge (SUMO's default
#: 4 m). On tight corners a right turn crosses both crossings near the corner, at an angle, and
#: SUMO's drivers, who judge a walker's distance along the crossing as if they crossed it
#: square, pass walkers who then step into the car's side. 2 km maps with 100 walkers (grid and
#: mixed, densities 10-60): a vehicle-person collision on 7 of 50 maps at 4 m, 4 of 50 at 8 m;
#: 12 m left 2 but made long left turns meet at the exits of arterial lights (2 junction
#: collisions, 1 map with 2.5 % teleports).
SIDEWALK_CORNER_RADIUS = 8.0


def plain_nodes(hd: HDMap) -> etree._Element:
    """``<nodes>``: one node per junction with its control type. A dead end on the map border
    (a road that ran on into the town the map was cut from) is marked ``fringe="outer"``, so
    that randomTrips' ``--fringe-junctions`` sends through traffic in and out there, and not
    at the cul-de-sacs inside. On a map with sidewalks every junction off a roundabout's ring
    has corners of :data:`SIDEWALK_CORNER_RADIUS`."""
    root = _root("nodes", "nodes_file.xsd")
    corners = {"radius": _num(SIDEWALK_CORNER_RADIUS)} if hd.sidewalks else {}
    if hd.geo_origin is not None:
        _add_location(root, hd)
    for jid in sorted(hd.junctions):
        j = hd.junctions[jid]
        x, y = j.xy
        outer = j.type == "dead_end" and min(x, y, hd.width - x, hd.height - y) < BORDER_M
        etree.SubElement(root, "node", id=node_id(jid), x=_num(x), y=_num(y), type=j.type,
                         **({"fringe": "outer"} if outer else {}),
                         **({} if j.roundabout is not None else corners),
                         **({"shape": " ".join(_points(_taper_shape(hd, j)))} if j.taper else {}))
    return root


def _taper_shape(hd: HDMap, junction) -> np.ndarray:
    """The outline of a taper junction (``hdmap.turn_bays``): the hull of its lanes' ends.
    netconvert would make a two-arm junction a few metres long, the through lanes jumping a
    lane width aside in it; given the HD map's outline, its internal lanes are the HD map's
    connectors."""
    points = []
    for rid in junction.roads:
        road = hd.roads[rid]
        for direction in DIRECTIONS:
            lanes = [hd.lanes[lane_id] for lane_id in road.lanes(direction)]
            sidewalk = hd.sidewalks.get(f"{edge_id(rid, direction)}_0")
            for lane in lanes + ([sidewalk] if sidewalk else []):
                k = -1 if road.ends_at(direction) == junction.id else 0
                points += [lane.left[k], lane.right[k]]
    return np.asarray(shapely.MultiPoint(points).convex_hull.exterior.coords)[:-1]


def plain_edges(hd: HDMap) -> etree._Element:
    """``<edges>``: one edge per road direction, shape in driving direction; a
    ``<roundabout>`` per roundabout (``hdmap.roundabouts``), for netconvert to make its
    entries yield to the ring."""
    root = _root("edges", "edges_file.xsd")
    for rid in sorted(hd.roads):
        road = hd.roads[rid]
        points = _points(road.centreline)  # formatted once, for both directions
        for direction in DIRECTIONS:
            if not road.lanes(direction):  # a one-way road
                continue
            line = points if direction == "f" else points[::-1]
            etree.SubElement(root, "edge", {
                "id": edge_id(rid, direction),
                "from": node_id(road.starts_at(direction)),
                "to": node_id(road.ends_at(direction)),
                "priority": str(road.priority),
                "numLanes": str(len(road.lanes(direction))),
                "speed": _num(road.speed),
                "width": _num(road.lane_width),
                "spreadType": "center" if road.one_way else "right",
                **({"sidewalkWidth": _num(road.sidewalk_width)} if road.sidewalk_width else {}),
                "shape": " ".join(line),
            })
    rings: dict[int, list[int]] = {}
    for jid in sorted(hd.junctions):
        if hd.junctions[jid].roundabout is not None:
            rings.setdefault(hd.junctions[jid].roundabout, []).append(jid)
    for ring in rings.values():
        roads = sorted({rid for jid in ring for rid in hd.junctions[jid].roads})
        edges = [edge_id(rid, "f") for rid in roads
                 if {hd.roads[rid].from_node, hd.roads[rid].to_node} <= set(ring)]
        etree.SubElement(root, "roundabout", nodes=" ".join(map(node_id, ring)),
                         edges=" ".join(edges))
    return root


def lane_connections(hd: HDMap) -> list[tuple[str, str, int, int]]:
    """(from edge, to edge, from lane, to lane) of every road lane -> connector -> road lane path
    in the HD map's lane graph, sorted."""
    found = set()
    for lane in hd.road_lanes():
        for via in lane.successors:
            for succ in hd.lanes[via].successors:
                target = hd.lanes[succ]
                found.add((lane.edge, target.edge, lane.index, target.index))
    return sorted(found)


def plain_connections(hd: HDMap) -> etree._Element:
    """``<connections>``: exactly the lane graph's connections; edges without any are declared
    empty so that netconvert does not invent connections for them.

    netconvert joins parallel connections between the same two edges into one internal edge of
    several lanes, and SUMO lets cars change lanes on it. A car stuck inside a junction behind
    spill-back would then shift sideways into the path of cross traffic that has since got
    green (3 junction collisions in the 10 km, 5000-vehicle scenario). No lane changes inside
    junctions, as the road rules say: only emergency vehicles may."""
    root = _root("connections", "connections_file.xsd")
    connections = lane_connections(hd)
    connected = {c[0] for c in connections}
    every_edge = sorted(edge_id(r, d) for r in hd.roads for d in DIRECTIONS
                        if hd.roads[r].lanes(d))
    for edge in every_edge:
        if edge not in connected:
            etree.SubElement(root, "connection", {"from": edge})
    parallel = Counter((src, dst) for src, dst, _, _ in connections)
    for src, dst, src_lane, dst_lane in connections:
        connection = etree.SubElement(root, "connection", {
            "from": src, "to": dst, "fromLane": str(src_lane), "toLane": str(dst_lane)})
        if parallel[src, dst] > 1:
            connection.set("changeLeft", NO_LANE_CHANGE)
            connection.set("changeRight", NO_LANE_CHANGE)
    for node, edges in crossings(hd):
        etree.SubElement(root, "crossing", node=node_id(node), edges=" ".join(edges),
                         priority="1")
    return root


def crossings(hd: HDMap) -> list[tuple[int, list[str]]]:
    """A pedestrian crossing over every road at every junction of three or more roads, on
    maps with sidewalks: (node, the road's SUMO edges).

    Pedestrians on them have priority over vehicles (``priority="1"``, a zebra), as turning
    traffic must let people on the crossing go first (StVO §9(3)); at traffic lights the
    lights rule. netconvert's own guess gave the crossings over main roads no priority, and
    SUMO's drivers, once stopped at a stop sign, then drove into people who had started to
    cross (5 collisions with 600 people in half an hour on a 1 km map; 1 with these)."""
    found = []
    for jid in sorted(hd.junctions):
        junction = hd.junctions[jid]
        if len(junction.roads) < 3:
            continue
        for rid in junction.roads:
            road = hd.roads[rid]
            if road.sidewalk_width:
                found.append((jid, [edge_id(rid, d) for d in DIRECTIONS if road.lanes(d)]))
    return found


PLAIN_FILES = {"map.nod.xml": plain_nodes, "map.edg.xml": plain_edges,
               "map.con.xml": plain_connections}


def write_plain(hdmap: HDMap, plain_dir: Path) -> None:
    """Write ``map.nod.xml``, ``map.edg.xml`` and ``map.con.xml`` into ``plain_dir`` (created
    if missing). Output is deterministic: sorted ids, two-decimal coordinates."""
    plain_dir = Path(plain_dir)
    plain_dir.mkdir(parents=True, exist_ok=True)
    for name, tree in PLAIN_FILES.items():
        etree.ElementTree(tree(hdmap)).write(plain_dir / name, pretty_print=True,
                                             xml_declaration=True, encoding="UTF-8")
