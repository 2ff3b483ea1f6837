"""HD map to a lanelet2-format OpenStreetMap file (``lanelet2_map.osm``).

Every HD map lane (road lanes and junction connectors) becomes one lanelet. lanelet2 derives its
topology from shared primitives, not from tags, so the file is built around identity:

* lanes of one driving direction that are neighbours share their common boundary *way* (lane
  changes). Every way runs in its lanes' driving direction, because lanelet2 guesses the
  orientation of bounds from their middle vertices (``geometry::align``) and a wrong guess
  reverses a lanelet: the two directions of a road get a solid centre line each rather than one
  shared inverted way, and boundaries are untangled (loops and fold-backs that offsetting a
  sharp bend leaves are cut) before they are written;
* a lane and each of its successors share the *nodes* at the end of the one and the start of the
  other (the routing graph's "following" relation). Node identity is found with a union-find over
  way end points driven by the HD map's successor links, so lanes that diverge from one lane start
  at the same nodes and lanes that merge into one lane end at the same nodes.

Ids are positive, unique across nodes, ways and relations (Tactics2D's ``Map`` keeps one id space)
and assigned in a fixed order, so the same HD map gives the same bytes. Coordinates are a
transverse Mercator projection (scale 1) centred on ``hd.geo_origin`` — the projection SUMO's
``location`` element declares — written to 1e-10 degrees; lanelet2's ``LocalCartesianProjector``
at the same origin reads them back within a millimetre on maps of a few kilometres (its
``UtmProjector`` does not: UTM's 0.9996 scale alone moves points by 40 cm per kilometre).
"""

from __future__ import annotations

import bisect
import itertools
from collections import defaultdict
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from xml.sax.saxutils import escape

import numpy as np
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import connected_components

from ..hdmap.model import HDMap, Lane
from ..projection import local_to_latlon
from ..scenario.xmlfile import DECLARATION
from .lanelet2_boundaries import untangle_all
from .lanelet2_rules import RegulatoryElement, rule_elements
from .lanelet2_walks import WalkLanelet, walk_elements

GENERATOR = "roadweaver-sumo"
LANE_TAG = "roadweaver:lane"  # the HD map lane id of a lanelet, for loaders and debugging
DEGREE_DECIMALS = 10  # 1e-10 degrees is about 0.01 mm
INDENT = "    "  # the indent of the written file

# lanelet2 tagging spec (lanelet2_core/doc/LinestringTagging.md)
DASHED = (("type", "line_thin"), ("subtype", "dashed"))  # lane change allowed both ways
SOLID = (("type", "line_thin"), ("subtype", "solid"))  # centre line between the two directions
CURB = (("type", "curbstone"), ("subtype", "high"))  # outer road edge
VIRTUAL = (("type", "virtual"),)  # inside junctions: no physical marking


@dataclass
class _Way:
    """One boundary way: points in driving direction, line tags, and (later) node ids: its
    first and last node (shared with other ways) and the consecutive ids of the nodes between."""

    points: np.ndarray
    tags: tuple
    first: int = 0
    inner: range = range(0)
    last: int = 0


@dataclass
class _Plan:
    """Which way (keyed by its owner ``(lane id, side)``) each lane side uses, and the ways."""

    slots: dict[tuple[str, str], tuple[str, str]] = field(default_factory=dict)
    ways: dict[tuple[str, str], _Way] = field(default_factory=dict)  # in creation order


def _lane_order(hd: HDMap) -> list[Lane]:
    """Road lanes first, then connectors, each by id: shared end points take road coordinates."""
    return sorted(hd.lanes.values(), key=lambda lane: (lane.kind != "road", lane.id))


def _left_slot(hd: HDMap, lane: Lane, plan: _Plan) -> None:
    """A lane owns its left boundary; a lane with a right neighbour uses that lane's left
    boundary as its right one, so each line between two lanes of a direction is one way."""
    if lane.left_neighbour is not None:
        tags = DASHED
    elif lane.kind == "connector":
        tags = VIRTUAL
    else:
        opposite = hd.roads[lane.road].lanes("b" if lane.direction == "f" else "f")
        tags = SOLID if opposite else CURB
    plan.ways[(lane.id, "left")] = _Way(lane.left, tags)  # untangled in _plan_ways
    plan.slots[(lane.id, "left")] = (lane.id, "left")


def _right_slot(lane: Lane, plan: _Plan) -> None:
    if lane.right_neighbour is not None:  # that lane owns the line as its left boundary
        plan.slots[(lane.id, "right")] = (lane.right_neighbour, "left")
        return
    tags = VIRTUAL if lane.kind == "connector" else CURB
    plan.ways[(lane.id, "right")] = _Way(lane.right, tags)
    plan.slots[(lane.id, "right")] = (lane.id, "right")


def _plan_ways(hd: HDMap) -> _Plan:
    plan = _Plan()
    for lane in _lane_order(hd):
        _left_slot(hd, lane, plan)
        _right_slot(lane, plan)
    ways = list(plan.ways.values())
    for way, points in zip(ways, untangle_all([w.points for w in ways]), strict=True):
        way.points = points
    return plan


class _Ids:
    """One id counter for nodes, ways and relations, with the node coordinates: nodes take
    their ids in blocks of consecutive ids (all the ways' nodes, then each signal's)."""

    def __init__(self) -> None:
        self.next = 1
        self.firsts: list[int] = []  # the first id of each block
        self.blocks: list[np.ndarray] = []  # its points

    def new(self) -> int:
        self.next += 1
        return self.next - 1

    def nodes(self, points: np.ndarray) -> int:
        """The first of new consecutive node ids for ``points``."""
        self.firsts.append(self.next)
        self.blocks.append(np.array(points, float).reshape(-1, 2))
        self.next += len(self.blocks[-1])
        return self.firsts[-1]

    def node(self, xy) -> int:
        return self.nodes([xy])

    def xy(self, nid: int) -> np.ndarray:
        k = bisect.bisect_right(self.firsts, nid) - 1
        return self.blocks[k][nid - self.firsts[k]]

    def all_nodes(self) -> tuple[np.ndarray, np.ndarray]:
        """Every node id in increasing order (blocks are made in id order), and its
        coordinates."""
        ids = [np.arange(first, first + len(points))
               for first, points in zip(self.firsts, self.blocks, strict=True)]
        return np.concatenate(ids), np.concatenate(self.blocks)


def _assign_nodes(hd: HDMap, plan: _Plan, ids: _Ids) -> None:
    """Give every way its node ids; end points joined by a successor link share one node, placed
    where the first way (road lanes come first) has it.

    Ids follow the ways' points in order, an end point taking a new id only where its node is
    first met, so the nodes are the ways' points less the end points met before: found for
    the whole map at once rather than point by point."""
    ways = list(plan.ways.values())
    way_index = {key: k for k, key in enumerate(plan.ways)}
    bounds = {lane: (way_index[plan.slots[(lane, "left")]], way_index[plan.slots[(lane, "right")]])
              for lane in hd.lanes}  # each lane's left and right way
    joints = [(2 * end + 1, 2 * start)  # the end of a lane's way, the start of its successor's
              for lane in hd.lanes.values() for succ in lane.successors
              for end, start in zip(bounds[lane.id], bounds[succ], strict=True)]
    a, b = np.array(joints, int).reshape(-1, 2).T
    n = 2 * len(ways)  # way end points: 2 * way + (0 = first, 1 = last)
    _, joint = connected_components(csr_matrix((np.ones(len(a)), (a, b)), shape=(n, n)))
    _, met = np.unique(joint, return_index=True)  # where each joint is first met
    # A way untangled to one point (a lane under a millimetre) still has two end points.
    points = [way.points if len(way.points) > 1 else way.points[[0, 0]] for way in ways]
    sizes = np.array([len(p) for p in points])
    ends = np.stack([np.cumsum(sizes) - sizes, np.cumsum(sizes) - 1], axis=1).ravel()
    kept = np.ones(sizes.sum(), bool)
    kept[ends] = False
    kept[ends[met]] = True
    first = ids.nodes(np.concatenate(points)[kept])
    before = np.cumsum(kept) - kept  # kept points before each point
    end_ids = (first + before[ends[met]])[joint].reshape(-1, 2).tolist()
    inner_starts = (first + before[ends[0::2] + 1]).tolist()
    for way, (start, end), inner, size in zip(ways, end_ids, inner_starts, sizes.tolist(),
                                              strict=True):
        way.first, way.inner, way.last = start, range(inner, inner + size - 2), end


def _lane_end_node(plan: _Plan, lane_id: str, side: str) -> int:
    return plan.ways[plan.slots[(lane_id, side)]].last


def speed_limit_tag(speed_mps: float) -> str:
    """``speed_limit`` value: km/h as a bare number with two decimals at most. lanelet2 reads a
    bare number as km/h (as it reads "50 km/h"); Tactics2D and Autoware's map validator only
    accept a bare number, and Tactics2D's default unit is km/h too."""
    return f"{round(speed_mps * 3.6, 2):g}"


def _attr(value: str) -> str:
    """An attribute value as XML text (lane ids are the only values not made here)."""
    return escape(value, {'"': "&quot;"})


def _open(tag: str, eid: int, attrs: str = "", children: bool = True) -> str:
    """The start of a node, way or relation with OSM's id attributes (JOSM's style)."""
    return f'{INDENT}<{tag} id="{eid}" visible="true" version="1"{attrs}{">" if children else "/>"}'


def _tag_lines(tags) -> list[str]:
    return [f'{INDENT * 2}<tag k="{_attr(key)}" v="{_attr(value)}"/>' for key, value in tags]


def _member(kind: str, ref: int, role: str) -> str:
    return f'{INDENT * 2}<member type="{kind}" ref="{ref}" role="{role}"/>'


def _way(wid: int, nodes, tags: tuple) -> str:
    return "\n".join([_open("way", wid), *(f'{INDENT * 2}<nd ref="{node}"/>' for node in nodes),
                      *_tag_lines(tags), f"{INDENT}</way>"])


def _regulatory(element: RegulatoryElement) -> str:
    """A regulatory element relation (``export.lanelet2_rules``)."""
    return "\n".join([_open("relation", element.id),
                      *(_member(kind, ref, role) for kind, ref, role in element.members),
                      *_tag_lines((("type", "regulatory_element"),
                                   ("subtype", element.subtype))),
                      f"{INDENT}</relation>"])


def _lanelet(rid: int, lane: Lane, left: int, right: int, regulatory: list[int]) -> str:
    """A lane's lanelet relation: its bounds, the regulatory elements it is subject to, its
    speed limit and its own id."""
    members = [_member("way", left, "left"), _member("way", right, "right")]
    members += [_member("relation", element, "regulatory_element") for element in regulatory]
    tags = (("type", "lanelet"), ("subtype", "road"), ("location", "urban"), ("one_way", "yes"),
            ("speed_limit", speed_limit_tag(lane.speed)), (LANE_TAG, lane.id))
    return "\n".join([_open("relation", rid), *members, *_tag_lines(tags), f"{INDENT}</relation>"])


def _walk_lanelet(walk: WalkLanelet) -> str:
    """A pedestrian lanelet (``export.lanelet2_walks``), walkable either way."""
    tags = (("type", "lanelet"), ("subtype", walk.subtype), ("location", "urban"),
            ("one_way", "no"), (LANE_TAG, walk.source))
    return "\n".join([_open("relation", walk.id), _member("way", walk.left, "left"),
                      _member("way", walk.right, "right"), *_tag_lines(tags),
                      f"{INDENT}</relation>"])


def _degrees(value: float) -> str:
    return f"{value:.{DEGREE_DECIMALS}f}"


def _bounds(hd: HDMap) -> str:
    lat, lon = local_to_latlon([0.0, hd.width, 0.0, hd.width], [0.0, 0.0, hd.height, hd.height],
                               hd.geo_origin)
    return (f'{INDENT}<bounds minlat="{_degrees(lat.min())}" minlon="{_degrees(lon.min())}" '
            f'maxlat="{_degrees(lat.max())}" maxlon="{_degrees(lon.max())}"/>')


def _nodes(hd: HDMap, ids: _Ids) -> Iterator[str]:
    node_ids, xy = ids.all_nodes()
    lat, lon = local_to_latlon(xy[:, 0], xy[:, 1], hd.geo_origin)
    for nid, node_lat, node_lon in zip(node_ids.tolist(), lat.tolist(), lon.tolist(),
                                       strict=True):
        yield _open("node", nid, f' lat="{_degrees(node_lat)}" lon="{_degrees(node_lon)}"', False)


def osm_elements(hd: HDMap) -> Iterator[str]:
    """The children of ``hd``'s ``<osm>`` element in lanelet2 format (see the module docstring)
    as indented XML text, in file order: bounds, nodes, ways, relations, each in id order. Ids
    are all given before the first element is made; the elements are made one at a time, as
    they are asked for."""
    if hd.geo_origin is None:
        raise ValueError("the HD map has no geo_origin; lanelet2 files need lat/lon")
    ids = _Ids()
    plan = _plan_ways(hd)
    _assign_nodes(hd, plan, ids)
    way_ids = {key: ids.new() for key in plan.ways}  # consecutive, in plan order
    lanes = sorted(hd.lanes.values(), key=lambda lane: lane.id)
    lanelet_ids = {lane.id: ids.new() for lane in lanes}
    elements, rule_ways = rule_elements(
        hd, lambda lane, side: _lane_end_node(plan, lane, side), ids, lanelet_ids)
    regulatory = defaultdict(list)
    for element in elements:
        for lane in element.lanes:
            regulatory[lane].append(element.id)
    walk_ways, walks = walk_elements(hd, ids)
    return itertools.chain(
        [_bounds(hd)],
        _nodes(hd, ids),
        (_way(way_ids[key], [way.first, *way.inner, way.last], way.tags)
         for key, way in plan.ways.items()),
        (_way(wid, nodes, tags) for wid, (nodes, tags) in rule_ways.items()),
        (_way(wid, nodes, tags) for wid, (nodes, tags) in walk_ways.items()),
        (_lanelet(lanelet_ids[lane.id], lane, way_ids[plan.slots[(lane.id, "left")]],
                  way_ids[plan.slots[(lane.id, "right")]], regulatory[lane.id])
         for lane in lanes),
        map(_regulatory, elements),
        map(_walk_lanelet, walks))


def write_lanelet2(hd: HDMap, path: Path) -> Path:
    """Write ``hd`` as a lanelet2-format OSM file (parent folders created) and return its
    path.

    Written as text, element by element: an OSM file is a flat list of nodes, ways and
    relations of a few fixed attributes, one line each or a few, and every boundary point of
    the map is a node (665,000 on a 10 km map), more than an element tree is worth building."""
    elements = osm_elements(hd)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("w", encoding="utf-8") as file:
        file.write(DECLARATION)
        file.write(f'<osm version="0.6" generator="{GENERATOR}">\n')
        for element in elements:
            file.write(element + "\n")
        file.write("</osm>\n")
    return path
