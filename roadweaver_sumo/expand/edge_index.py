"""A spatial index over the roads of a graph that is being edited (shapely's STRtree is static)."""

from __future__ import annotations

import math
from collections import defaultdict

import networkx as nx
import numpy as np
import shapely
from shapely.geometry import LineString

_NO_ROADS = frozenset()  # what a cell no road overlaps holds


def edge_key(u, v) -> tuple:
    return (u, v) if u <= v else (v, u)


class EdgeIndex:
    """Uniform grid of cells, each listing the roads whose bounding box overlaps it."""

    def __init__(self, G: nx.Graph, cell: float = 100.0):
        self.G = G
        self.cell = cell
        self.cells: dict[tuple[int, int], set] = defaultdict(set)
        self.lines: dict[tuple, LineString] = {}
        self.add_many(list(G.edges))
        self._top = max(G.nodes, default=-1)

    def new_node_id(self) -> int:
        """``max(G.nodes) + 1`` without scanning every node (a scan per split would make the
        density fill quadratic). Exact while nodes are only added with the next id, as the
        fill does, and none removed."""
        while self._top + 1 in self.G:
            self._top += 1
        self._top += 1
        return self._top

    def _cells(self, bounds, pad: float = 0.0):
        x0, y0, x1, y1 = bounds
        for cx in range(math.floor((x0 - pad) / self.cell), math.floor((x1 + pad) / self.cell) + 1):
            for cy in range(
                math.floor((y0 - pad) / self.cell), math.floor((y1 + pad) / self.cell) + 1
            ):
                yield cx, cy

    def add_many(self, edges: list[tuple]) -> None:
        """:meth:`add` for each of ``edges``, their lines made in one call (one each took
        most of the time of indexing a whole graph)."""
        if not edges:
            return
        coords = [self.G.edges[e]["coords"] for e in edges]
        which = np.repeat(np.arange(len(coords)), [len(c) for c in coords])
        lines = shapely.linestrings(np.concatenate(coords), indices=which)
        for (u, v), line, bounds in zip(edges, lines, shapely.bounds(lines).tolist(),
                                        strict=True):
            self._insert(edge_key(u, v), line, bounds)

    def add(self, u, v) -> None:
        line = LineString(self.G.edges[u, v]["coords"])
        self._insert(edge_key(u, v), line, line.bounds)

    def _insert(self, key, line: LineString, bounds) -> None:
        self.lines[key] = line
        for c in self._cells(bounds):
            self.cells[c].add(key)

    def remove(self, u, v) -> None:
        key = edge_key(u, v)
        line = self.lines.pop(key)
        for c in self._cells(line.bounds):
            self.cells[c].discard(key)

    def near(self, geom, distance: float) -> list[tuple]:
        """Roads within ``distance`` of ``geom``, nearest first (ties by id: deterministic)."""
        found: set = set()
        for c in self._cells(shapely.bounds(geom).tolist(), pad=distance):
            found |= self.cells.get(c, _NO_ROADS)
        keys = sorted(found)
        if not keys:
            return []
        lines = np.array([self.lines[k] for k in keys])
        if distance == 0.0:
            # "touches or crosses": a prepared intersects test is exact and, against a big
            # block polygon, many times cheaper than measuring each distance (which is 0 here)
            shapely.prepare(geom)
            return [k for k, hit in zip(keys, shapely.intersects(geom, lines), strict=True) if hit]
        dist = shapely.distance(lines, geom)
        order = np.argsort(dist, kind="stable")
        return [keys[k] for k in order if dist[k] <= distance]
