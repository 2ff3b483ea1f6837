"""Longitude/latitude of imported OSM data to a local metric frame (metres, x east, y north).

The package's one projection (:mod:`roadweaver_sumo.projection`, a transverse Mercator)
centred on the extract, shifted so that the data starts at (0, 0). It is conformal, so bearings
and junction angles (which the condition vector measures) are not distorted.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..projection import latlon_to_local, local_to_latlon


@dataclass(frozen=True)
class LocalProjection:
    """The transverse Mercator centred on (``lat0``, ``lon0``); ``x0``/``y0`` are subtracted
    after projecting, so a map's data can start at (0, 0)."""

    lon0: float
    lat0: float
    x0: float = 0.0
    y0: float = 0.0

    def forward(self, lon, lat) -> np.ndarray:
        """``(n, 2)`` metres for arrays of longitudes and latitudes in degrees."""
        x, y = latlon_to_local(lat, lon, (self.lat0, self.lon0))
        return np.column_stack([np.ravel(x) - self.x0, np.ravel(y) - self.y0])

    def inverse(self, xy) -> np.ndarray:
        """``(n, 2)`` (lon, lat) degrees for ``(n, 2)`` metres: the geo-reference of a map point."""
        xy = np.atleast_2d(np.asarray(xy, dtype=float))
        lat, lon = local_to_latlon(xy[:, 0] + self.x0, xy[:, 1] + self.y0,
                                   (self.lat0, self.lon0))
        return np.column_stack([lon, lat])

    def as_dict(self) -> dict:
        """JSON-ready description, stored in ``G.graph["projection"]``."""
        return {"proj": "tmerc-wgs84", "lon0": self.lon0, "lat0": self.lat0,
                "x0": self.x0, "y0": self.y0}


def fit_projection(lon: np.ndarray, lat: np.ndarray) -> LocalProjection:
    """A projection centred on the bounding box of the points whose frame starts at (0, 0)."""
    lon0 = float((np.min(lon) + np.max(lon)) / 2)
    lat0 = float((np.min(lat) + np.max(lat)) / 2)
    xy = LocalProjection(lon0, lat0).forward(lon, lat)
    return LocalProjection(lon0, lat0, float(xy[:, 0].min()), float(xy[:, 1].min()))
