"""What a skeleton generator hands to the expansion, whichever generator it is."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.ndimage import gaussian_filter

from ..raster import rasterise_polylines
from ..tensor_field import TensorField


@dataclass
class Skeleton:
    """Principal roads and the road field they come with.

    ``polylines``: principal centrelines in map metres, ``classes`` their road classes.
    ``frame``: the perimeter road. ``basis``: the orientation field to fall back on far from
    the skeleton. ``road_prob``: road probability per raster cell (the decoded
    road field F's first channel for the learned model), which becomes the A* cost map.
    """

    polylines: list[np.ndarray]
    frame: np.ndarray
    basis: TensorField
    road_prob: np.ndarray
    res: float
    classes: list[str] = field(default_factory=list)
    #: grow collectors inward from the perimeter too: a learned skeleton may leave large parts
    #: of the map empty, which the procedural one (arterials across the map) never does
    grow_from_frame: bool = False
    #: which generator made it and, for the learned one, the data attribution it carries
    provenance: dict = field(default_factory=lambda: {"generator": "procedural"})

    def road_classes(self) -> list[str]:
        """Class per polyline; a generator that gives none makes every skeleton road arterial."""
        return self.classes or ["arterial"] * len(self.polylines)

    def cost_map(self) -> np.ndarray:
        """Traversal cost per cell: cheap where the field predicts roads (paper §III-C, A*)."""
        return 1.0 + 4.0 * (1.0 - np.clip(self.road_prob, 0.0, 1.0))


def road_field_from_polylines(
    lines: list[np.ndarray], shape: tuple[int, int], res: float, width_m: float
) -> np.ndarray:
    """Rasterise polylines and blur them into a road probability in [0, 1]."""
    raster = rasterise_polylines(lines, shape, res).astype(float)
    blurred = gaussian_filter(raster, sigma=width_m / 2 / res)
    peak = blurred.max()
    return blurred / peak if peak > 0 else blurred


PERIMETER_INSET = 15.0  # metres between the perimeter ring road and the map border


def perimeter(width: float, height: float, inset: float = PERIMETER_INSET) -> np.ndarray:
    """A ring road just inside the map border. Roads that reach the edge of the map end on it
    instead of being cut off, so the network is closed for simulation (no dead ends made by the
    map edge) and every block is a face that the density fill can split."""
    lo, hx, hy = inset, width - inset, height - inset
    return np.array([(lo, lo), (hx, lo), (hx, hy), (lo, hy), (lo, lo)])
