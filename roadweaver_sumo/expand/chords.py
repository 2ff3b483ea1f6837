"""Chords of the density fill (paper §III-C): the local road that splits a block.

A chord is traced through the same tensor field as the growth (the Euler steps of
:func:`..streamlines.follow_field`) from a point inside the block to its edge both ways, or
continues a side street from a T-junction on the block's edge; a straight one is the fallback
where the field circles. It is accepted only if its ends meet the block's edge at a decent
angle and away from existing junctions (:func:`_ends_ok`; the far end only, for a chord that
starts at a junction).
"""

from __future__ import annotations

import math

import numpy as np
import shapely
import shapely.ops
from shapely.geometry import LineString, Point, Polygon

from ..streamlines import choose_axis, follow_field
from ..tensor_field import TensorField
from .edge_index import EdgeIndex
from .node_points import NodePoints

STEP = 20.0  # metres per Euler step of a fill road (locals are short and gently curved)


def split_chord(face: Polygon, nodes: NodePoints, field: TensorField, rng, min_edge, min_angle,
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
        chord = _field_chord(face, nodes, field, start, wanted, min_edge, min_angle, roads)
        if chord is not None:
            return chord
    return None


def scattered_chord(face: Polygon, nodes: NodePoints, field: TensorField, rng, min_edge,
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
        wanted = np.array([1.0, 0.0]) if attempt % 2 else np.array([0.0, 1.0])
        chord = _field_chord(face, nodes, field, start, wanted, min_edge, min_angle, roads)
        if chord is not None:
            return chord
    return None


def _field_chord(face: Polygon, nodes: NodePoints, field: TensorField, start, wanted,
                 min_edge, min_angle, roads: EdgeIndex | None):
    """The chord traced from ``start`` both ways along the field's axis closest to ``wanted``
    (:func:`_joined`), or None."""
    d0 = choose_axis(field, start, wanted)
    halves = [_trace_in_face(face, start, d, field, roads) for d in (d0, -d0)]
    met = [line for _, line in filter(None, halves)]
    return _joined(face, nodes, [h and h[0] for h in halves], min_edge, min_angle, met)


def continuation_chord(face: Polygon, nodes: NodePoints, field: TensorField, rng, min_edge,
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


def straight_chord(face: Polygon, nodes: NodePoints, field, rng, min_edge, min_angle, *,
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


def _joined(face: Polygon, nodes: NodePoints, halves: list, min_edge, min_angle, met=()):
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
            return np.vstack([*kept, substring_coords(path, 0.0, best[0])]), best[1]
        kept.append(chunk_xy[:-1])
        last = steps[-1]
    return None


def substring_coords(line: LineString, start: float, end: float) -> np.ndarray:
    """The coordinates of ``line`` from ``start`` to ``end`` metres along it."""
    return shapely.get_coordinates(shapely.ops.substring(line, start, end))


def _ends_ok(face: Polygon, nodes: NodePoints, chord, min_edge: float, min_angle: float,
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
