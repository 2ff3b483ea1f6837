"""Square training tiles cut from a large road graph, with rotations and shifted crops.

Roads leaving a tile are clipped at its border, where they become dead ends: a tile graph looks
like any real map extract, and the model learns that roads run off the map. Tiles mostly without
roads (open country, the sea, the outside of a clipped extract) are skipped by a coverage test.
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Sequence
from dataclasses import dataclass

import networkx as nx
import numpy as np
import shapely
from shapely.strtree import STRtree

from ..roadgraph import add_road, new_road_graph
from .build import relabel_consecutive
from .sampling import sample_roads

COVERAGE_CELL_M = 100.0
COVERAGE_RADIUS_M = 50.0
#: Default share of covered cells below which a tile is skipped (see docs/data.md for the choice).
MIN_COVERAGE = 0.5
_SNAP_M = 1e-3
_FIT_M = 1.0


@dataclass(frozen=True)
class Tile:
    """A tile graph in its own frame [0, size]², and where it came from in the source frame.

    ``base`` is the graph as cut; ``graph`` is ``base`` turned by ``quarter_turns`` x 90°, made
    on demand (a consumer that rotates rasters instead never pays for it).
    """

    base: nx.Graph
    quarter_turns: int
    centre: tuple[float, float]
    angle_deg: float
    shift: tuple[float, float]
    coverage: float

    @property
    def graph(self) -> nx.Graph:
        return rotate_tile(self.base, self.quarter_turns) if self.quarter_turns else self.base


@dataclass(frozen=True)
class EdgeIndex:
    """The source graph's edges as shapely lines in an STR tree (built once per source graph)."""

    edges: list
    lines: np.ndarray
    tree: STRtree


def edge_index(G: nx.Graph) -> EdgeIndex:
    """Spatial index over the edges of ``G`` for repeated tile cutting."""
    edges = list(G.edges)
    lines = np.array([shapely.LineString(G.edges[e]["coords"]) for e in edges], dtype=object)
    return EdgeIndex(edges, lines, STRtree(lines))


def coverage(G: nx.Graph, cell_m: float = COVERAGE_CELL_M,
             radius_m: float = COVERAGE_RADIUS_M) -> float:
    """Share of ``cell_m`` cells of the map whose centre lies within ``radius_m`` of a road.

    With the defaults this is about the share of the map within 50 m of a road: close to 1 in
    towns and suburbs, under 0.3 in farmland with roads a kilometre apart.
    """
    w, h = G.graph["width"], G.graph["height"]
    xs = np.arange(cell_m / 2, w, cell_m)
    ys = np.arange(cell_m / 2, h, cell_m)
    X, Y = np.meshgrid(xs, ys)
    cells = np.column_stack([X.ravel(), Y.ravel()])
    dist, _ = sample_roads(G, radius_m / 5).nearest(cells, radius_m + 1e-6)  # "within": <=
    return float(np.isfinite(dist).mean()) if dist.size else 0.0


def _rotation(angle_deg: float) -> np.ndarray:
    a = math.radians(angle_deg)
    c, s = math.cos(a), math.sin(a)
    if angle_deg % 90 == 0:  # exact, so 90° rotations of a tile are exact too
        c, s = round(c), round(s)
    return np.array([[c, -s], [s, c]])


def _turn(coords: np.ndarray, offset, rot: np.ndarray, size: float) -> np.ndarray:
    return (coords - offset) @ rot.T + size / 2


def _clip_pieces(G, index, centre, size, angle_deg):
    """(edge ends, their tile positions, part) for every part of every edge inside the tile.

    Edges wholly inside are passed through; only those crossing the border go through shapely.
    """
    reach = size / 2 * (1.0 if angle_deg % 90 == 0 else math.sqrt(2)) + 1.0
    cx, cy = centre
    hits = np.sort(index.tree.query(shapely.box(cx - reach, cy - reach, cx + reach, cy + reach)))
    if len(hits) == 0:
        return
    edges = [index.edges[k] for k in hits]
    polylines = [G.edges[e]["coords"] for e in edges]
    lengths = np.array([len(c) for c in polylines])
    turned = _turn(np.vstack(polylines), centre, _rotation(angle_deg), size)
    inside = np.all((turned >= 0.0) & (turned <= size), axis=1)
    whole = np.logical_and.reduceat(inside, np.cumsum(lengths) - lengths)
    parts = np.split(turned, np.cumsum(lengths)[:-1])
    cross = np.flatnonzero(~whole)
    window = shapely.box(0, 0, size, size)
    lines = np.array([shapely.LineString(parts[i]) for i in cross], dtype=object)
    clipped = dict(zip(cross, shapely.line_merge(shapely.intersection(lines, window))))
    for i, (u, v) in enumerate(edges):
        start = G.edges[u, v]["start"]
        ends = (start, v if start == u else u)
        if whole[i]:
            yield ends, None, parts[i]
            continue
        for part in shapely.get_parts(clipped[i]):
            if part.geom_type == "LineString" and part.length > 0:
                yield ends, parts[i][[0, -1]], np.asarray(part.coords)


def cut_tile(G: nx.Graph, centre: tuple[float, float], size: float, angle_deg: float = 0.0,
             index: EdgeIndex | None = None) -> nx.Graph:
    """The ``size`` x ``size`` tile centred on ``centre``, its content turned ``angle_deg``
    counter-clockwise; clip points become dead-end nodes. Nodes are renumbered 0..n-1."""
    index = index or edge_index(G)
    T = new_road_graph(size, size)
    border: dict[tuple[float, float], tuple] = {}
    for ends, end_xy, part in _clip_pieces(G, index, centre, size, angle_deg):
        if end_xy is None:  # the whole edge: its ends are the original nodes
            nodes = list(ends)
        else:
            nodes = []
            for p in (part[0], part[-1]):
                hit = [n for n, q in zip(ends, end_xy) if np.abs(p - q).max() < _SNAP_M]
                nodes.append(hit[0] if hit else border.setdefault(
                    (round(p[0], 3), round(p[1], 3)), ("border", len(border))))
        for n, p in zip(nodes, (part[0], part[-1])):
            if n not in T:
                T.add_node(n, xy=(float(p[0]), float(p[1])))
        if nodes[0] != nodes[1] and not T.has_edge(*nodes):
            add_road(T, nodes[0], nodes[1], part, G.edges[ends]["road_class"])
    return relabel_consecutive(T)


def rotate_tile(T: nx.Graph, k: int) -> nx.Graph:
    """Tile graph ``T`` turned ``k`` x 90° counter-clockwise about its centre (exact)."""
    size = T.graph["width"]
    rot = _rotation(90.0 * k)
    centre = np.array([size / 2, size / 2])
    R = T.copy()
    nodes = list(T.nodes)
    if nodes:
        xy = _turn(np.array([T.nodes[n]["xy"] for n in nodes]), centre, rot, size)
        for n, p in zip(nodes, xy.tolist()):
            R.nodes[n]["xy"] = tuple(p)
    for u, v, data in R.edges(data=True):
        data["coords"] = _turn(data["coords"], centre, rot, size)
    return R


def tile_centres(width: float, height: float, tile_m: float,
                 shifts: Sequence[float]) -> Iterator[tuple[tuple[float, float], tuple]]:
    """Centres of a grid of whole tiles inside [0, W] x [0, H], once per (x, y) shift pair
    (shifts are fractions of a tile), with the shift pair. A tile may overhang the map by up
    to 1 m (projection round-off)."""
    for sy in shifts:
        for sx in shifts:
            xs = np.arange(sx * tile_m + tile_m / 2, width - tile_m / 2 + _FIT_M, tile_m)
            ys = np.arange(sy * tile_m + tile_m / 2, height - tile_m / 2 + _FIT_M, tile_m)
            for cy in ys:
                for cx in xs:
                    yield (float(cx), float(cy)), (sx, sy)


def iter_tiles(G: nx.Graph, tile_m: float = 2000.0, *,
               rotations: Sequence[float] = (0, 90, 180, 270), shifts: Sequence[float] = (0.0, 0.5),
               random_rotations: int = 0, min_coverage: float = MIN_COVERAGE,
               seed: int | Sequence[int] = 0) -> Iterator[Tile]:
    """Every covered tile of ``G`` in each rotation, plus ``random_rotations`` tiles at seeded
    random angles per covered crop. Deterministic for a given graph and seed."""
    index = edge_index(G)
    rng = np.random.default_rng(seed)
    for centre, shift in tile_centres(G.graph["width"], G.graph["height"], tile_m, shifts):
        base = cut_tile(G, centre, tile_m, 0.0, index)
        cov = coverage(base)
        if cov < min_coverage:
            continue
        angles = [float(a) for a in rotations if a % 90 != 0]
        angles += [float(a) for a in rng.uniform(0.0, 360.0, random_rotations)]
        for angle in rotations:
            if angle % 90 == 0:
                yield Tile(base, int(angle // 90) % 4, centre, float(angle), shift, cov)
        for angle in angles:
            tile = cut_tile(G, centre, tile_m, angle, index)
            cov_r = coverage(tile)
            if cov_r >= min_coverage:
                yield Tile(tile, 0, centre, angle, shift, cov_r)
