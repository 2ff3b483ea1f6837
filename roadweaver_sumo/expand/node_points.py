"""The junctions of the road graph as the density fill (paper §III-C) asks about them.

Every chord end asks whether a junction lies near it, every block which junctions lie on its
edge, and every T-junction on a block's edge which way its side street runs on straight
through it (:func:`_continuation`). :class:`NodePoints` answers from a k-d tree over the
nodes and a cache of those directions, and takes in the nodes the fill adds.
"""

from __future__ import annotations

import math

import networkx as nx
import numpy as np
import shapely
from scipy.spatial import cKDTree
from shapely.geometry import Polygon

from ..roadgraph import edge_coords
from .junction_angles import point_along

STRAIGHT_CAP = 150.0  # degrees: the two roads of a T's bar are at least this close to straight


class NodePoints:
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


def _continuation(G: nx.Graph, node) -> np.ndarray | None:
    """The unit direction straight on from a T-junction's stem through ``node``, or None when
    no two of its three roads form a near-straight bar (a Y, not a T)."""
    xy = np.asarray(G.nodes[node]["xy"], float)
    leaving = []
    for other in sorted(G.neighbors(node)):
        # 10 m out (at most half the road), past any kink at the junction
        ahead = point_along(edge_coords(G, node, other), 10.0)
        leaving.append(unit(np.array(ahead) - xy))
    for k, stem in enumerate(leaving):
        bar = [d for j, d in enumerate(leaving) if j != k]
        if float(bar[0] @ bar[1]) <= math.cos(math.radians(STRAIGHT_CAP)):
            return -stem
    return None


def unit(v: np.ndarray) -> np.ndarray:
    return v / max(float(np.hypot(*v)), 1e-9)
