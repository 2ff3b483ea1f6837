"""Where the density fill puts local roads (issue 35): where the skeleton's road field does.

Real towns are uneven: dense cores beside parks, rail yards and sparse edges. Over 4 x 4 cells
of a real 2 km tile road length varies with a coefficient of variation of 0.46 (median of 153
OSM tiles, ``bench/realism.py``); splitting the largest block first, everywhere, made ours
0.16, with blocks twice the real median area at the same density. The fill (:mod:`.fill`)
splits the block of the largest area x :func:`block_weight` first instead. The weight is the
skeleton's road field (the decoded field F's road channel for the learned model, paper §III-B;
the blurred principal roads for the procedural one) averaged over a neighbourhood, relative to
its mean and squared: where the field has many roads blocks are split small, where it has few
they stay large, and the map's total still meets the target density.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import shapely
from scipy.ndimage import gaussian_filter
from shapely.geometry import Polygon

from ..skeleton import Skeleton

NEIGHBOURHOOD = 150.0  # metres: the Gaussian's sigma over which the road field is averaged
CONTRAST = 2.0  # the weight's power: 2 matched the real variation of road length (1: 0.34)
FLOOR = 0.05  # the least relative weight: an empty stretch of field still gets roads at last


def block_weight(skeleton: Skeleton, cut: tuple[float, float, float, float]
                 ) -> Callable[[Polygon], float]:
    """The fill's weight of a block: the neighbourhood's road field at a point inside it
    (module docstring), times the share of the block inside ``cut``, the map's box in the
    town it is cut out of. Roads outside the map are cut away, so the field counts only
    inside it (the town's ring road, part of the procedural road field, drew the fill to the
    town's corners), averaged over the part of the neighbourhood inside: averaged over all of
    it, the field fell by half at the map's edge, the fill left a band along the edge
    sparse, and 1.2 % of our road length ran along the border against 1.8 % of real tiles'
    (``realism.frame_share``, medians)."""
    rows, cols = skeleton.road_prob.shape
    y, x = (np.arange(rows) + 0.5) * skeleton.res, (np.arange(cols) + 0.5) * skeleton.res
    inside = ((cut[1] <= y) & (y <= cut[3]))[:, None] & ((cut[0] <= x) & (x <= cut[2]))[None, :]
    sigma = NEIGHBOURHOOD / skeleton.res
    field = gaussian_filter(np.where(inside, skeleton.road_prob, 0.0), sigma)
    field = field / np.maximum(gaussian_filter(inside.astype(float), sigma), 1e-6)
    mean = float(field[inside].mean()) if inside.any() else 0.0
    if mean <= 0.0:
        field = np.ones_like(field)
        mean = 1.0
    weight = np.maximum(field / mean, FLOOR) ** CONTRAST

    def of_block(block: Polygon) -> float:
        point = block.representative_point()
        i = min(max(int(point.y / skeleton.res), 0), rows - 1)
        j = min(max(int(point.x / skeleton.res), 0), cols - 1)
        return float(weight[i, j]) * shapely.clip_by_rect(block, *cut).area / block.area

    return of_block
