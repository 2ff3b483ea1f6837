"""Polylines onto the map raster (road fields, cost maps, A* targets)."""

from __future__ import annotations

import itertools
import math

import numba as nb
import numpy as np

from .compiled import F8, F8_2D, I8_1D, compiled


def sample_polyline(line: np.ndarray, spacing: float) -> np.ndarray:
    """Points along ``line`` at most ``spacing`` apart, both ends included."""
    line = np.asarray(line, dtype=float)
    s = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(line, axis=0).T))])
    marks = np.linspace(0.0, s[-1], max(2, int(np.ceil(s[-1] / spacing)) + 1))
    return np.column_stack([np.interp(marks, s, line[:, 0]), np.interp(marks, s, line[:, 1])])


def rasterise_polylines(lines, shape: tuple[int, int], res: float) -> np.ndarray:
    """Boolean mask of the raster cells (``res`` metres each) that the polylines pass through."""
    mask = np.zeros(shape, dtype=bool)
    i, j = polyline_cells(lines, shape, res)
    mask[i, j] = True
    return mask


def rasterise_window(cells, window) -> np.ndarray:
    """The window (i0, i1, j0, j1) of the mask whose True cells are ``cells`` (rows, columns
    from :func:`polyline_cells`), without the whole map's raster (one per dead end, each
    searching a small window)."""
    i0, i1, j0, j1 = window
    mask = np.zeros((i1 - i0, j1 - j0), dtype=bool)
    i, j = cells
    inside = (i >= i0) & (i < i1) & (j >= j0) & (j < j1)
    mask[i[inside] - i0, j[inside] - j0] = True
    return mask


def polyline_cells(lines, shape: tuple[int, int], res: float) -> tuple[np.ndarray, np.ndarray]:
    """Row and column of a point every half cell along the polylines, clipped to the raster."""
    each = polyline_cells_each(lines, shape, res)
    if not each:
        return np.zeros(0, int), np.zeros(0, int)
    return np.concatenate([i for i, _ in each]), np.concatenate([j for _, j in each])


def polyline_cells_each(lines, shape: tuple[int, int], res: float) -> list[tuple]:
    """:func:`polyline_cells` of each polyline (of two points or more) on its own, all sampled
    in one compiled pass (a 10 km map has 9,000 roads)."""
    lines = [np.asarray(line, dtype=float) for line in lines if len(line) >= 2]
    if not lines:
        return []
    offsets = np.r_[0, np.cumsum([len(line) for line in lines])]
    pts, cuts = _samples(np.ascontiguousarray(np.concatenate(lines)), offsets, res / 2)
    ny, nx = shape
    i = np.clip((pts[:, 1] / res).astype(int), 0, ny - 1)
    j = np.clip((pts[:, 0] / res).astype(int), 0, nx - 1)
    cuts = cuts.tolist()
    return [(i[a:b], j[a:b]) for a, b in itertools.pairwise(cuts)]


@compiled(nb.types.Tuple((F8_2D, I8_1D))(F8_2D, I8_1D, F8))
def _samples(points, offsets, spacing):
    """:func:`sample_polyline` of each line ``points[offsets[k]:offsets[k + 1]]``, stacked, and
    where each line's samples start. The same float operations in the same order as numpy's
    ``cumsum``, ``linspace`` and ``interp`` there, so the same bits."""
    n = len(offsets) - 1
    along = np.empty(len(points))  # distance from each line's start, as cumsum sums it
    cuts = np.zeros(n + 1, dtype=np.int64)
    for k in range(n):
        a, b = offsets[k], offsets[k + 1]
        along[a] = 0.0
        for m in range(a, b - 1):
            along[m + 1] = along[m] + math.hypot(points[m + 1, 0] - points[m, 0],
                                                 points[m + 1, 1] - points[m, 1])
        cuts[k + 1] = cuts[k] + max(2, math.ceil(along[b - 1] / spacing) + 1)
    out = np.empty((cuts[n], 2))
    for k in range(n):
        a, b = offsets[k], offsets[k + 1]
        total, count = along[b - 1], cuts[k + 1] - cuts[k]
        step = total / (count - 1)
        j = a
        for i in range(count):
            if i == count - 1:
                x = total
            elif step == 0.0:
                x = i / (count - 1) * total
            else:
                x = i * step
            while j + 1 < b and along[j + 1] <= x:
                j += 1
            for d in range(2):
                if j == b - 1 or along[j] == x:
                    out[cuts[k] + i, d] = points[j, d]
                else:
                    slope = (points[j + 1, d] - points[j, d]) / (along[j + 1] - along[j])
                    out[cuts[k] + i, d] = slope * (x - along[j]) + points[j, d]
    return out, cuts
