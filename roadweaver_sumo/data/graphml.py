"""Read a street graph saved by osmnx (``ox.save_graphml``) into a RoadGraph.

Users who already work with osmnx can measure the condition vector of "a map like this city"
without an OSM extract. Longitude/latitude (node ``x``/``y``) are projected like OSM input;
edges without a ``geometry`` are straight; osmnx's directed twin edges collapse to one road.
"""

from __future__ import annotations

import ast
from pathlib import Path

import networkx as nx
import numpy as np
import shapely

from ..errors import RoadweaverError
from ..roadgraph import new_road_graph
from .build import add_segment, node_counter
from .osm import HIGHWAY_CLASS
from .projection import fit_projection

_RANK = {"arterial": 0, "collector": 1, "local": 2}


def _road_class(highway) -> str:
    """Highest class among the (possibly list-valued) highway tags; unknown values are local."""
    values = highway if isinstance(highway, list) else [highway]
    if isinstance(highway, str) and highway.startswith("["):
        values = ast.literal_eval(highway)
    classes = [HIGHWAY_CLASS.get(v, "local") for v in values] or ["local"]
    return min(classes, key=_RANK.__getitem__)


def _edge_lonlat(g: nx.Graph, u, v, data) -> np.ndarray:
    """(lon, lat) polyline of an osmnx edge, oriented from u to v."""
    ends = np.array([[float(g.nodes[n]["x"]), float(g.nodes[n]["y"])] for n in (u, v)])
    if "geometry" not in data:
        return ends
    coords = np.asarray(shapely.from_wkt(data["geometry"]).coords)
    if np.abs(coords[0] - ends[1]).sum() < np.abs(coords[0] - ends[0]).sum():
        coords = coords[::-1]
    return coords


def read_graphml(path: str | Path) -> nx.Graph:
    """The road graph of an osmnx GraphML file, in metres (see :mod:`.projection`)."""
    path = Path(path)
    if not path.is_file():
        raise RoadweaverError(f"{path}: no such GraphML file")
    try:
        g = nx.read_graphml(path)
        lon = np.array([float(d["x"]) for _, d in g.nodes(data=True)])
        lat = np.array([float(d["y"]) for _, d in g.nodes(data=True)])
    except (KeyError, ValueError, SyntaxError) as exc:
        raise RoadweaverError(f"{path}: not an osmnx GraphML street graph ({exc})") from exc
    if len(lon) == 0:
        raise RoadweaverError(f"{path}: the graph has no nodes")
    proj = fit_projection(lon, lat)
    xy = dict(zip(g.nodes, proj.forward(lon, lat)))
    width, height = np.max(list(xy.values()), axis=0)
    G = new_road_graph(max(float(width), 1.0), max(float(height), 1.0))
    G.graph["projection"] = proj.as_dict()
    fresh = node_counter(G, start=-(1 << 62))
    for n, p in xy.items():
        G.add_node(n, xy=(float(p[0]), float(p[1])))
    for u, v, data in g.edges(data=True):
        ll = _edge_lonlat(g, u, v, data)
        coords = proj.forward(ll[:, 0], ll[:, 1])  # a two-way street's twin is a duplicate
        add_segment(G, u, v, coords, _road_class(data.get("highway", "")), fresh)
    G.remove_nodes_from([n for n, d in G.degree() if d == 0])
    return G
