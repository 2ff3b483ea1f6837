"""Density control: fill the largest empty blocks with local roads until the target is met.

Density is a closed loop (DESIGN.md): each round splits the largest block (a face of the planar
graph) with a local road traced through the same tensor field from the block's interior to its
boundary on both sides. A road across a face adds exactly its two T-junctions. Some roads
instead continue a side street across the block from a T-junction on its edge: that T becomes a
crossroads, as real streets run on through junctions (real tiles have 21 % four-way junctions
100 m inside the tile; without continuations the fill makes T-junctions only), and the road adds
one node. The T may be one a road across the neighbouring block made after this block was cut. The node
count moves in steps of one or two, so it overshoots the target by at most one. When there are too many road nodes, local roads that are not
bridges are removed, shortest first.
"""

from __future__ import annotations

import heapq
import math
from functools import partial

import networkx as nx
import numpy as np
import shapely
import shapely.ops
from scipy.spatial import cKDTree
from shapely.geometry import LineString, Point, Polygon

from ..metrics import road_node_count
from ..roadgraph import add_road, edge_coords, edge_length, edge_list
from ..streamlines import choose_axis, follow_field
from ..tensor_field import TensorField
from .edge_index import EdgeIndex
from .junction_angles import point_along
from .planar import road_lines

STEP = 20.0  # metres per Euler step of a fill road (locals are short and gently curved)
CONTINUE_SHARE = 0.5  # share of blocks first offered a continuation of a side street
STRAIGHT_CAP = 150.0  # degrees: the two roads of a T's bar are at least this close to straight


def faces(G: nx.Graph) -> list[Polygon]:
    """Bounded faces (blocks) of the planar road graph."""
    lines = road_lines(edge_list(G))  # one shapely call for all roads
    return [p for p in shapely.get_parts(shapely.polygonize(lines)) if p.area > 1.0]


def fill_to_density(
    G: nx.Graph,
    target: int,
    field: TensorField,
    rng: np.random.Generator,
    min_edge: float,
    min_angle: float,
    stub: float = 0.0,
) -> None:
    """Split blocks, largest first (and the blocks their splits make), until
    ``road_node_count(G) >= target`` or no block can be split, counting the road nodes as the
    clean-up will leave them (``stub``: see :func:`counted_change`)."""
    need = target - road_node_count(G)
    heap = [(-f.area, k, f) for k, f in enumerate(sorted(faces(G), key=lambda f: f.bounds))]
    heapq.heapify(heap)
    counter = len(heap)
    index = EdgeIndex(G)
    nodes = _NodePoints(G)
    count = 0
    while heap and count < need:
        _, _, face = heapq.heappop(heap)
        ends = None
        makers = [partial(split_chord, roads=index), partial(straight_chord, roads=index),
                  partial(scattered_chord, roads=index)]
        if rng.random() < CONTINUE_SHARE:
            makers.insert(0, continuation_chord)
        for make_chord in makers:
            chord = make_chord(face, nodes, field, rng, min_edge, min_angle)
            if chord is not None:
                start = nodes.at(chord[0])
                ends = insert_chord(G, chord, min_edge, index, start_node=start)
                nodes.update()  # a refused chord may still have split a road at its first end
            if ends is not None:
                break
        if ends is None:
            continue
        # The other nodes a chord may create (a shape node, a split point before the chord
        # reaches it) have degree 2: not counted.
        count += sum(counted_change(G, n, stub) for n in ends)
        for part in _split_face(face, chord, ends, index):
            heapq.heappush(heap, (-part.area, counter, part))
            counter += 1


def counted_change(G: nx.Graph, end, stub: float) -> int:
    """How a chord ending at node ``end`` changes the road-node count, as the clean-up after
    the fill will leave it. The chord adds one to the node's degree. Where it cut a dead-end
    road less than ``stub`` from its end, the clean-up prunes that tip, a counted dead end, and
    the node keeps one road fewer: a junction on a road again, not counted. (Counting such ends
    as new junctions lost 3.5 % of a learned 10 km map's road nodes to the clean-up, and a
    second density round had to make them up.)"""
    degree = G.degree(end)
    tips = sum(1 for w in G.neighbors(end)
               if G.degree(w) == 1 and edge_length(G, end, w) < stub)
    return ((degree - tips) != 2) - ((degree - 1) != 2) - tips


def stub_loss(G: nx.Graph, stub: float) -> int:
    """The road nodes the clean-up's stub pruning will remove: every dead-end road shorter than
    ``stub`` (its end, a counted dead end) and, where that leaves two roads at the junction it
    hangs from, that junction too (see :func:`counted_change`)."""
    loss = 0
    for n in G.nodes:
        degree = G.degree(n)
        if degree < 2:
            continue
        tips = sum(1 for w in G.neighbors(n)
                   if G.degree(w) == 1 and edge_length(G, n, w) < stub)
        loss += tips + (degree != 2) - ((degree - tips) != 2) if tips else 0
    return loss


def _split_face(face: Polygon, chord: np.ndarray, ends: tuple, index: EdgeIndex) -> list[Polygon]:
    """The blocks ``face`` becomes with ``chord`` (inserted, between the nodes ``ends``) added.
    A chord across the face splits it in two (as ``shapely.ops.split`` does it before GEOS
    3.15: polygonize the boundary noded with the chord); one that ends on a dead-end road
    inside the face (which its rings leave out) closes a block only together with that road,
    so such faces are re-polygonised from their rings and the roads inside them that the
    chord is joined to (the chord among them). The other roads inside are left out: a block
    of a learned 10 km map can hold a thousand dangles, and noding them all would dominate
    its split."""
    shapely.prepare(face)  # for the containment tests
    parts = _blocks(face, face.boundary.union(_extended(chord, 1.0)))
    if len(parts) > 1:
        return parts
    inside = index.near(face, 0.0)
    if not inside:
        return parts
    lines = [index.lines[key] for key in inside]
    off_ring = {id(line) for line in _off_ring(face.exterior, lines)}
    joined = _joined_roads([key for key, line in zip(inside, lines, strict=True)
                            if id(line) in off_ring], ends)
    return _blocks(face, shapely.union_all([face.exterior, *face.interiors,
                                            *(index.lines[key] for key in joined)]))


def _joined_roads(roads: list[tuple], ends: tuple) -> list[tuple]:
    """Those of ``roads`` (edge keys) reachable from the nodes ``ends`` over ``roads``, in
    their first order."""
    at: dict = {}
    for key in roads:
        for n in key:
            at.setdefault(n, []).append(key)
    seen, todo, reached = set(ends), list(ends), set()
    while todo:
        for key in at.get(todo.pop(), ()):
            if key not in reached:
                reached.add(key)
                todo.extend(n for n in key if n not in seen)
                seen.update(key)
    return [key for key in roads if key in reached]


def _blocks(face: Polygon, noded) -> list[Polygon]:
    """The polygons (over 1 m²) inside ``face`` that the ``noded`` lines enclose."""
    found = shapely.get_parts(shapely.polygonize([noded]))  # takes each line of it in turn
    return [p for p in found if p.area > 1.0 and face.contains(p.representative_point())]


def _off_ring(ring, lines: list) -> list:
    """``lines`` without those made only of segments of ``ring`` (the block's own edge roads).
    Noding them against the ring only splits it at its own vertices, which polygonize joins
    again (the blocks come out the same, vertex for vertex), and it was most of the union's
    work. Compared by exact coordinates: each vertex gets the id of the ring vertex it equals."""
    ring_xy = shapely.get_coordinates(ring).view(np.complex128).ravel()
    vertices = np.sort(ring_xy)
    ring_id = np.searchsorted(vertices, ring_xy)  # equal vertices get one id
    n = len(vertices)
    ring_segments = np.sort(np.concatenate([ring_id[:-1] * n + ring_id[1:],
                                            ring_id[1:] * n + ring_id[:-1]]))
    xy, which = shapely.get_coordinates(lines, return_index=True)
    xy = xy.view(np.complex128).ravel()
    vid = np.minimum(np.searchsorted(vertices, xy), n - 1)
    vid[vertices[vid] != xy] = -1  # not a ring vertex
    inner = which[:-1] == which[1:]  # consecutive vertices of one line: a segment
    a, b = vid[:-1][inner], vid[1:][inner]
    code = a * n + b
    found = ring_segments[np.minimum(np.searchsorted(ring_segments, code), len(ring_segments) - 1)]
    on = (a >= 0) & (b >= 0) & (found == code)
    off_ring = np.zeros(len(lines), bool)
    off_ring[which[:-1][inner][~on]] = True
    return [line for line, keep in zip(lines, off_ring, strict=True) if keep]


class _NodePoints:
    """The junction positions of ``G`` for "is any node near this point" (asked for every chord
    end): a k-d tree over the nodes, plus the few added since it was built (rebuilt when those
    reach REBUILD_SHARE of it), instead of an array of every node rebuilt for each block."""

    REBUILD_SHARE = 0.1

    def __init__(self, G: nx.Graph):
        self.G = G
        self.top = max(G.nodes, default=-1)
        self.tree = cKDTree(np.array([G.nodes[n]["xy"] for n in G.nodes]).reshape(-1, 2))
        self.added = np.zeros((0, 2))
        self.by_xy = {tuple(G.nodes[n]["xy"]): n for n in G.nodes}
        self.continuations = {}

    def update(self) -> None:
        """Take in the nodes added to ``G`` since the last call (new nodes get the next ids and
        none are removed while filling)."""
        new = []
        while self.top + 1 in self.G:
            self.top += 1
            xy = self.G.nodes[self.top]["xy"]
            new.append(xy)
            self.by_xy[tuple(xy)] = self.top
        if new:
            self.added = np.vstack([self.added, new])
        if len(self.added) > max(64, self.REBUILD_SHARE * self.tree.n):
            self.tree = cKDTree(np.vstack([self.tree.data, self.added]))
            self.added = np.zeros((0, 2))

    def at(self, p):
        """The node exactly at ``p`` (a vertex of a block's boundary, say), or None: roads end
        exactly on their nodes' coordinates."""
        return self.by_xy.get((float(p[0]), float(p[1])))

    def on_boundary(self, face: Polygon, tolerance: float = 0.01) -> list[tuple]:
        """(node, xy) of every node within ``tolerance`` of ``face``'s outer boundary, sorted by
        id. A face is split from the block it came from, so a junction a neighbouring block's
        road has since made on the shared edge lies on that edge but is not one of the face's
        vertices. A prepared ring (its segments indexed once) picks the candidates, with twice
        the tolerance as a margin; their distance to the ring is then measured exactly."""
        x0, y0, x1, y1 = face.bounds
        centre = np.array([0.5 * (x0 + x1), 0.5 * (y0 + y1)])
        near = self.tree.query_ball_point(centre, 0.5 * math.hypot(x1 - x0, y1 - y0) + 1.0,
                                          return_sorted=False)  # a set is made of them anyway
        pts = np.vstack([self.tree.data[near], self.added])
        if len(pts) == 0:
            return []
        ring = face.exterior
        points = shapely.points(pts)
        shapely.prepare(ring)
        close = shapely.dwithin(ring, points, 2 * tolerance)
        close[close] = shapely.distance(ring, points[close]) <= tolerance
        found = {self.by_xy[(float(x), float(y))] for x, y in pts[close]}
        return sorted((n, np.asarray(self.G.nodes[n]["xy"], float)) for n in found)

    def continuation(self, node) -> np.ndarray | None:
        """:func:`_continuation` of ``node``, kept for its roads as they are: a junction lies on
        the edges of several blocks, and only a new road at it or a split of one of its roads
        (which changes its neighbours) changes its answer."""
        key = (node, *sorted(self.G.neighbors(node)))
        if key not in self.continuations:
            self.continuations[key] = _continuation(self.G, node)
        return self.continuations[key]

    def any_within(self, p: np.ndarray, radius: float) -> bool:
        """Whether a node lies closer than ``radius`` to ``p`` (exactly as an np.hypot test over
        all nodes: the tree only picks the candidates, with a margin)."""
        near = self.tree.query_ball_point(p, radius + 1e-6)
        pts = np.vstack([self.tree.data[near], self.added])
        return len(pts) > 0 and bool(np.min(np.hypot(*(pts - p).T)) < radius)


def _extended(chord: np.ndarray, by: float) -> LineString:
    """The chord lengthened at both ends, so that splitting its face cannot fail on rounding
    (the ends lie on the face boundary only to floating-point precision)."""
    head = chord[0] + by * _unit(chord[0] - chord[1])
    tail = chord[-1] + by * _unit(chord[-1] - chord[-2])
    return LineString(np.vstack([head, chord, tail]))


def _unit(v: np.ndarray) -> np.ndarray:
    return v / max(float(np.hypot(*v)), 1e-9)


def split_chord(face: Polygon, nodes: _NodePoints, field: TensorField, rng, min_edge, min_angle,
                *, roads: EdgeIndex | None = None):
    """A local road across ``face``: traced both ways from an interior point along the tensor
    axis that cuts the face's long side, clipped where it first leaves the face. A few start
    points and both axes are tried before the block is given up."""
    along, across, centre, long_side = _axes(face)
    for attempt in range(6):
        shift = 0.0 if attempt == 0 else rng.uniform(-0.3, 0.3) * long_side
        start = centre + shift * along
        if not shapely.contains_xy(face, *start):
            continue
        wanted = across if attempt < 4 else along
        d0 = choose_axis(field, start, wanted)
        halves = [_trace_in_face(face, start, d, field, roads) for d in (d0, -d0)]
        met = [line for _, line in filter(None, halves)]
        chord = _joined(face, nodes, [h and h[0] for h in halves], min_edge, min_angle, met)
        if chord is not None:
            return chord
    return None


def scattered_chord(face: Polygon, nodes: _NodePoints, field: TensorField, rng, min_edge,
                    min_angle, *, roads: EdgeIndex | None = None, tries: int = 16):
    """:func:`split_chord` from random points inside ``face``: the last resort for a large
    concave block whose centre lies outside it or whose middle chords all end too close to a
    junction (a block wrapped around dead-end trees of the skeleton). Traced across the
    field first, then along it."""
    x0, y0, x1, y1 = face.bounds
    for attempt in range(tries):
        start = np.array([rng.uniform(x0, x1), rng.uniform(y0, y1)])
        if not shapely.contains_xy(face, *start):
            continue
        d0 = choose_axis(field, start, np.array([1.0, 0.0]) if attempt % 2 else
                         np.array([0.0, 1.0]))
        halves = [_trace_in_face(face, start, d, field, roads) for d in (d0, -d0)]
        met = [line for _, line in filter(None, halves)]
        chord = _joined(face, nodes, [h and h[0] for h in halves], min_edge, min_angle, met)
        if chord is not None:
            return chord
    return None


def continuation_chord(face: Polygon, nodes: _NodePoints, field: TensorField, rng, min_edge,
                       min_angle):
    """A local road that continues a side street across ``face``: from a T-junction on the
    block's edge whose stem lies outside the block, straight on through the junction and then
    along the field to the far side. Of the T-junctions whose continuation points into the
    block, the one aimed closest to the block's centre is tried first."""
    centre = _centre(face)
    candidates = []
    for node, xy in nodes.on_boundary(face):
        if nodes.G.degree(node) != 3:
            continue
        ahead = nodes.continuation(node)
        if ahead is None or not shapely.contains_xy(face, *(xy + 2.0 * ahead)):
            continue
        off = centre - xy
        miss = abs(float(ahead[0] * off[1] - ahead[1] * off[0]))  # centre's distance from the line
        candidates.append((miss, node, xy, ahead))
    for _, node, xy, ahead in sorted(candidates, key=lambda c: c[:2])[:3]:
        traced = _trace_in_face(face, xy + 1.0 * ahead, ahead, field)
        if traced is None:
            continue
        chord = np.vstack([xy, traced[0]])
        if _ends_ok(face, nodes, chord, min_edge, min_angle, check_start=False):
            return chord
    return None


def _continuation(G: nx.Graph, node) -> np.ndarray | None:
    """The unit direction straight on from a T-junction's stem through ``node``, or None when
    no two of its three roads form a near-straight bar (a Y, not a T)."""
    xy = np.asarray(G.nodes[node]["xy"], float)
    leaving = []
    for other in sorted(G.neighbors(node)):
        # 10 m out (at most half the road), past any kink at the junction
        ahead = point_along(edge_coords(G, node, other), 10.0)
        leaving.append(_unit(np.array(ahead) - xy))
    for k, stem in enumerate(leaving):
        bar = [d for j, d in enumerate(leaving) if j != k]
        if float(bar[0] @ bar[1]) <= math.cos(math.radians(STRAIGHT_CAP)):
            return -stem
    return None


def straight_chord(face: Polygon, nodes: _NodePoints, field, rng, min_edge, min_angle, *,
                   roads: EdgeIndex | None = None):
    """A straight road across the middle of ``face``, across its long side or else along it:
    for a block that no field-following road crosses (near the centre of a radial field the
    streamlines circle, end on the side they started from, or never reach the block edge). It
    ends on the first road it meets, a dead end inside the block included (``roads``)."""
    along, across, centre, _ = _axes(face)
    for wanted in (across, along):
        halves = [_straight_in_face(face, centre, d, roads) for d in (wanted, -wanted)]
        met = [line for _, line in filter(None, halves)]
        chord = _joined(face, nodes, [h and h[0] for h in halves], min_edge, min_angle, met)
        if chord is not None:
            return chord
    return None


def _joined(face: Polygon, nodes: _NodePoints, halves: list, min_edge, min_angle, met=()):
    """The two halves traced from one start point as one chord, if both reach the block edge
    (or a road in ``met``) and :func:`_ends_ok` accepts the ends."""
    if any(h is None for h in halves):
        return None
    chord = np.vstack([halves[1][::-1], halves[0][1:]])
    return chord if _ends_ok(face, nodes, chord, min_edge, min_angle, met) else None


def _straight_in_face(face: Polygon, start, d, roads: EdgeIndex | None):
    """The straight path from ``start`` along ``d`` to the first block edge or road it meets,
    with a point every STEP metres like a traced one, and the line it ends on; None if
    ``start`` is not inside."""
    if not shapely.contains_xy(face, *start):
        return None
    x0, y0, x1, y1 = face.bounds
    path = LineString([start, start + 2.0 * (x1 - x0 + y1 - y0) * np.asarray(d, float)])
    rings = [face.exterior, *face.interiors]
    best = _first_hit(path, _crossed_lines(path, rings, roads), skip_start=True)
    if best is None:
        return None
    along, line = best
    steps = max(1, math.ceil(along / STEP))
    return np.asarray(start, float) + np.linspace(0.0, along, steps + 1)[:, None] * d, line


def _crossed_lines(path: LineString, rings: list, roads: EdgeIndex | None) -> list:
    """The ``rings`` of a block (inner rings, holes, stop a road too), then the roads in
    ``roads``, that ``path`` touches or crosses: one prepared predicate call instead of an
    overlay (``intersection``) with each block ring, most of which it misses. (The index
    already tests the roads with the same predicate.)"""
    shapely.prepare(path)
    lines = [line for line, hit in zip(rings, shapely.intersects(path, rings), strict=True) if hit]
    return lines + ([roads.lines[key] for key in roads.near(path, 0.0)] if roads else [])


def _first_hit(path: LineString, lines: list, skip_start: bool) -> tuple | None:
    """(distance along ``path``, line) of the first of ``lines`` that ``path`` meets, where
    its intersections with them lie (not at its very start, if ``skip_start``: the point a
    road sets out from may lie on a block edge); None if it meets none of them."""
    best = None
    for line in lines:
        hit = path.intersection(line)
        if hit.is_empty:
            continue
        points = shapely.points(shapely.get_coordinates(hit))
        along = float(shapely.line_locate_point(path, points).min())
        if (not skip_start or along > 1e-6) and (best is None or along < best[0]):
            best = (along, line)
    return best


def _axes(face: Polygon):
    """Unit vectors along and across the long side of the face's minimum rotated rectangle, a
    point inside the face (:func:`_centre`) and the long side's length."""
    rc = np.asarray(face.minimum_rotated_rectangle.exterior.coords)
    sides = np.diff(rc[:3], axis=0)
    lengths = np.hypot(*sides.T)
    long_side = sides[int(np.argmax(lengths))]
    along = long_side / max(np.hypot(*long_side), 1e-9)
    across = np.array([-along[1], along[0]])
    return along, across, _centre(face), lengths.max()


def _centre(face: Polygon) -> np.ndarray:
    """A point inside the face: its centroid where that is inside."""
    centroid = np.asarray(face.centroid.coords[0])
    if shapely.contains_xy(face, *centroid):
        return centroid
    return np.asarray(face.representative_point().coords[0])


def _trace_in_face(face: Polygon, start, d, field: TensorField,
                   roads: EdgeIndex | None = None):
    """Follow the field from ``start`` until the path crosses the face boundary, or the first
    road in ``roads`` (a dead end inside the block, which the face's rings do not include);
    returns the path and the line it ends on, or None.

    The path is traced in growing chunks and intersected with the boundary once per chunk (a
    shapely call per Euler step would dominate the run time)."""
    rings = [face.exterior, *face.interiors]  # inner rings: blocks hanging inside on bridges
    kept = []  # the path before the chunk being checked
    last = np.array([float(start[0]), float(start[1])])
    d = np.asarray(d, float)
    for chunk in (4, 8, 16, 32, 64, 128):
        steps, d = follow_field(field, last, d, chunk, math.radians(8.0), STEP)
        chunk_xy = np.concatenate([last[None], steps])
        path = shapely.linestrings(chunk_xy)
        best = _first_hit(path, _crossed_lines(path, rings, roads), skip_start=not kept)
        if best is not None:
            return np.vstack([*kept, _substring(path, 0.0, best[0])]), best[1]
        kept.append(chunk_xy[:-1])
        last = steps[-1]
    return None


def _substring(line: LineString, start: float, end: float) -> np.ndarray:
    """The coordinates of ``line`` from ``start`` to ``end`` metres along it."""
    return shapely.get_coordinates(shapely.ops.substring(line, start, end))


def _ends_ok(face: Polygon, nodes: _NodePoints, chord, min_edge: float, min_angle: float,
             met=(), check_start: bool = True) -> bool:
    """Both ends meet the block edge (or a road in ``met``) at a decent angle and away from
    existing junctions (the far end only, for a chord that starts at a junction)."""
    if LineString(chord).length < 3 * min_edge:
        return False
    ends = ((chord[0], chord[1]), (chord[-1], chord[-2]))
    for end, inner in ends if check_start else ends[1:]:
        if nodes.any_within(end, 2.5 * min_edge):
            return False
        point = Point(end)
        lines = [face.exterior, *face.interiors, *met]
        ring = lines[int(np.argmin(shapely.distance(lines, point)))]  # the first nearest
        s = ring.project(point)
        a, b = shapely.get_coordinates(shapely.line_interpolate_point(
            ring, [max(s - 1.0, 0), min(s + 1.0, ring.length)]))
        tangent = (b - a) / max(np.hypot(*(b - a)), 1e-9)
        road = (inner - end) / max(np.hypot(*(inner - end)), 1e-9)
        if abs(float(tangent @ road)) > math.cos(math.radians(min_angle)):
            return False
    return True


def insert_chord(
    G: nx.Graph, chord: np.ndarray, min_edge: float, index: EdgeIndex, start_node=None
) -> tuple | None:
    """Split the road(s) the chord ends on and add the chord as a local road between them
    (from ``start_node`` itself, if given: a chord that starts at a junction).

    Refused when the chord touches any road other than those it ends on (a dead-end road
    inside the block, say), so the graph stays planar without re-noding. Returns the chord's
    end nodes, or None when refused."""
    line = LineString(chord)
    if start_node is not None:  # the junction's own roads meet the chord's first metres
        line = LineString(_substring(line, 2.0, line.length))
    touching = index.near(line, 0.5)
    if not 1 <= len(touching) <= (1 if start_node is not None else 2):
        return None
    nodes = [] if start_node is None else [start_node]
    for point in (chord[0], chord[-1])[len(nodes):]:
        # Look the edge up again for the second end: splitting for the first may have cut it.
        near = index.near(Point(point), 1.0)
        if not near:
            return None
        nodes.append(split_edge_at(G, near[0], point, min_edge, index))
    u, v = nodes
    if u == v:
        return None
    if G.has_edge(u, v):
        # Both ends landed on one road, next to each other: a shape node in the middle of the
        # chord keeps the graph simple (no two roads between the same pair of nodes).
        k = len(chord) // 2
        m = index.new_node_id()
        G.add_node(m, xy=(float(chord[k][0]), float(chord[k][1])))
        for a, b, part in ((u, m, chord[: k + 1]), (m, v, chord[k:])):
            add_road(G, a, b, part, "local")
            index.add(a, b)
        return u, v
    add_road(G, u, v, chord, "local")
    index.add(u, v)
    return u, v


def split_edge_at(G: nx.Graph, edge, point, tolerance: float, index: EdgeIndex):
    """Insert a node on road ``edge`` at ``point`` (or reuse an end node within tolerance)."""
    u, v = edge
    coords = edge_coords(G, u, v)
    line = LineString(coords)
    s = line.project(Point(point))
    if s < tolerance:
        return u
    if line.length - s < tolerance:
        return v
    cls = G.edges[u, v]["road_class"]
    first, second = _substring(line, 0.0, s), _substring(line, s, line.length)
    node = index.new_node_id()
    G.add_node(node, xy=tuple(second[0]))
    index.remove(u, v)
    G.remove_edge(u, v)
    add_road(G, u, node, first, cls)
    add_road(G, node, v, second, cls)
    index.add(u, node)
    index.add(node, v)
    return node


def prune_to_density(G: nx.Graph, target: int, stub: float = 0.0) -> None:
    """Remove non-bridge local roads, shortest first, while above ``target`` + 1 road nodes
    (counted as the clean-up will leave them: :func:`stub_loss`).

    One pass over the roads sorted once: removing a road only lowers degrees and only turns
    roads into bridges, so a road that cannot go now never can, and each road is tested with a
    local search for another path between its ends rather than a bridge search of the graph."""
    count = road_node_count(G) - stub_loss(G, stub)
    candidates = sorted(
        (edge_length(G, u, v), u, v) for u, v in G.edges if G.edges[u, v]["road_class"] != "arterial"
    )
    for _, u, v in candidates:
        if count <= target + 1:
            return
        if G.degree(u) < 3 or G.degree(v) < 3 or not _on_cycle(G, u, v):
            continue
        G.remove_edge(u, v)
        count += sum((G.degree(n) != 2) - (G.degree(n) + 1 != 2) for n in (u, v))


def _on_cycle(G: nx.Graph, u, v) -> bool:
    """Whether u and v stay connected without the road u-v (it is not a bridge): a
    bidirectional breadth-first search, which stays local around a road on a small cycle."""
    seen = ({u}, {v})
    fronts = ([u], [v])
    while fronts[0] and fronts[1]:
        side = 0 if len(fronts[0]) <= len(fronts[1]) else 1
        nxt = []
        for a in fronts[side]:
            for b in G.neighbors(a):
                if {a, b} == {u, v}:
                    continue
                if b in seen[1 - side]:
                    return True
                if b not in seen[side]:
                    seen[side].add(b)
                    nxt.append(b)
        fronts[side][:] = nxt
    return False
