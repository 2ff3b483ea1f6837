"""A* reconnection of dangling road ends over the road-field cost map (paper §III-C).

Each dead end that is not at the map border searches, within a window around it, the cheapest
path to any other road; cells the skeleton's road field marks as likely road are cheap, so the
new link follows the layout the skeleton suggests. The graph search is scikit-image's
minimum-cost-path search (``MCP_Geometric``) in a window around the dead end.
"""

from __future__ import annotations

import networkx as nx
import numpy as np
import shapely
from shapely.ops import nearest_points
from skimage.graph import MCP_Geometric

from ..raster import polyline_cells_each, rasterise_polylines, rasterise_window
from ..roadgraph import sorted_edge_list
from .perimeter import components_main_first
from .planar import road_lines


def dangling_ends(G: nx.Graph, margin: float) -> list[int]:
    """Degree-1 nodes farther than ``margin`` from the map border."""
    width, height = G.graph["width"], G.graph["height"]
    out = []
    for n, deg in sorted(G.degree()):
        x, y = G.nodes[n]["xy"]
        if deg == 1 and min(x, y, width - x, height - y) >= margin:
            out.append(n)
    return out


def reconnect_dangles(
    G: nx.Graph, cost: np.ndarray, res: float, radius: float, margin: float
) -> list[np.ndarray]:
    """Polylines linking dangling ends to the nearest reachable road (not yet inserted)."""
    roads = sorted_edge_list(G)
    edges = [(u, v) for u, v, _ in roads]
    lines = road_lines(roads)
    tree = shapely.STRtree(lines)
    position = {e: k for k, e in enumerate(edges)}
    # Each road's cells once: a junction's roads are excluded from several dead ends' searches.
    cells = polyline_cells_each([data["coords"] for _, _, data in roads], cost.shape, res)
    road_mask = np.zeros(cost.shape, dtype=bool)
    for i, j in cells:
        road_mask[i, j] = True

    def link(n):
        (w,) = G.neighbors(n)
        # The roads at the dead end's own junction are not targets: a link onto them would
        # make a loop back to where the road started, not a new connection.
        skip = {position.get((w, x), position.get((x, w))) for x in G.neighbors(w)}
        exclude = (np.concatenate([cells[k][0] for k in skip]),
                   np.concatenate([cells[k][1] for k in skip]))
        path = _cheapest_link(np.asarray(G.nodes[n]["xy"]), cost, road_mask, res, radius,
                              exclude)
        if path is not None:
            path = _snap_end(path, lines, tree, skip)
        return path

    paths = [link(n) for n in dangling_ends(G, margin)]
    return [path for path in paths if path is not None]


def link_components(G: nx.Graph, cost: np.ndarray, res: float, radius: float,
                    pending: list[np.ndarray] = ()) -> list[np.ndarray]:
    """Polylines linking each component that is not the main one (the perimeter ring's) to
    it: an A* path from the component's junction nearest to a main road, within ``radius``.
    A component with no dead end (a loop, a cluster whose ends all found each other) gets no
    link from :func:`reconnect_dangles` and would otherwise be dropped whole.

    ``pending`` are the links :func:`reconnect_dangles` made, not yet in ``G``: each joins its
    dead end's component to that of the road it ends on (and the main component's links are
    targets too), so the graph is noded once with both sets of links instead of twice. (Where
    a pending link crosses a road without ending on it, the two components count as apart:
    at worst one more link.)"""
    roads = sorted_edge_list(G)
    comps, pending_comp = _joined_components(G, roads, pending)
    if len(comps) <= 1:
        return []
    main_roads = [road for road in roads if road[0] in comps[0]]
    main_links = [path for path, c in zip(pending, pending_comp, strict=True) if c == 0]
    lines = road_lines(main_roads) + [shapely.LineString(path) for path in main_links]
    tree = shapely.STRtree(lines)
    targets = rasterise_polylines([data["coords"] for _, _, data in main_roads] + main_links,
                                  cost.shape, res)
    links = []
    for comp in comps[1:]:
        nodes = sorted(comp)
        xy = np.array([G.nodes[n]["xy"] for n in nodes], float)
        _, gap = tree.query_nearest(shapely.points(xy), return_distance=True, all_matches=False)
        k = int(np.argmin(gap))
        if gap[k] > radius:
            continue
        path = _cheapest_link(xy[k], cost, targets, res, radius)
        if path is None and gap[k] < 2 * res:  # within a cell or two: a straight link
            path = np.array([xy[k], xy[k]])
        if path is not None:
            path = _snap_end(path, lines, tree, set())
        if path is not None and np.hypot(*(path[-1] - path[0])) > 1.0:
            links.append(path)
    return links


def _joined_components(G: nx.Graph, roads: list, pending: list) -> tuple[list[set], list[int]]:
    """The node sets of ``G``'s components as the ``pending`` links join them (main first, as
    :func:`components_main_first` orders components), and which of them each link is in.
    A link starts on its dead end's node and ends on (within a hair of) a road."""
    comps = list(nx.connected_components(G))
    group = list(range(len(comps)))

    def find(c: int) -> int:
        while group[c] != c:
            group[c] = group[group[c]]
            c = group[c]
        return c

    comp_of = {n: c for c, comp in enumerate(comps) for n in comp}
    starts = []
    if len(pending):
        node_at = {tuple(G.nodes[n]["xy"]): n for n in G}
        tree = shapely.STRtree(road_lines(roads))
        _, hit = tree.query_nearest(shapely.points([path[-1] for path in pending]),
                                    all_matches=False)
        for path, k in zip(pending, hit.tolist(), strict=True):
            a = comp_of[node_at[(float(path[0][0]), float(path[0][1]))]]
            group[find(a)] = find(comp_of[roads[k][0]])
            starts.append(a)
    joined: dict[int, set] = {}
    for c, comp in enumerate(comps):
        joined.setdefault(find(c), set()).update(comp)
    ordered = components_main_first(G, list(joined.values()))
    rank = {min(comp): r for r, comp in enumerate(ordered)}
    root_rank = {root: rank[min(comp)] for root, comp in joined.items()}
    return ordered, [root_rank[find(a)] for a in starts]


def _cheapest_link(p, cost, targets, res, radius, exclude=None):
    """The cheapest path from ``p`` to a ``targets`` cell (not one of the ``exclude`` cells,
    rows and columns) within ``radius``; the masks are only read inside that window (one
    search per dead end)."""
    ny, nx_ = cost.shape
    r = int(radius / res)
    ci, cj = int(p[1] / res), int(p[0] / res)
    i0, i1 = max(ci - r, 0), min(ci + r + 1, ny)
    j0, j1 = max(cj - r, 0), min(cj + r + 1, nx_)
    window_targets = targets[i0:i1, j0:j1]
    if exclude is not None:
        window_targets = window_targets & ~rasterise_window(exclude, (i0, i1, j0, j1))
    if not window_targets.any():
        return None
    start = (min(max(ci - i0, 0), i1 - i0 - 1), min(max(cj - j0, 0), j1 - j0 - 1))
    cells = _cheapest_cells(cost[i0:i1, j0:j1], window_targets, start)
    if len(cells) < 2:
        return None  # the start cell is a target: no path to trace
    xy = (cells[:, ::-1] + [j0, i0] + 0.5) * res
    xy[0] = p
    line = shapely.simplify(shapely.linestrings(xy), res * 0.75)
    length = shapely.length(line)
    if length > radius * 1.5 or length < res:
        return None
    return shapely.get_coordinates(line)


def _cheapest_cells(cost: np.ndarray, targets: np.ndarray, start: tuple) -> np.ndarray:
    """The cells (row, column) of the cheapest path from ``start`` to the first target cell
    that scikit-image's minimum-cost-path search settles, start first; none if none is
    reached."""
    mcp = MCP_Geometric(cost)
    costs, _ = mcp.find_costs([start], np.argwhere(targets), find_all_ends=False)
    reached = np.where(targets, costs, np.inf)
    if not np.isfinite(reached).any():
        return np.zeros((0, 2), dtype=np.int64)
    return np.array(mcp.traceback(np.unravel_index(int(np.argmin(reached)), cost.shape)))


def _snap_end(path: np.ndarray, lines: list, tree, skip: set) -> np.ndarray | None:
    """Move the path's last point onto the nearest road not in ``skip``."""
    end = shapely.points(path[-1])
    near = [k for k in tree.query(end, predicate="dwithin", distance=20.0).tolist()
            if k not in skip]
    if not near:
        return None
    gaps = shapely.distance(tree.geometries.take(near), end).tolist()
    _, k = min(zip(gaps, near, strict=True))
    hit = nearest_points(lines[k], end)[0]
    out = path.copy()
    out[-1] = (hit.x, hit.y)
    return out
