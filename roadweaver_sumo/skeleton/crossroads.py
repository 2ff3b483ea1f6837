"""Crossroads where a grid has them: the learned skeleton's side streets continued across the
road they meet (issue 35, "4-way crossings where real grids have them"; paper §III-B, graph
reconstruction).

The decoded road field of a grid draws crossings as well as T-junctions, but the vectoriser
traces a crossing whose four arms do not quite meet as two T-junctions a block apart or as one
T, and the expansion's fill adds T-junctions of its own. Learned `grid` maps had 0.18 of their
junctions four-way and 0.65 of junction arms running straight on, where the grid-labelled city
centres of ``../shared/data/cgcc`` have 0.25-0.55 and 0.72-0.86 (p10-p90). A T-junction's side
street (its stem) is continued straight on across the through road until it meets the next
road, within :data:`REACH_BLOCKS` block sizes, with a probability of the condition's gridness
prior: a grid asked for (0.67) becomes one of crossroads, an organic town (0.07) keeps its
T-junctions.
"""

from __future__ import annotations

import numpy as np
import shapely

#: two arms of a junction form its through road when they run on within this (degrees)
THROUGH_TOL_DEG = 30.0
#: an arm's direction is taken to the point this far along it (metres)
PROBE_M = 25.0
#: a continuation is at most this many block sizes long, and at least MIN_M
REACH_BLOCKS = 1.5
MIN_M = 15.0


def stem_continuations(lines: list[np.ndarray], block_m: float, gridness: float,
                       rng: np.random.Generator) -> list[np.ndarray]:
    """Straight roads (two points each) continuing the stems of the T-junctions of ``lines``
    (skeleton polylines in metres, which meet at their ends) across the through road, each
    T taken with probability ``gridness``."""
    if not lines:
        return []
    roads = np.array([shapely.LineString(line) for line in lines])
    tree = shapely.STRtree(roads)
    arms: dict[tuple, list[np.ndarray]] = {}
    for line in lines:
        for end, rest in ((line[0], line), (line[-1], line[::-1])):
            key = (round(float(end[0]), 3), round(float(end[1]), 3))
            arms.setdefault(key, []).append(_leaving(rest))
    out = []
    for point, leaving in sorted(arms.items()):
        stem = _stem(leaving)
        if stem is None or rng.random() >= gridness:
            continue
        start = np.array(point)
        hit = _first_hit(start, -stem, REACH_BLOCKS * block_m, roads, tree)
        if hit is not None:
            out.append(np.array([start, hit]))
    return out


def _stem(leaving: list[np.ndarray]) -> np.ndarray | None:
    """The direction of a T-junction's side street, given its three arms' directions: the arm
    that is not part of the straightest pair, if that pair runs on within THROUGH_TOL_DEG."""
    if len(leaving) != 3:
        return None
    best = None
    for i, j, other in ((0, 1, 2), (0, 2, 1), (1, 2, 0)):
        deviation = 180.0 - np.degrees(np.arccos(np.clip(leaving[i] @ leaving[j], -1.0, 1.0)))
        if deviation <= THROUGH_TOL_DEG and (best is None or deviation < best[0]):
            best = (deviation, other)
    return None if best is None else leaving[best[1]]


def _leaving(line: np.ndarray) -> np.ndarray:
    """Unit direction of ``line`` from its first point to the point PROBE_M along it."""
    geom = shapely.LineString(line)
    d = np.asarray(geom.interpolate(min(PROBE_M, geom.length)).coords[0]) - line[0]
    return d / max(float(np.hypot(*d)), 1e-9)


def _first_hit(start: np.ndarray, direction: np.ndarray, reach: float, roads: np.ndarray,
               tree: shapely.STRtree) -> np.ndarray | None:
    """Where the ray from ``start`` first meets a road, if no nearer than MIN_M and within
    ``reach``."""
    ray = shapely.LineString([start + MIN_M * direction, start + reach * direction])
    best = None
    for k in tree.query(ray, predicate="intersects").tolist():
        for p in shapely.get_parts(shapely.intersection(ray, roads[k])):
            if p.geom_type == "Point":
                d = float(np.hypot(*(np.asarray(p.coords[0]) - start)))
                if best is None or d < best[0]:
                    best = (d, np.asarray(p.coords[0]))
    return None if best is None else best[1]
