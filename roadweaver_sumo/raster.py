"""Polylines onto the map raster (road fields, cost maps, A* targets)."""

from __future__ import annotations

import numpy as np


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
    """:func:`polyline_cells` of each polyline (of two points or more) on its own."""
    ny, nx = shape
    cells = []
    for line in lines:
        if len(line) < 2:
            continue
        pts = sample_polyline(line, res / 2)
        cells.append((np.clip((pts[:, 1] / res).astype(int), 0, ny - 1),
                      np.clip((pts[:, 0] / res).astype(int), 0, nx - 1)))
    return cells
