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
import functools
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import connected_components
from shapely.geometry import LineString

from ..compiled import B1, B1_1D, I8, I8_1D, U1_1D, U1_1D_CONST, compiled
from ..hdmap.model import HDMap, Lane
from ..scenario.xmlfile import DECLARATION
from .xmltext import Element, PlacedBlock, attr_text, escape, leaf, sub, write

GENERATOR = "roadweaver-sumo"
LANE_TAG = "roadweaver:lane"  # the HD map lane id of a lanelet, for loaders and debugging
DEGREE_DECIMALS = 10  # 1e-10 degrees is about 0.01 mm
INDENT = "    "  # the indent of the written file
TRAFFIC_LIGHT_OFFSET_M = 1.0  # the traffic light way sits this far past the stop line
MIN_STEP_M = 1e-3  # shorter boundary steps are dropped

# lanelet2 tagging spec (lanelet2_core/doc/LinestringTagging.md)
DASHED = (("type", "line_thin"), ("subtype", "dashed"))  # lane change allowed both ways
SOLID = (("type", "line_thin"), ("subtype", "solid"))  # centre line between the two directions
CURB = (("type", "curbstone"), ("subtype", "high"))  # outer road edge
VIRTUAL = (("type", "virtual"),)  # inside junctions: no physical marking

# WGS84 ellipsoid and the Krüger series of the transverse Mercator projection to fourth order in
# the third flattening n (Karney 2011, "Transverse Mercator with an accuracy of a few
# nanometers", Eqs. 35-36): micrometre-exact within hundreds of kilometres of the origin.
_A, _F = 6378137.0, 1 / 298.257223563
_N = _F / (2 - _F)
_E = 2 * np.sqrt(_N) / (1 + _N)  # first eccentricity
_RECTIFYING = _A / (1 + _N) * (1 + _N**2 / 4 + _N**4 / 64)
_ALPHA = np.array([_N / 2 - 2 * _N**2 / 3 + 5 * _N**3 / 16 + 41 * _N**4 / 180,
                   13 * _N**2 / 48 - 3 * _N**3 / 5 + 557 * _N**4 / 1440,
                   61 * _N**3 / 240 - 103 * _N**4 / 140,
                   49561 * _N**4 / 161280])
_BETA = np.array([_N / 2 - 2 * _N**2 / 3 + 37 * _N**3 / 96 - _N**4 / 360,
                  _N**2 / 48 + _N**3 / 15 - 437 * _N**4 / 1440,
                  17 * _N**3 / 480 - 37 * _N**4 / 840,
                  4397 * _N**4 / 161280])
_DELTA = np.array([2 * _N - 2 * _N**2 / 3 - 2 * _N**3 + 116 * _N**4 / 45,
                   7 * _N**2 / 3 - 8 * _N**3 / 5 - 227 * _N**4 / 45,
                   56 * _N**3 / 15 - 136 * _N**4 / 35,
                   4279 * _N**4 / 630])
_J2 = 2 * np.arange(1, 5)
_ALPHA_J, _BETA_J, _DELTA_J = (list(zip(c.tolist(), _J2.tolist(), strict=True))
                               for c in (_ALPHA, _BETA, _DELTA))


def _series(terms):
    """The sum of a series' four terms, added one after another to 0.0 as ``np.sum`` adds
    four columns (same bits, signed zeros included), without the four-column arrays that
    made the projection of a million nodes twice as slow."""
    return sum(terms, 0.0)


def _tm_forward(lat, lon, lon0):
    """Geodetic degrees to transverse Mercator metres (easting, northing from the equator)."""
    phi, lam = np.radians(np.asarray(lat, float)), np.radians(np.asarray(lon, float) - lon0)
    sin_phi = np.sin(phi)
    tau = np.sinh(np.arctanh(sin_phi) - _E * np.arctanh(_E * sin_phi))  # conformal latitude
    xi_p = np.arctan2(tau, np.cos(lam))
    eta_p = np.arctanh(np.sin(lam) / np.sqrt(1 + tau**2))
    xi = xi_p + _series(a * np.sin(j * xi_p) * np.cosh(j * eta_p) for a, j in _ALPHA_J)
    eta = eta_p + _series(a * np.cos(j * xi_p) * np.sinh(j * eta_p) for a, j in _ALPHA_J)
    return _RECTIFYING * eta, _RECTIFYING * xi


def latlon_to_local(lat, lon, origin: tuple[float, float]) -> tuple[np.ndarray, np.ndarray]:
    """WGS84 degrees to local metres (x east, y north) of the map whose (0, 0) is ``origin``."""
    lat0, lon0 = origin
    x, y = _tm_forward(lat, lon, lon0)
    return x, y - _tm_forward(lat0, lon0, lon0)[1]


def local_to_latlon(x, y, origin: tuple[float, float]) -> tuple[np.ndarray, np.ndarray]:
    """Local metres to WGS84 degrees: the inverse of :func:`latlon_to_local`."""
    lat0, lon0 = origin
    xi = (np.asarray(y, float) + _tm_forward(lat0, lon0, lon0)[1]) / _RECTIFYING
    eta = np.asarray(x, float) / _RECTIFYING
    xi_p = xi - _series(b * np.sin(j * xi) * np.cosh(j * eta) for b, j in _BETA_J)
    eta_p = eta - _series(b * np.cos(j * xi) * np.sinh(j * eta) for b, j in _BETA_J)
    chi = np.arcsin(np.sin(xi_p) / np.cosh(eta_p))  # conformal latitude
    phi = chi + _series(d * np.sin(j * chi) for d, j in _DELTA_J)
    return np.degrees(phi), lon0 + np.degrees(np.arctan2(np.sinh(eta_p), np.cos(xi_p)))


def untangle(points: np.ndarray) -> np.ndarray:
    """``points`` without the loops and fold-backs that offsetting a sharp bend leaves in a
    boundary, and without sub-millimetre steps; the end points stay (they are shared nodes)."""
    points = _cut_loops(np.asarray(points, float))
    step = np.diff(points, axis=0)
    if (len(step) and np.hypot(step[:, 0], step[:, 1]).min() > 1.001 * MIN_STEP_M  # margin: math.hypot below
            and (step[:-1, 0] * step[1:, 0] + step[:-1, 1] * step[1:, 1] >= 0).all()):
        return points  # no short step and no fold-back: the loop below would keep every point
    points = points.tolist()  # plain floats: a hot loop
    kept = [points[0]]
    for index, (x, y) in enumerate(points[1:], start=1):
        if math.hypot(x - kept[-1][0], y - kept[-1][1]) < MIN_STEP_M:
            if index == len(points) - 1 and len(kept) > 1:
                kept[-1] = [x, y]
            continue
        while len(kept) >= 2 and ((kept[-1][0] - kept[-2][0]) * (x - kept[-1][0])
                                  + (kept[-1][1] - kept[-2][1]) * (y - kept[-1][1])) < 0:
            kept.pop()  # a turn of more than 90 degrees: the polyline folds back here
        kept.append([x, y])
    return np.array(kept)


def _cut_loops(points: np.ndarray) -> np.ndarray:
    """Replace each self-crossing loop by its crossing point (swallowtails of offset curves)."""
    if len(points) < 4 or _turning(points) < 0.99 * math.pi or LineString(points).is_simple:
        return points  # a polyline turning less than half a turn in all cannot cross itself
    i = 0
    while i < len(points) - 3:
        a, b = points[i], points[i + 1]
        starts, ends = points[i + 2:-1], points[i + 3:]
        t, u = _segment_crossings(a, b, starts, ends)
        hits = np.nonzero((t >= 0) & (t <= 1) & (u >= 0) & (u <= 1))[0]
        if len(hits):
            j = i + 2 + hits[-1]  # the last crossing removes the largest loop
            crossing = a + t[hits[-1]] * (b - a)
            points = np.vstack([points[:i + 1], crossing, points[j + 1:]])
        i += 1
    return points


def _turning(points: np.ndarray) -> float:
    """Total absolute turning (rad) of a polyline; a zero-length step only adds to it."""
    step = np.diff(points, axis=0)
    heading = np.arctan2(step[:, 1], step[:, 0])
    return float(np.abs(np.angle(np.exp(1j * np.diff(heading)))).sum())


def _segment_crossings(a, b, starts, ends):
    """Parameters ``t`` on segment a-b and ``u`` on each segment starts-ends of their lines'
    intersection (``inf`` for parallel segments)."""
    d, e = b - a, ends - starts
    denom = d[0] * e[:, 1] - d[1] * e[:, 0]
    w = starts - a
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (w[:, 0] * e[:, 1] - w[:, 1] * e[:, 0]) / denom
        u = (w[:, 0] * d[1] - w[:, 1] * d[0]) / denom
    parallel = np.abs(denom) < 1e-12
    t[parallel] = u[parallel] = np.inf
    return t, u


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
    for way, clean in zip(ways, _clean([w.points for w in ways]), strict=True):
        way.points = np.asarray(way.points, float) if clean else untangle(way.points)
    return plan


def _clean(polylines: list) -> np.ndarray:
    """Per polyline, whether :func:`untangle` would return it unchanged because it turns less
    than half a turn in all (so it cannot cross itself), has no sub-millimetre step and never
    turns by more than 90 degrees: one vectorised pass over all boundaries of the map instead
    of a dozen small numpy calls per boundary."""
    sizes = np.fromiter(map(len, polylines), int, len(polylines))
    pts = np.concatenate(polylines, dtype=float)  # (n, 2) each: no per-polyline conversion
    owner = np.repeat(np.arange(len(polylines)), sizes)
    step = np.diff(pts, axis=0)
    inside = owner[1:] == owner[:-1]  # steps between two polylines are not steps
    step, step_owner = step[inside], owner[1:][inside]
    short = np.hypot(step[:, 0], step[:, 1]) <= 1.001 * MIN_STEP_M  # margin: untangle's hypot
    pair = step_owner[1:] == step_owner[:-1]
    fold = (step[:-1, 0] * step[1:, 0] + step[:-1, 1] * step[1:, 1] < 0)[pair]
    heading = np.arctan2(step[:, 1], step[:, 0])
    turn = np.abs(np.angle(np.exp(1j * (heading[1:] - heading[:-1])[pair])))
    n = len(polylines)
    turning = np.bincount(step_owner[1:][pair], weights=turn, minlength=n)
    bad = (np.bincount(step_owner[short], minlength=n)
           + np.bincount(step_owner[1:][pair][fold], minlength=n))
    return (bad == 0) & ((sizes < 4) | (turning < 0.99 * math.pi)) & (sizes >= 2)


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


@dataclass
class _Signal:
    """A traffic light regulatory element of one approach (one incoming road direction)."""

    id: int
    lanes: list[str]
    light: int  # the traffic light way
    stop_line: int  # its ref_line


def _signals(hd: HDMap, plan: _Plan, ids: _Ids) -> tuple[list[_Signal], dict[int, tuple]]:
    """One traffic light per approach to a ``traffic_light`` junction: a stop line across the
    approach's lane ends (the lanes' own end nodes) and a light way just past it."""
    signals, ways = [], {}
    for rid in sorted(hd.roads):
        road = hd.roads[rid]
        for direction in ("f", "b"):
            lanes = road.lanes(direction)
            junction = hd.junctions[road.ends_at(direction)]
            if not lanes or junction.type != "traffic_light":
                continue
            line = [_lane_end_node(plan, lanes[0], "right")]
            line += [_lane_end_node(plan, lane, "left") for lane in lanes]
            across = np.subtract(ids.xy(line[-1]), ids.xy(line[0]))  # right to left
            shift = TRAFFIC_LIGHT_OFFSET_M * np.array([across[1], -across[0]]) / np.hypot(*across)
            light = [ids.node(np.add(ids.xy(n), shift)) for n in (line[0], line[-1])]
            stop_id, light_id = ids.new(), ids.new()
            ways[stop_id] = (line, (("type", "stop_line"),))
            ways[light_id] = (light, (("type", "traffic_light"), ("subtype", "red_yellow_green")))
            signals.append(_Signal(ids.new(), lanes, light_id, stop_id))
    return signals, ways


def speed_limit_tag(speed_mps: float) -> str:
    """``speed_limit`` value: km/h as a bare number with two decimals at most. lanelet2 reads a
    bare number as km/h (as it reads "50 km/h"); Tactics2D and Autoware's map validator only
    accept a bare number, and Tactics2D's default unit is km/h too."""
    return f"{round(speed_mps * 3.6, 2):g}"


_INNER = "\n" + 2 * INDENT  # between the children of a way or relation
_BETWEEN_REFS = f'"/>{_INNER}<nd ref="'


def _element(tag: str, eid: int, children: str) -> str:
    """An element with OSM's id attributes and its children's finished lines (joined by
    ``_INNER``), as text to be placed one indent deep: ways and relations number tens of
    thousands, each with a handful of children, so each is formatted in one go."""
    return f'<{tag} id="{eid}" visible="true" version="1">{_INNER}{children}\n{INDENT}</{tag}>'


@functools.lru_cache(maxsize=4096)
def _tag_lines(tags: tuple) -> str:
    """``<tag>`` lines of a tags tuple, cached: way tags repeat thousands of times, and lanelet
    tags other than the lane id take few values."""
    return _INNER.join(_tag_line(key, value) for key, value in tags)


def _tag_line(key: str, value: str) -> str:
    return leaf("tag", attr_text((("k", key), ("v", value))))


def _way(wid: int, nodes, tags: tuple) -> str:
    refs = _BETWEEN_REFS.join(map(str, nodes))
    return _element("way", wid, f'<nd ref="{refs}"/>{_INNER}{_tag_lines(tags)}')


def _planned_ways(plan: _Plan, first_id: int) -> memoryview:
    """:func:`_way` of each planned way (ids ``first_id`` on, in plan order), joined as the
    root's children, as ASCII bytes from a compiled writer (a million node refs as Python ints
    and strings took a tenth of the file's time, formatting 80k ways another tenth)."""
    tags: dict[tuple, int] = {}  # each way's tags as an index into the few tag tuples
    rows = np.array([(way.first, way.inner.start, len(way.inner), way.last,
                      tags.setdefault(way.tags, len(tags))) for way in plan.ways.values()],
                    np.int64).reshape(-1, 5)
    ends = [f"{_INNER}{_tag_lines(t)}\n{INDENT}</way>".encode() for t in tags]
    return _way_lines(first_id, *rows.T.copy(), _uint8(b"".join(ends)),
                      np.cumsum([0, *map(len, ends)]), _uint8(_INNER.encode()),
                      _uint8(f"\n{INDENT}".encode())).data


def _uint8(text: bytes) -> np.ndarray:
    return np.frombuffer(text, np.uint8).copy()


def _relation(rid: int, members: list[tuple[str, int, str]], tags: str) -> str:
    """A relation with its members and its ``<tag>`` lines ``tags``."""
    lines = [f'<member type="{kind}" ref="{ref}" role="{role}"/>'  # plain words: no escaping
             for kind, ref, role in members]
    return _element("relation", rid, _INNER.join([*lines, tags]))


def _degrees(value: float) -> str:
    return f"{value:.{DEGREE_DECIMALS}f}"


def _add_nodes(root, hd: HDMap, ids: _Ids) -> None:
    node_ids, xy = ids.all_nodes()
    lat, lon = local_to_latlon(xy[:, 0], xy[:, 1], hd.geo_origin)
    # The nodes are the root's children: their lines go one indent deep.
    text = _node_lines(node_ids, *_fixed_point(lat), *_fixed_point(lon),
                       np.frombuffer(("\n" + INDENT).encode(), np.uint8).copy())
    root.append(PlacedBlock(text.data))  # 50 MB of bytes: written as they are, not decoded


_NODE_LINE = (f'<node id="%d" visible="true" version="1" lat="%.{DEGREE_DECIMALS}f"'
              f' lon="%.{DEGREE_DECIMALS}f"/>')
_SCALE = 10.0 ** DEGREE_DECIMALS
#: |v| 10^D of a degree value is within 2.5e-4 of its exact product (half a float spacing at
#: 180 degrees); a fraction this far from one half rounds the same way as the exact value.
_TIE_MARGIN = 1e-3


def _fixed_point(values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each value as ``%.{DEGREE_DECIMALS}f`` rounds it: |value| in units of 10^-D, and its
    sign. Near a rounding tie the float product could round the other way than Python's exact
    decimal conversion; those few values are read back from Python's own formatting."""
    scaled = np.abs(values) * _SCALE
    whole = np.floor(scaled)
    frac = scaled - whole
    units = (whole + (frac > 0.5)).astype(np.int64)
    for k in np.flatnonzero(np.abs(frac - 0.5) < _TIE_MARGIN):
        units[k] = int(f"{abs(values[k]):.{DEGREE_DECIMALS}f}".replace(".", ""))
    return units, np.signbit(values)


#: The constant pieces of ``_NODE_LINE`` around its id and two coordinates, as bytes.
_NODE_PARTS = tuple(np.frombuffer(text, np.uint8).copy()
                    for text in (b'<node id="', b'" visible="true" version="1" lat="',
                                 b'" lon="', b'"/>'))


@compiled(I8(U1_1D, I8, U1_1D_CONST))
def _copy(out, pos, text):  # pragma: no cover - compiled
    for i in range(len(text)):
        out[pos + i] = text[i]
    return pos + len(text)


@compiled(I8(U1_1D, I8, I8, U1_1D))
def _write_int(out, pos, value, digits):  # pragma: no cover - compiled
    """The decimal digits of ``value`` >= 0 at ``out[pos]``; returns the position after."""
    n = 0
    while True:
        digits[n] = 48 + value % 10
        value //= 10
        n += 1
        if value == 0:
            break
    for i in range(n):
        out[pos + i] = digits[n - 1 - i]
    return pos + n


#: "00" to "99": two digits per division (integer division is what the writer spends on).
_DIGIT_PAIRS = np.frombuffer("".join(f"{k:02d}" for k in range(100)).encode(), np.uint8).copy()


@compiled(I8(U1_1D, I8, I8, B1, U1_1D))
def _write_fixed(out, pos, units, negative, digits):  # pragma: no cover - compiled
    """``units`` 10^-DEGREE_DECIMALS as ``%.{DEGREE_DECIMALS}f`` writes it (the sign even
    where the value rounds to zero, as Python does)."""
    if negative:
        out[pos] = 45  # "-"
        pos += 1
    scale = 10 ** DEGREE_DECIMALS
    pos = _write_int(out, pos, units // scale, digits)
    out[pos] = 46  # "."
    pos += 1
    rest = units % scale
    for i in range(DEGREE_DECIMALS - 2, -1, -2):  # DEGREE_DECIMALS is even
        pair = rest % 100
        rest //= 100
        out[pos + i] = _DIGIT_PAIRS[2 * pair]
        out[pos + i + 1] = _DIGIT_PAIRS[2 * pair + 1]
    return pos + DEGREE_DECIMALS


@compiled(U1_1D(I8_1D, I8_1D, B1_1D, I8_1D, B1_1D, U1_1D))
def _node_lines(ids, lat_units, lat_negative, lon_units, lon_negative, separator):  # pragma: no cover
    """The ``<node>`` lines of the file (``_NODE_LINE``, joined by ``separator``) as ASCII
    bytes, from fixed-point coordinates: a million Python formattings took 0.6 s at 10 km."""
    head, mid, lon_key, tail = _NODE_PARTS
    out = np.empty(len(ids) * (128 + len(separator)), np.uint8)
    digits = np.empty(24, np.uint8)
    pos = 0
    for k in range(len(ids)):
        if k:
            for i in range(len(separator)):
                out[pos + i] = separator[i]
            pos += len(separator)
        pos = _copy(out, pos, head)
        pos = _write_int(out, pos, ids[k], digits)
        pos = _copy(out, pos, mid)
        pos = _write_fixed(out, pos, lat_units[k], lat_negative[k], digits)
        pos = _copy(out, pos, lon_key)
        pos = _write_fixed(out, pos, lon_units[k], lon_negative[k], digits)
        pos = _copy(out, pos, tail)
    return out[:pos]


@compiled(I8(U1_1D, I8, U1_1D, I8, I8))
def _put(out, pos, text, start, stop):  # pragma: no cover - compiled
    """:func:`_copy` of ``text[start:stop]``, a writable array."""
    for i in range(start, stop):
        out[pos + i - start] = text[i]
    return pos + stop - start


_WAY_PARTS = tuple(np.frombuffer(text, np.uint8).copy()
                   for text in (b'<way id="', b'" visible="true" version="1">', b'<nd ref="',
                                b'"/>'))


@compiled(U1_1D(I8, I8_1D, I8_1D, I8_1D, I8_1D, I8_1D, U1_1D, I8_1D, U1_1D, U1_1D))
def _way_lines(first_id, first, inner, count, last, tag, ends, ends_at, inner_separator,
               separator):  # pragma: no cover - compiled
    """Per way ``first_id + k`` its ``<way>`` line, the ``<nd>`` lines of its nodes ``first``,
    ``count`` consecutive ids from ``inner`` and ``last`` (joined by ``inner_separator``) and
    its end ``ends[ends_at[tag]:ends_at[tag + 1]]``; ways joined by ``separator``, as ASCII
    bytes."""
    way_head, way_tail, head, tail = _WAY_PARTS
    n_refs = len(first) * 2 + count.sum()
    size = n_refs * (len(head) + 20 + len(tail) + len(inner_separator))
    size += len(first) * (len(way_head) + 20 + len(way_tail) + len(separator) + ends.size)
    out = np.empty(size, np.uint8)
    digits = np.empty(24, np.uint8)
    pos = 0
    for k in range(len(first)):
        if k:
            pos = _put(out, pos, separator, 0, len(separator))
        pos = _copy(out, pos, way_head)
        pos = _write_int(out, pos, first_id + k, digits)
        pos = _copy(out, pos, way_tail)
        for i in range(count[k] + 2):
            pos = _put(out, pos, inner_separator, 0, len(inner_separator))
            node = first[k] if i == 0 else last[k] if i == count[k] + 1 else inner[k] + i - 1
            pos = _copy(out, pos, head)
            pos = _write_int(out, pos, node, digits)
            pos = _copy(out, pos, tail)
        pos = _put(out, pos, ends, ends_at[tag[k]], ends_at[tag[k] + 1])
    return out[:pos]


def _add_bounds(root, hd: HDMap) -> None:
    lat, lon = local_to_latlon([0.0, hd.width, 0.0, hd.width], [0.0, 0.0, hd.height, hd.height],
                               hd.geo_origin)
    sub(root, "bounds", attr_text((("minlat", _degrees(lat.min())), ("minlon", _degrees(lon.min())),
                                   ("maxlat", _degrees(lat.max())), ("maxlon", _degrees(lon.max())))))


def _lanelet(rid: int, lane: Lane, left: int, right: int, regulatory: int | None) -> str:
    """A lane's lanelet relation: its bounds, its traffic light if any, the tags of its speed
    (cached) and its own id, formatted in one go (one per lane; ``LANE_TAG`` and the member
    words are plain words, only the lane id needs escaping)."""
    members = (f'<member type="way" ref="{left}" role="left"/>{_INNER}'
               f'<member type="way" ref="{right}" role="right"/>')
    if regulatory is not None:
        members += f'{_INNER}<member type="relation" ref="{regulatory}" role="regulatory_element"/>'
    return _element("relation", rid, f'{members}{_INNER}{_lanelet_speed_tags(lane.speed)}'
                                     f'{_INNER}<tag k="{LANE_TAG}" v="{escape(lane.id)}"/>')


@functools.lru_cache(maxsize=256)
def _lanelet_speed_tags(speed: float) -> str:
    """The ``<tag>`` lines of a lanelet but its lane id: they differ only by speed."""
    return _tag_lines((("type", "lanelet"), ("subtype", "road"), ("location", "urban"),
                       ("one_way", "yes"), ("speed_limit", speed_limit_tag(speed))))


def lanelet2_tree(hd: HDMap) -> Element:
    """The ``<osm>`` element of ``hd`` in lanelet2 format (see the module docstring)."""
    if hd.geo_origin is None:
        raise ValueError("the HD map has no geo_origin; lanelet2 files need lat/lon")
    ids = _Ids()
    plan = _plan_ways(hd)
    _assign_nodes(hd, plan, ids)
    way_ids = {key: ids.new() for key in plan.ways}  # consecutive, in plan order
    signals, signal_ways = _signals(hd, plan, ids)
    regulatory = {lane: s.id for s in signals for lane in s.lanes}

    root = Element("osm", attr_text((("version", "0.6"), ("generator", GENERATOR))))
    _add_bounds(root, hd)
    _add_nodes(root, hd, ids)
    # Ways and then relations in id order, the order their ids were given in.
    if plan.ways:  # the root's children: lines one indent deep
        root.append(PlacedBlock(_planned_ways(plan, next(iter(way_ids.values())))))
    ways = [_way(wid, nodes, tags) for wid, (nodes, tags) in signal_ways.items()]
    relations = [_relation(s.id, [("way", s.light, "refers"), ("way", s.stop_line, "ref_line")],
                           _tag_lines((("type", "regulatory_element"),
                                       ("subtype", "traffic_light"))))
                 for s in signals]
    relations += [_lanelet(ids.new(), lane, way_ids[plan.slots[(lane.id, "left")]],
                           way_ids[plan.slots[(lane.id, "right")]], regulatory.get(lane.id))
                  for lane in sorted(hd.lanes.values(), key=lambda lane: lane.id)]
    for elements in (ways, relations):
        if elements:  # the root's children: lines one indent deep
            root.append(PlacedBlock(f"\n{INDENT}".join(elements)))
    return root


def write_lanelet2(hd: HDMap, path: Path) -> Path:
    """Write ``hd`` as a lanelet2-format OSM file (parent folders created) and return its
    path."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    return write(lanelet2_tree(hd), path, indent=INDENT, declaration=DECLARATION)
