"""Turn traced polylines into a planar road graph (paper §III-C).

Planarity is guaranteed by noding: shapely's union, snap-rounded to a 1 cm grid, splits every
polyline wherever it meets another, so every crossing of two roads becomes a junction (and a
road that ends a hair off another meets it too). The clean-up (:mod:`.cleanup`) then removes what a road
engineer would not draw.
"""

from __future__ import annotations

import networkx as nx
import numpy as np
import shapely
import shapely.ops

from ..roadgraph import (
    ROAD_CLASSES,
    add_road,
    new_road_graph,
)

GRID = 0.01  # noding precision, metres
CLASS_RANK = {name: rank for rank, name in enumerate(reversed(ROAD_CLASSES))}  # local=0


def higher_class(a: str, b: str) -> str:
    return a if CLASS_RANK[a] >= CLASS_RANK[b] else b


def build_planar_graph(roads: list[tuple[np.ndarray, str]], width: float, height: float):
    """Node all polylines against each other and build the graph of the pieces.

    Each piece becomes the road between the nodes at its rounded ends, in order of (first
    point, last point, length); a second piece between the same two nodes, or one closing a
    loop, goes through :func:`add_piece`. Everything up to that is done in bulk over all
    pieces: a 10 km map has 5,000 of them, and the graph is rebuilt after every reconnection
    and fill round."""
    G = new_road_graph(width, height)
    kept = [(np.asarray(c, float).reshape(-1, 2), cls) for c, cls in roads if len(c) >= 2]
    if not kept:
        return G
    lines = _linestrings([c for c, _ in kept])
    long_enough = shapely.length(lines) > GRID
    kept = [road for road, ok in zip(kept, long_enough.tolist(), strict=True) if ok]
    if not kept:
        return G
    noded = shapely.union_all(lines[long_enough], grid_size=GRID)  # snap-rounded noding
    pieces = shapely.get_parts(noded)
    xy, owner = shapely.get_coordinates(pieces, return_index=True)
    first = np.flatnonzero(np.r_[True, owner[1:] != owner[:-1]])
    last = np.r_[first[1:], len(owner)] - 1
    lengths = shapely.length(pieces)
    order = np.lexsort((lengths, xy[last, 1], xy[last, 0], xy[first, 1], xy[first, 0]))
    classes = _piece_classes(pieces, lines[long_enough], [cls for _, cls in kept])
    ends = np.empty((2 * len(pieces), 2))  # start and end of each piece, interleaved
    ends[0::2], ends[1::2] = _rounded(xy[first]), _rounded(xy[last])
    node_of, node_xy = _unique_points(ends)
    for nid, key in enumerate(node_xy):
        G.add_node(nid, xy=key)
    snapped = xy.copy()  # add_road's snapping of each road's ends onto its nodes
    snapped[first] = np.array(node_xy)[node_of[0::2]]
    snapped[last] = np.array(node_xy)[node_of[1::2]]
    bounds = np.r_[first, len(owner)].tolist()
    seen: set = set()
    batch = []
    for k in order.tolist():
        u, v = int(node_of[2 * k]), int(node_of[2 * k + 1])
        a, b = bounds[k], bounds[k + 1]
        pair = (u, v) if u < v else (v, u)
        if u != v and pair not in seen:
            seen.add(pair)
            batch.append((u, v, {"coords": snapped[a:b].copy(), "start": u,
                                 "road_class": classes[k]}))
            continue
        G.add_edges_from(batch)
        batch = []
        add_piece(G, u, v, xy[a:b].tolist(), classes[k])
    G.add_edges_from(batch)
    return G


def _linestrings(coords: list) -> np.ndarray:
    """The polylines as LineStrings, from one shapely call."""
    return shapely.linestrings(np.concatenate(coords),
                               indices=np.repeat(np.arange(len(coords)), [len(c) for c in coords]))


def road_lines(roads: list) -> list:
    """The polylines of ``roads`` (``(u, v, data)``, as :func:`~roadweaver_sumo.roadgraph.edge_list`
    gives them) as LineStrings, from one shapely call."""
    return _linestrings([data["coords"] for _, _, data in roads]).tolist() if roads else []


def _piece_classes(pieces: np.ndarray, lines: np.ndarray, classes: list[str]) -> list[str]:
    """The road class of every piece: the best class of the ``lines`` passing within 5 cm of
    its middle."""
    mids = shapely.line_interpolate_point(pieces, 0.5, normalized=True)
    piece, line = shapely.STRtree(lines).query(mids, predicate="dwithin", distance=0.05)
    rank = np.array([CLASS_RANK[cls] for cls in classes])
    best = np.zeros(len(pieces), dtype=int)
    np.maximum.at(best, piece, rank[line])
    names = sorted(CLASS_RANK, key=CLASS_RANK.__getitem__)
    return [names[r] for r in best.tolist()]


def _rounded(points: np.ndarray) -> np.ndarray:
    """Python's ``round(x, 2)`` of every coordinate. The union's vertices lie on the 0.01 grid
    already (``rint(100 x) / 100 == x``: x is the double nearest k/100, which ``round`` keeps);
    any other goes through ``round`` itself."""
    off = np.rint(points * 100) / 100 != points
    out = points.copy()
    out[off] = [round(x, 2) for x in points[off].tolist()]
    return out


def _unique_points(points: np.ndarray) -> tuple[np.ndarray, list[tuple]]:
    """Number the distinct points in (x, y) order: each point's number, and each number's
    point (as Python floats, the first of equal ones: ``sorted(dict.fromkeys(...))``)."""
    order = np.lexsort((points[:, 1], points[:, 0]))  # stable: equal points keep their order
    ranked = points[order]
    new = np.r_[True, (ranked[1:] != ranked[:-1]).any(axis=1)]
    number = np.empty(len(points), dtype=int)
    number[order] = np.cumsum(new) - 1
    return number, [tuple(p) for p in ranked[new].tolist()]


def add_piece(G: nx.Graph, u: int, v: int, coords, cls: str) -> None:
    """Add a road u-v. A second road between the same nodes gets a shape node in its middle, a
    closed loop two, so the graph stays simple (SUMO and the lane builder need distinct node
    pairs). The nodes of ``G`` are numbered 0..n-1, as :func:`build_planar_graph` numbers
    them: a shape node is number n."""
    if u != v and not G.has_edge(u, v):
        add_road(G, u, v, coords, cls)
        return
    line = shapely.LineString(coords)
    cuts = [0.5] if u != v else [1 / 3, 2 / 3]
    ends = [u]
    for frac in cuts:
        p = line.interpolate(frac, normalized=True)
        m = G.number_of_nodes()
        G.add_node(m, xy=(float(p.x), float(p.y)))
        ends.append(m)
    ends.append(v)
    marks = [0.0] + [f * line.length for f in cuts] + [line.length]
    for a, b, s0, s1 in zip(ends[:-1], ends[1:], marks[:-1], marks[1:]):
        add_road(G, a, b, np.asarray(shapely.ops.substring(line, s0, s1).coords), cls)

