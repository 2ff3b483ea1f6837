"""Polylines onto the map raster (road fields, cost maps, A* targets)."""

from __future__ import annotations

import numpy as np


def rasterise_polylines(lines, shape: tuple[int, int], res: float) -> np.ndarray:
    """Boolean mask of the raster cells (``res`` metres each) that the polylines pass through."""
    mask = np.zeros(shape, dtype=bool)
    ny, nx = shape
    for line in lines:
        line = np.asarray(line, dtype=float)
        seg = np.diff(line, axis=0)
        n = np.maximum(np.ceil(np.hypot(*seg.T) / (res / 2)).astype(int), 1)
        pts = np.vstack(
            [a + np.linspace(0, 1, k, endpoint=False)[:, None] * d for a, d, k in zip(line, seg, n)]
            + [line[-1:]]
        )
        i = np.clip((pts[:, 1] / res).astype(int), 0, ny - 1)
        j = np.clip((pts[:, 0] / res).astype(int), 0, nx - 1)
        mask[i, j] = True
    return mask
