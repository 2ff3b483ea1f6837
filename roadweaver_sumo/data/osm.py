"""Read any user's OpenStreetMap extract into a simplified, projected RoadGraph.

Two streaming passes with pyosmium (ways, then only the nodes those ways use), so memory grows
with the drivable network, not with the file: buildings, land use and addresses are skipped in
C++. The graph is the car-drivable network topologically simplified as in osmnx (Boeing 2017):
nodes are the OSM nodes where drivable ways meet or end, edges are the polylines between them.
"""

from __future__ import annotations

from itertools import pairwise
from pathlib import Path

import networkx as nx
import numpy as np

from ..errors import RoadweaverError
from ..roadgraph import new_road_graph
from .build import add_segment, node_counter
from .projection import fit_projection

OSM_SUFFIXES = (".osm", ".osm.gz", ".osm.bz2", ".osm.pbf", ".pbf")

#: OSM ``highway`` values a car may drive on, and the road class each maps to.
HIGHWAY_CLASS = {
    "motorway": "arterial", "trunk": "arterial", "primary": "arterial",
    "secondary": "collector", "tertiary": "collector",
    "unclassified": "local", "residential": "local", "living_street": "local",
}
HIGHWAY_CLASS.update({f"{k}_link": v for k, v in list(HIGHWAY_CLASS.items())[:5]})

_CLOSED_ACCESS = {"no", "private"}


def road_class(highway: str) -> str | None:
    """Road class of an OSM ``highway`` value, or None when cars do not use it."""
    return HIGHWAY_CLASS.get(highway)


def is_drivable(tags) -> bool:
    """A way cars may drive through: a drivable highway that is not an area nor closed to them.

    ``service``, ``track``, ``path``, ``footway``, ``cycleway``, ``construction`` and the like have
    no class and are dropped; so are ``area=yes`` and ``access`` / ``motor_vehicle`` = no/private.
    """
    return (
        tags.get("highway") in HIGHWAY_CLASS
        and tags.get("area") != "yes"
        and tags.get("access") not in _CLOSED_ACCESS
        and tags.get("motor_vehicle") not in _CLOSED_ACCESS
    )


def _osmium():
    try:
        import osmium
        import osmium.filter
    except ImportError as exc:  # optional at import time, needed to read OSM
        raise RoadweaverError("reading OSM files needs pyosmium: pip install osmium") from exc
    return osmium


def _check_path(path: Path) -> None:
    if not path.is_file():
        raise RoadweaverError(f"{path}: no such OSM file")
    if not path.name.lower().endswith(OSM_SUFFIXES):
        raise RoadweaverError(
            f"{path}: not an OSM file (expected one of {', '.join(OSM_SUFFIXES)})"
        )


def _drivable_ways(path: Path) -> list[tuple[np.ndarray, str]]:
    """(node ids, road class) of every drivable way, consecutive repeats removed."""
    osmium = _osmium()
    ways = []
    reader = osmium.FileProcessor(str(path), osmium.osm.WAY)
    for way in reader.with_filter(osmium.filter.KeyFilter("highway")):
        if not is_drivable(way.tags):
            continue
        refs = np.fromiter((n.ref for n in way.nodes), dtype=np.int64)
        refs = refs[np.concatenate([[True], refs[1:] != refs[:-1]])] if len(refs) else refs
        if len(refs) >= 2:
            ways.append((refs, HIGHWAY_CLASS[way.tags["highway"]]))
    return ways


def _node_lonlat(path: Path, wanted: np.ndarray) -> np.ndarray:
    """(lon, lat) for the sorted ids ``wanted``; NaN for nodes missing from a clipped extract.

    A Python set does the id test: pyosmium's IdFilter allocates an id bitmap that took
    ~0.5 GB even for a small country extract.
    """
    osmium = _osmium()
    ids = set(wanted.tolist())
    found = []
    for node in osmium.FileProcessor(str(path), osmium.osm.NODE):
        if node.id in ids and node.location.valid():
            found.append((node.id, node.location.lon, node.location.lat))
    lonlat = np.full((len(wanted), 2), np.nan)
    if found:
        arr = np.array(found)
        lonlat[np.searchsorted(wanted, arr[:, 0].astype(np.int64))] = arr[:, 1:]
    return lonlat


def _located_runs(ways, ids: np.ndarray, ok: np.ndarray) -> list[tuple[np.ndarray, str]]:
    """Ways as index arrays into ``ids``, split where a node has no location (clipped data)."""
    runs = []
    for refs, cls in ways:
        idx = np.searchsorted(ids, refs)
        good = ok[idx]
        if good.all():
            runs.append((idx, cls))
            continue
        breaks = np.flatnonzero(np.diff(np.concatenate([[0], good.astype(np.int8), [0]])))
        runs.extend((idx[a:b], cls) for a, b in zip(breaks[::2], breaks[1::2]) if b - a >= 2)
    return runs


def _junctions(runs, n_ids: int) -> np.ndarray:
    """Nodes where runs end or that several runs (or one run twice) pass through."""
    uses = np.bincount(np.concatenate([r for r, _ in runs]), minlength=n_ids)
    key = uses >= 2
    for r, _ in runs:
        key[r[[0, -1]]] = True
    return key


def _build_graph(runs, ids, xy, key, proj) -> nx.Graph:
    width, height = (float(v) for v in np.nanmax(xy, axis=0))
    G = new_road_graph(max(width, 1.0), max(height, 1.0))
    G.graph["projection"] = proj.as_dict()
    fresh = node_counter(G, start=-(1 << 62))  # below every OSM id
    for r, cls in runs:
        cuts = np.flatnonzero(key[r])
        for a, b in pairwise(cuts):
            u, v = int(ids[r[a]]), int(ids[r[b]])
            for n, i in ((u, r[a]), (v, r[b])):
                if n not in G:
                    G.add_node(n, xy=(float(xy[i, 0]), float(xy[i, 1])))
            add_segment(G, u, v, xy[r[a : b + 1]], cls, fresh)
    return G


def read_osm(path: str | Path) -> nx.Graph:
    """The car-drivable road graph of an OSM file (.osm, .osm.gz, .osm.bz2, .osm.pbf).

    Coordinates are metres in a transverse Mercator frame centred on the data, shifted so the
    network starts at (0, 0); ``G.graph["projection"]`` says how to get lon/lat back.
    Raises RoadweaverError for a missing or unreadable file and for a file without drivable roads.
    """
    path = Path(path)
    _check_path(path)
    try:
        ways = _drivable_ways(path)
        ids = np.unique(np.concatenate([w for w, _ in ways])) if ways else np.zeros(0, np.int64)
        lonlat = _node_lonlat(path, ids) if len(ids) else np.zeros((0, 2))
    except RuntimeError as exc:  # pyosmium reports parse and format errors this way
        detail = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise RoadweaverError(f"{path}: cannot read OSM data ({detail})") from exc
    ok = ~np.isnan(lonlat[:, 0])
    runs = _located_runs(ways, ids, ok)
    if not runs:
        raise RoadweaverError(f"{path}: no car-drivable roads (motorway ... residential) found")
    key = _junctions(runs, len(ids))
    proj = fit_projection(lonlat[ok, 0], lonlat[ok, 1])
    xy = np.full_like(lonlat, np.nan)
    xy[ok] = proj.forward(lonlat[ok, 0], lonlat[ok, 1])
    return _build_graph(runs, ids, xy, key, proj)
