"""Road-field raster to road graph: skeleton tracing and heatmap-guided cleaning.

The graph-reconstruction step after decoding F (paper §III-B): the thresholded road channel is
thinned to one-pixel centrelines (Zhang-Suen via scikit-image), the skeleton pixels become a
pixel graph, chains of degree-2 pixels become polylines between junction clusters and ends, and
the junction and endpoint heatmaps decide which short spurs are real and where junctions sit.
"""

from __future__ import annotations

import networkx as nx
import numpy as np
import shapely
from scipy import sparse
from scipy.sparse.csgraph import connected_components
from skimage.morphology import skeletonize

from ..roadgraph import add_road, edge_length, merge_degree2, new_road_graph
from .build import add_segment, node_counter

_STEPS = ((0, 1), (1, 0), (1, 1), (1, -1))


def pixel_graph(skeleton: np.ndarray) -> tuple[np.ndarray, sparse.csr_matrix]:
    """Skeleton pixels ``(n, 2)`` as ``(iy, ix)`` and their 8-neighbour adjacency.

    A diagonal step is left out where a pixel bridges the corner (the L-shaped staircase of a
    thinned line), so only true branchings have degree >= 3.
    """
    pix = np.argwhere(skeleton)
    on = np.pad(skeleton, 1)
    index = np.full(on.shape, -1)
    index[pix[:, 0] + 1, pix[:, 1] + 1] = np.arange(len(pix))
    rows, cols = [], []
    for dy, dx in _STEPS:
        q = pix + 1 + (dy, dx)
        ok = on[q[:, 0], q[:, 1]]
        if dy and dx:
            ok &= ~on[pix[:, 0] + 1 + dy, pix[:, 1] + 1] & ~on[pix[:, 0] + 1, pix[:, 1] + 1 + dx]
        rows.append(np.flatnonzero(ok))
        cols.append(index[q[ok, 0], q[ok, 1]])
    r, c = np.concatenate(rows), np.concatenate(cols)
    A = sparse.coo_matrix((np.ones(len(r)), (r, c)), shape=(len(pix),) * 2)
    return pix, (A + A.T).tocsr()


def _key_clusters(A: sparse.csr_matrix, degree: np.ndarray) -> np.ndarray:
    """Node id per pixel: touching branch pixels share one, each end pixel has its own, chain
    pixels get -1."""
    branch = degree >= 3
    C = A.tocoo()
    keep = branch[C.row] & branch[C.col]
    B = sparse.coo_matrix((C.data[keep], (C.row[keep], C.col[keep])), shape=A.shape)
    _, label = connected_components(B.tocsr(), directed=False)
    node = np.full(len(degree), -1)
    key = np.flatnonzero(degree != 2)
    _, node[key] = np.unique(label[key], return_inverse=True)
    return node


def _trace(A: sparse.csr_matrix, node: np.ndarray) -> list[tuple[int, int, list[int]]]:
    """(node a, node b, pixel path) for every chain between key pixels, then closed rings.
    (Walked on Python lists: a 10 km field has some 27,000 skeleton pixels, and indexing
    numpy arrays one pixel at a time cost more than the walk.)"""
    indptr, indices, key = A.indptr.tolist(), A.indices.tolist(), node.tolist()
    covered = node >= 0
    done: set[tuple[int, int]] = set()
    traces = []
    for k in np.flatnonzero(node >= 0).tolist():
        for nb in indices[indptr[k] : indptr[k + 1]]:
            if key[nb] == key[k] or (k, nb) in done:
                continue
            path = [k, nb]
            while key[path[-1]] < 0:  # a chain pixel: exactly two neighbours
                p, q = indices[indptr[path[-1]] : indptr[path[-1] + 1]]
                path.append(q if p == path[-2] else p)
            done.add((path[-1], path[-2]))
            covered[path] = True
            traces.append((key[k], key[path[-1]], path))
    for start in np.flatnonzero(~covered).tolist():  # rings of degree-2 pixels with no junction
        if covered[start]:
            continue
        path = [start]
        while True:
            nbrs = [p for p in indices[indptr[path[-1]] : indptr[path[-1] + 1]]
                    if len(path) < 2 or p != path[-2]]
            if not nbrs or nbrs[0] == start:
                break
            path.append(nbrs[0])
        covered[path] = True
        traces.append((-1 - start, -1 - start, path + [start]))
    return traces


def skeleton_graph(mask: np.ndarray, res: float, tile_m: float,
                   road_class: str = "arterial") -> nx.Graph:
    """Road graph of the centrelines of a boolean road mask (``[iy, ix]``, pixels ``res`` m,
    ``tile_m`` wide; a rectangular mask gives a rectangular map)."""
    skeleton = skeletonize(mask)
    pix, A = pixel_graph(skeleton)
    degree = np.asarray(A.sum(axis=1)).ravel().astype(int)
    node = _key_clusters(A, degree)
    xy = (pix[:, ::-1] + 0.5) * res
    G = new_road_graph(tile_m, tile_m * mask.shape[0] / mask.shape[1])
    keyed = node >= 0
    ids, cluster = np.unique(node[keyed], return_inverse=True)
    size = np.bincount(cluster)
    centre = np.column_stack([np.bincount(cluster, weights=xy[keyed, k]) / size for k in (0, 1)])
    for n, (x, y) in zip(ids.tolist(), centre.tolist(), strict=True):
        G.add_node(n, xy=(x, y))
    fresh = node_counter(G, start=len(pix) + 1)
    traces = _trace(A, node)
    for (a, b, path), line in zip(traces, _centrelines(traces, xy, centre, res), strict=True):
        if a not in G:  # a ring's node, on its first pixel
            G.add_node(a, xy=(float(xy[path[0], 0]), float(xy[path[0], 1])))
        _add_segment(G, a, b, line, road_class, fresh)
    return G


def _add_segment(G: nx.Graph, u, v, coords: np.ndarray, road_class: str, fresh) -> None:
    """:func:`add_segment`, with a road between two nodes not yet joined (nearly all of them)
    added straight away: add_segment measures every road first, which only loops and second
    roads between the same nodes need (7,000 roads on a 10 km field)."""
    if u != v and not G.has_edge(u, v):
        add_road(G, u, v, coords, road_class)
    else:
        add_segment(G, u, v, coords, road_class, fresh)


def _centrelines(traces, xy: np.ndarray, centre: np.ndarray, res: float) -> list[np.ndarray]:
    """The polyline of every traced path (``centre`` row i: key node i's position): its pixel
    centres from node to node, with two rounds of a (1/4, 1/2, 1/4) average of the interior
    points (ends fixed), which removes one-pixel steps but keeps bends, then simplified to
    half a pixel. All paths go through numpy and shapely at once; each point is computed as
    a path on its own would compute it."""
    if not traces:
        return []
    paths = [path for _, _, path in traces]
    sizes = np.array([len(path) for path in paths])
    last = np.cumsum(sizes) - 1
    first = last - sizes + 1
    coords = xy[np.concatenate(paths)]
    ends = np.concatenate([first, last])
    nodes = np.array([a for a, _, _ in traces] + [b for _, b, _ in traces])
    keyed = nodes >= 0  # a ring's node is its first pixel already
    coords[ends[keyed]] = centre[nodes[keyed]]
    inner = np.ones(len(coords), dtype=bool)
    inner[first] = inner[last] = False
    for _ in range(2):
        smoothed = 0.25 * coords[:-2] + 0.5 * coords[1:-1] + 0.25 * coords[2:]
        coords[1:-1] = np.where(inner[1:-1, None], smoothed, coords[1:-1])
    lines = shapely.simplify(shapely.linestrings(coords, indices=np.repeat(np.arange(len(paths)),
                                                                           sizes)), 0.5 * res)
    return np.split(shapely.get_coordinates(lines),
                    np.cumsum(shapely.get_num_coordinates(lines))[:-1])


def _pixel_value(channel: np.ndarray, xy, res: float) -> float:
    iy = min(max(int(xy[1] / res), 0), channel.shape[0] - 1)
    ix = min(max(int(xy[0] / res), 0), channel.shape[1] - 1)
    return float(channel[iy, ix])


def prune_spurs(G: nx.Graph, endpoint: np.ndarray, res: float, min_len: float,
                keep_heat: float = 0.5) -> nx.Graph:
    """Remove dead-end branches shorter than ``min_len`` that hang off a junction, unless the
    endpoint heatmap says a road really ends there. Skeletonising a road band sprouts such
    spurs wherever its outline is bumpy."""
    for n in [n for n, d in G.degree() if d == 1]:
        (v,) = G.neighbors(n)
        if (G.degree(v) >= 3 and edge_length(G, n, v) < min_len
                and _pixel_value(endpoint, G.nodes[n]["xy"], res) < keep_heat):
            G.remove_node(n)
    return G


def merge_close_junctions(G: nx.Graph, max_dist: float) -> nx.Graph:
    """Contract roads shorter than ``max_dist`` between junctions (degree >= 3) into one node.

    A thinned four-way crossing often becomes two three-way junctions a pixel apart."""
    short = [(u, v) for u, v in G.edges
             if G.degree(u) >= 3 and G.degree(v) >= 3 and edge_length(G, u, v) < max_dist]
    if not short:
        return G
    rep = {}
    for comp in nx.connected_components(nx.Graph(short)):
        members = sorted(comp)
        centre = np.mean([G.nodes[m]["xy"] for m in members], axis=0)
        for m in members:
            rep[m] = members[0]
        G.nodes[members[0]]["xy"] = (float(centre[0]), float(centre[1]))
    H = new_road_graph(G.graph["width"], G.graph["height"])
    H.add_nodes_from((n, {"xy": G.nodes[n]["xy"]}) for n in G if rep.get(n, n) == n)
    fresh = node_counter(G)
    for u, v, data in G.edges(data=True):
        a, b = rep.get(u, u), rep.get(v, v)
        coords = data["coords"] if data["start"] == u else data["coords"][::-1]
        if a == b and edge_length(G, u, v) < max_dist:
            continue
        _add_segment(H, a, b, coords, data["road_class"], fresh)
    return H


def place_junctions(G: nx.Graph, junction: np.ndarray, res: float, radius_px: int = 2,
                    min_heat: float = 0.5) -> nx.Graph:
    """Move each junction to the heat-weighted centre of the junction-heatmap peak near it."""
    rows, cols = junction.shape  # not square for a rectangular map
    for n in [n for n, d in G.degree() if d >= 3]:
        x, y = G.nodes[n]["xy"]
        iy, ix = int(y / res), int(x / res)
        y0, y1 = max(iy - radius_px, 0), min(iy + radius_px + 1, rows)
        x0, x1 = max(ix - radius_px, 0), min(ix + radius_px + 1, cols)
        win = junction[y0:y1, x0:x1]
        if win.size == 0 or win.max() < min_heat:
            continue
        w = np.where(win >= 0.5 * win.max(), win, 0.0)
        gy, gx = np.mgrid[y0:y1, x0:x1]
        p = ((gx * w).sum() / w.sum() + 0.5) * res, ((gy * w).sum() / w.sum() + 0.5) * res
        G.nodes[n]["xy"] = (float(p[0]), float(p[1]))
        for v in G.neighbors(n):
            data = G.edges[n, v]
            data["coords"][0 if data["start"] == n else -1] = p
    return G


def snap_to_border(G: nx.Graph, max_dist: float) -> nx.Graph:
    """Move dead ends within ``max_dist`` of the map border onto it: thinning stops a pixel or
    two short of the edge, but a road that reaches the border leaves the map there."""
    size = np.array([G.graph["width"], G.graph["height"]])
    for n in [n for n, d in G.degree() if d == 1]:
        p = np.array(G.nodes[n]["xy"], dtype=float)
        gaps = np.concatenate([p, size - p])
        k = int(np.argmin(gaps))
        if gaps[k] >= max_dist:
            continue
        p[k % 2] = 0.0 if k < 2 else size[k % 2]
        G.nodes[n]["xy"] = (float(p[0]), float(p[1]))
        (v,) = G.neighbors(n)
        data = G.edges[n, v]
        data["coords"][0 if data["start"] == n else -1] = p
    return G


def clean_graph(G: nx.Graph, F: np.ndarray, res: float, *, min_spur_px: float = 3.0,
                merge_px: float = 1.5, border_px: float = 2.0,
                min_component_px: float = 4.0) -> nx.Graph:
    """Skeleton graph to road graph: spurs pruned, close junctions merged and moved onto the
    junction heatmap's peaks, ends near the border put on it, specks dropped, degree-2 chains
    joined. Lengths are in pixels."""
    G = prune_spurs(G, F[..., 4], res, min_spur_px * res)
    G = snap_to_border(G, border_px * res)
    G = merge_degree2(G)
    G = merge_close_junctions(G, merge_px * res)
    G = place_junctions(G, F[..., 3], res)
    for comp in list(nx.connected_components(G)):
        sub = G.subgraph(comp)
        if sum(edge_length(sub, u, v) for u, v in sub.edges) < min_component_px * res:
            G.remove_nodes_from(comp)
    return merge_degree2(G)
