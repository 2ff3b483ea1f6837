"""The road field F (paper §III-B): a road graph as an H x W x 6 raster, and back.

Channels (``F[iy, ix, c]``, row ``iy`` runs north from y = 0, column ``ix`` east from x = 0;
pixel centres at ``((ix + 0.5) r, (iy + 0.5) r)`` with ``r = tile / size`` metres):

0. road probability: ``exp(-d² / 2σ²)``, d the distance from the pixel centre to the nearest
   centreline and σ one pixel, so a road is a band about 2.4 pixels wide at threshold 0.5
   (wide enough for a stride-8 VQ-VAE to place and for the skeletoniser to keep connected,
   narrow enough that the streets of a 60-80 m block stay apart);
1. ``p cos 2θ`` and 2. ``p sin 2θ``: the doubled angle of the nearest road (a direction without
   sign) scaled by the road probability p, hence zero off the road;
3. junction heatmap: a Gaussian (σ one pixel) around every node of degree >= 3;
4. endpoint heatmap: the same around every node of degree 1;
5. distance field: distance to the nearest road, clipped at ``dist_clip_m``, divided by it.

Resolution: a 2 km tile at 128 x 128 (15.6 m per pixel). At 64 x 64 (31 m) two parallel streets
of a 60-80 m urban block would be two pixels apart and merge when skeletonised; 128 keeps them
apart while a 16 x 16 token grid (VQ-VAE stride 8) stays small enough for CPU training
(docs/data.md has the measured round trip at both sizes).
"""

from __future__ import annotations

import networkx as nx
import numpy as np
from scipy.spatial import cKDTree

from .sampling import sample_roads

FIELD_SIZE = 128
CHANNELS = ("road", "cos2theta", "sin2theta", "junction", "endpoint", "distance")
ROAD_SIGMA_PX = 1.0
NODE_SIGMA_PX = 1.0
DIST_CLIP_M = 200.0


def pixel_centres(size: int, res: float) -> np.ndarray:
    """``(size * size, 2)`` pixel-centre coordinates in metres, row-major over ``[iy, ix]``."""
    c = (np.arange(size) + 0.5) * res
    X, Y = np.meshgrid(c, c)
    return np.column_stack([X.ravel(), Y.ravel()])


def _node_heat(G: nx.Graph, nodes: list, centres: np.ndarray, sigma: float) -> np.ndarray:
    """Max over ``nodes`` of a Gaussian of width ``sigma`` (the nearest node's Gaussian)."""
    if not nodes:
        return np.zeros(len(centres))
    xy = np.array([G.nodes[n]["xy"] for n in nodes], dtype=float)
    d, _ = cKDTree(xy).query(centres, distance_upper_bound=4 * sigma)
    return np.exp(-0.5 * (d / sigma) ** 2)


def road_field(G: nx.Graph, size: int = FIELD_SIZE, *, dist_clip_m: float = DIST_CLIP_M,
               classes: tuple[str, ...] | None = None) -> np.ndarray:
    """Rasterise tile graph ``G`` (extent ``G.graph["width"]``, square) into F, float32.

    ``classes`` keeps only roads of those classes (e.g. ``("arterial", "collector")`` for a
    skeleton of principal roads); by default every road is drawn.
    """
    if classes is not None:
        G = G.edge_subgraph([e for e, c in nx.get_edge_attributes(G, "road_class").items()
                             if c in classes])
    res = G.graph["width"] / size
    centres = pixel_centres(size, res)
    dist, theta = sample_roads(G, res / 8).nearest(centres, dist_clip_m)
    road = np.exp(-0.5 * (dist / (ROAD_SIGMA_PX * res)) ** 2)
    degree = dict(G.degree())
    F = np.stack([
        road,
        road * np.cos(2 * theta),
        road * np.sin(2 * theta),
        _node_heat(G, [n for n, d in degree.items() if d >= 3], centres, NODE_SIGMA_PX * res),
        _node_heat(G, [n for n, d in degree.items() if d == 1], centres, NODE_SIGMA_PX * res),
        np.minimum(dist, dist_clip_m) / dist_clip_m,
    ], axis=-1)
    return F.reshape(size, size, len(CHANNELS)).astype(np.float32)


def rotate_field(F: np.ndarray, k: int) -> np.ndarray:
    """F of the tile turned ``k`` x 90° counter-clockwise (what ``tiles.rotate_tile`` does to
    the graph), without rasterising again: the raster turns and 2θ gains k·180°."""
    R = np.rot90(F, k=k % 4, axes=(1, 0)).copy()
    if k % 2:
        R[..., 1:3] *= -1.0
    return R


def field_to_graph(F: np.ndarray, tile_m: float, *, threshold: float = 0.5,
                   road_class: str = "arterial", **options) -> nx.Graph:
    """The road graph (metres, RoadGraph convention) that a road field F describes.

    The inverse of :func:`road_field` used at sampling time (paper §III-B, "graph
    reconstruction"): threshold the road probability, skeletonise, trace the skeleton into a
    graph, then clean it with the junction and endpoint heatmaps. ``options`` go to
    :func:`roadweaver_sumo.data.vectorise.clean_graph` (spur length, merge distance).
    """
    from .vectorise import clean_graph, skeleton_graph

    res = tile_m / F.shape[1]
    G = skeleton_graph(F[..., 0] >= threshold, res, tile_m, road_class)
    return clean_graph(G, F, res, **options)
