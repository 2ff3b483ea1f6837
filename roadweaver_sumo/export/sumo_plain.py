"""HD map to SUMO plain XML (``map.nod.xml``, ``map.edg.xml``, ``map.con.xml``) for netconvert.

One SUMO edge per road direction (``r7_f`` along the reference line, ``r7_b`` against it), whose
shape is the road's reference line in driving direction, from one junction outline to the
other (netconvert's plain edges may start and end on the node's shape): SUMO's default
``spreadType="right"`` puts the lanes right of it, as in the HD map, so SUMO lane ``r7_f_0``
is HD map lane ``r7_f_0``, on the same line. A one-way road has only its ``f`` edge, its
driving lanes centred on the shape (``spreadType="center"``).

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


def plain_nodes(hd: HDMap) -> etree._Element:
    """``<nodes>``: one node per junction with its control type and the HD map's outline
    (:func:`junction_outline`). A dead end on the map border (a road that ran on into the
    town the map was cut from) is marked ``fringe="outer"``, so that randomTrips'
    ``--fringe-junctions`` sends through traffic in and out there, and not at the cul-de-sacs
    inside."""
    root = _root("nodes", "nodes_file.xsd")
    if hd.geo_origin is not None:
        _add_location(root, hd)
    for jid in sorted(hd.junctions):
        j = hd.junctions[jid]
        x, y = j.xy
        outer = j.type == "dead_end" and min(x, y, hd.width - x, hd.height - y) < BORDER_M
        etree.SubElement(root, "node", id=node_id(jid), x=_num(x), y=_num(y), type=j.type,
                         **({"fringe": "outer"} if outer else {}),
                         shape=" ".join(_points(junction_outline(hd, j))))
    return root


def junction_outline(hd: HDMap, junction) -> np.ndarray:
    """The outline of a junction: round it counter-clockwise, each road's cross-section where
    the HD map's trims (``hdmap.junctions.junction_trims``) end its lanes and sidewalks, from
    its right edge to its left (seen from the junction); a dead end's closes at its centre.
    Left to itself netconvert draws larger junctions than the HD map's wherever crossings
    are, and a road of 25 m between two of them became a SUMO edge of 0.2 m while
    ``map.xodr`` kept 8 m of it; at a taper junction (``hdmap.turn_bays``) it made the
    through lanes jump a lane width aside. Given the outline, SUMO's edges end where the HD
    map's lanes do and its internal lanes follow the HD map's connectors."""
    centre = np.asarray(junction.xy, dtype=float)
    arms = []
    for rid in junction.roads:
        road = hd.roads[rid]
        points = []
        for direction in DIRECTIONS:
            lanes = [hd.lanes[lane_id] for lane_id in road.lanes(direction)]
            sidewalk = hd.sidewalks.get(f"{edge_id(rid, direction)}_0")
            k = -1 if road.ends_at(direction) == junction.id else 0
            for lane in lanes + ([sidewalk] if sidewalk else []):
                points += [lane.left[k], lane.right[k]]
        points = np.asarray(points)
        mid = points.mean(axis=0)
        out = mid - centre  # lane ends are trimmed at least MIN_RADIUS from the centre
        rel = points - mid
        side = out[0] * rel[:, 1] - out[1] * rel[:, 0]  # > 0: left, seen from the junction
        arms.append((math.atan2(out[1], out[0]), points[np.argmin(side)], points[np.argmax(side)]))
    outline = [p for _, right, left in sorted(arms, key=lambda arm: arm[0]) for p in (right, left)]
    if len(arms) == 1:
        outline.append(centre)
    return np.asarray(outline)


def plain_edges(hd: HDMap) -> etree._Element:
    """``<edges>``: one edge per road direction, shape in driving direction; a
    ``<roundabout>`` per roundabout (``hdmap.roundabouts``), for netconvert to make its
    entries yield to the ring."""
    root = _root("edges", "edges_file.xsd")
    for rid in sorted(hd.roads):
        road = hd.roads[rid]
        points = _points(road.reference[0])  # formatted once, for both directions
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
