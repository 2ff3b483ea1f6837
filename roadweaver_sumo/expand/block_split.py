"""Splitting a block of the density fill (paper §III-C) by the chord just inserted into it.

The fill keeps its blocks in a heap, largest first, and the parts a chord cuts a block into go
back in. They are found from the block alone (its boundary noded with the chord and, where the
chord ends on a dead-end road inside the block, the roads joined to it), not from the faces of
the whole graph.
"""

from __future__ import annotations

import numpy as np
import shapely
from shapely.geometry import LineString, Polygon

from .edge_index import EdgeIndex
from .node_points import unit


def split_face(face: Polygon, chord: np.ndarray, ends: tuple, index: EdgeIndex) -> list[Polygon]:
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


def _extended(chord: np.ndarray, by: float) -> LineString:
    """The chord lengthened at both ends, so that splitting its face cannot fail on rounding
    (the ends lie on the face boundary only to floating-point precision)."""
    head = chord[0] + by * unit(chord[0] - chord[1])
    tail = chord[-1] + by * unit(chord[-1] - chord[-2])
    return LineString(np.vstack([head, chord, tail]))
