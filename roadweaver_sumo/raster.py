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
    lines = [line for line in lines if len(line) >= 2]
    if not lines:
        return np.zeros(0, int), np.zeros(0, int)
    pts = np.vstack([sample_polyline(line, res / 2) for line in lines])
    ny, nx = shape
    i = np.clip((pts[:, 1] / res).astype(int), 0, ny - 1)
    j = np.clip((pts[:, 0] / res).astype(int), 0, nx - 1)
    return i, j
