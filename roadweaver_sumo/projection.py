"""The package's one map projection: a transverse Mercator (WGS84, scale 1) centred on a map's
geo origin, computed by PROJ (pyproj).

It is the projection SUMO's ``<location projParameter>`` declares for our nets, so our local
metres, SUMO's x/y, the lanelet2 file's lat/lon and lanelet2's ``LocalCartesianProjector`` at
the same origin agree (UTM would not: its 0.9996 scale moves points by 40 cm per kilometre).
Imported OSM data is projected the same way, centred on the extract.
"""

from __future__ import annotations

import functools

import numpy as np
import pyproj


def tmerc(origin: tuple[float, float]) -> str:
    """The PROJ string of the projection centred on ``origin`` (lat, lon): (0, 0) there."""
    lat, lon = origin
    return f"+proj=tmerc +lat_0={lat} +lon_0={lon} +k=1 +x_0=0 +y_0=0 +ellps=WGS84 +units=m"


@functools.lru_cache(maxsize=16)
def _transformer(origin: tuple[float, float]) -> pyproj.Transformer:
    return pyproj.Transformer.from_crs("EPSG:4326", tmerc(origin), always_xy=True)


def latlon_to_local(lat, lon, origin: tuple[float, float]) -> tuple[np.ndarray, np.ndarray]:
    """WGS84 degrees to local metres (x east, y north) of the map whose (0, 0) is ``origin``."""
    x, y = _transformer(tuple(origin)).transform(np.asarray(lon, float), np.asarray(lat, float))
    return np.asarray(x), np.asarray(y)


def local_to_latlon(x, y, origin: tuple[float, float]) -> tuple[np.ndarray, np.ndarray]:
    """Local metres to WGS84 degrees (lat, lon): the inverse of :func:`latlon_to_local`."""
    lon, lat = _transformer(tuple(origin)).transform(np.asarray(x, float), np.asarray(y, float),
                                                     direction="INVERSE")
    return np.asarray(lat), np.asarray(lon)
