"""Per-map statistics that tell a real town from a generated one (issue 35, "Statistics").

A map is measured as a whole and, where the border distorts a figure, "away from the border"
(suffix ``_inner``): a real map is cut out of a larger network, so its roads end at the cut as
dead ends and the blocks along the cut are open; a generated map may instead be closed by a frame
road. Leaving out the road nodes within :data:`MARGIN_M` of the border and the blocks that come
that close to it measures both the way real cut maps are measured (issue 35, "Away from the
border").

Conventions follow osmnx where it has one (Boeing 2017, "OSMnx", §3; Boeing 2019, "Urban spatial
order"): road nodes are nodes of degree != 2, the graph is topologically simplified first (chains
through degree-2 nodes joined), bearings are length-weighted over 36 bins, circuity is the sum of
road lengths over the sum of straight distances between their end nodes. All lengths in metres,
areas in m², angles in the units named.
"""

from __future__ import annotations

import math
from collections import defaultdict

import networkx as nx
import numpy as np
import shapely

from . import metrics
from .metrics import JUNCTION_REACH_M, mean_curvature
from .roadgraph import edge_length, end_directions, merge_degree2, resample_roads

#: Road nodes this close to the border, and blocks coming this close, are left out of the
#: ``_inner`` figures; road length this close to it and parallel to it counts as frame road.
MARGIN_M = 30.0
#: Two arms continue each other when they deviate from a straight line by at most this.
STRAIGHT_TOL_DEG = 15.0
#: A junction angle is "near right" within this of 90°; "acute" under ACUTE_DEG.
RIGHT_TOL_DEG = 15.0
ACUTE_DEG = 45.0
#: A piece of road is parallel to a side of the map within this angle.
PARALLEL_TOL_DEG = 20.0
#: Blocks under this area count as small (issue 35: real towns have 14 % of them).
SMALL_BLOCK_M2 = 5000.0
#: The map is cut into CELLS x CELLS cells for the unevenness of road length.
CELLS = 4
#: Step (m) at which roads are resampled for the frame share and the cell lengths.
SAMPLE_STEP_M = 5.0

#: The statistics a map is compared on (bench/realism.py): the ``_inner`` variant wherever there
#: is one, since the real reference is made of cut maps. Density is left out: it is what the
#: generator is asked for, and a comparison is made at the reference's density.
COMPARED = (
    "dead_end_share_inner", "cycle_share_inner", "three_way_share_inner",
    "four_way_share_inner", "bearing_entropy", "edge_length_mean", "edge_length_p10",
    "edge_length_p50", "edge_length_p90", "turning_per_km", "circuity",
    "right_angle_share_inner", "acute_angle_share_inner", "straight_through_share_inner",
    "stroke_length_median", "block_area_median_inner", "small_block_share_inner",
    "block_compactness_median_inner", "frame_share", "length_cv",
)

Bbox = tuple[float, float, float, float]


def realism_statistics(G: nx.Graph, bbox: Bbox | None = None) -> dict[str, float]:
    """Every statistic of issue 35 for road graph ``G`` on the map ``bbox`` = (x0, y0, x1, y1).

    ``bbox`` defaults to ``[0, width] x [0, height]`` from ``G.graph``. Figures that are not
    defined for the map (no junction, no block) are NaN. Returns a flat dict name -> float.
    """
    if bbox is None:
        bbox = (0.0, 0.0, float(G.graph["width"]), float(G.graph["height"]))
    H = simplified(G)
    inner = {n for n in H if _border_distance(np.asarray(H.nodes[n]["xy"]), bbox) >= MARGIN_M}
    area_km2 = (bbox[2] - bbox[0]) * (bbox[3] - bbox[1]) / 1e6
    out = {"density": metrics.density(H, area_km2), "bearing_entropy": metrics.bearing_entropy(H)}
    on_cycle = _on_cycle(H)
    arms = junction_arms(H)
    blocks = _blocks(H)
    touching = _touches_border(blocks, bbox)
    for suffix, nodes in (("", set(H)), ("_inner", inner)):
        out.update({k + suffix: v for k, v in _degree_shares(H, nodes, on_cycle).items()})
        out.update({k + suffix: v for k, v in _angle_shares(arms, nodes).items()})
        chosen = blocks if not suffix else blocks[~touching]
        out.update({k + suffix: v for k, v in block_statistics(chosen).items()})
    out.update(_link_statistics(H))
    out["turning_per_km"] = mean_curvature(H)
    out["stroke_length_median"] = _weighted_median(stroke_lengths(H, arms))
    out.update(_length_layout(H, bbox))
    return {k: float(v) for k, v in out.items()}


def simplified(G: nx.Graph) -> nx.Graph:
    """A copy of ``G`` with every chain through degree-2 nodes joined into one road (osmnx's
    topological simplification), whatever the road classes; a degree-2 node stays only where
    joining would make a self-loop or a second road between the same two nodes."""
    H = G.copy()
    nx.set_edge_attributes(H, "local", "road_class")  # a class change is no junction here
    return merge_degree2(H)


def junction_arms(H: nx.Graph) -> dict:
    """Node -> list of (bearing in radians, edge) of the roads leaving it, each bearing taken
    to the point ``JUNCTION_REACH_M`` along the road (a kink at the node does not count)."""
    nodes, angles = end_directions(H, JUNCTION_REACH_M)
    edges = list(H.edges)
    arms: dict = defaultdict(list)
    for k, (n, a) in enumerate(zip(nodes, angles)):
        arms[n].append((float(a), edges[k % len(edges)]))
    return arms


def _degree_shares(H: nx.Graph, nodes: set, on_cycle: set) -> dict:
    """Dead-end, 3-way, 4-way+ and on-cycle shares of the road nodes among ``nodes``."""
    degrees = [d for _, d in H.degree(nodes) if d != 2]
    on = sum(1 for n in nodes if H.degree(n) != 2 and n in on_cycle)
    if not degrees:
        return dict.fromkeys(("dead_end_share", "three_way_share", "four_way_share",
                              "cycle_share"), math.nan)
    d = np.array(degrees)
    return {"dead_end_share": np.mean(d == 1), "three_way_share": np.mean(d == 3),
            "four_way_share": np.mean(d >= 4), "cycle_share": on / len(d)}


def _on_cycle(H: nx.Graph) -> set:
    """Nodes on some cycle: those of a biconnected component larger than one bridge
    (as :func:`metrics.cycle_ratio` counts them)."""
    return {n for comp in nx.biconnected_components(H) if len(comp) >= 3 for n in comp}


def _angle_shares(arms: dict, nodes: set) -> dict:
    """At junctions (3+ arms) among ``nodes``: the share of angles between neighbouring arms
    within RIGHT_TOL_DEG of 90° and under ACUTE_DEG, and the share of arms with another arm
    within STRAIGHT_TOL_DEG of straight on the other side (issue 35, "straight-through")."""
    gaps, straight = [], []
    for n in nodes:
        if len(arms.get(n, ())) < 3:
            continue
        a = np.sort([b for b, _ in arms[n]])
        gaps.append(np.degrees(np.diff(np.append(a, a[0] + 2 * math.pi))))
        straight.append(_deviation(a[:, None], a[None, :]).min(axis=1, initial=math.pi,
                                                             where=~np.eye(len(a), dtype=bool)))
    if not gaps:
        return dict.fromkeys(("right_angle_share", "acute_angle_share",
                              "straight_through_share"), math.nan)
    g, s = np.concatenate(gaps), np.concatenate(straight)
    return {"right_angle_share": np.mean(np.abs(g - 90.0) <= RIGHT_TOL_DEG),
            "acute_angle_share": np.mean(g < ACUTE_DEG),
            "straight_through_share": np.mean(s <= math.radians(STRAIGHT_TOL_DEG))}


def _deviation(a, b):
    """How far (radians, 0..π) leaving along bearing ``b`` deviates from going straight on
    after arriving along the arm of bearing ``a`` (arms point away from the node)."""
    return np.abs(np.mod(a - b, 2 * math.pi) - math.pi)


def stroke_lengths(H: nx.Graph, arms: dict | None = None) -> np.ndarray:
    """Lengths of the strokes (:func:`stroke_groups`)."""
    groups = stroke_groups(H, junction_arms(H) if arms is None else arms)
    length: dict = defaultdict(float)
    for e in H.edges:
        length[groups[e]] += edge_length(H, *e)
    return np.array(list(length.values()))


def stroke_groups(H: nx.Graph, arms: dict) -> dict:
    """Edge -> its stroke (an edge standing for it): roads followed straight on through
    junctions (Thomson 2006, "The 'stroke' concept in geographic network generalization").
    At every node the pair of arms closest to straight is joined first, then the next among
    those left, while they deviate by at most STRAIGHT_TOL_DEG; each arm joins at most one
    other. ``arms``: :func:`junction_arms`."""
    strokes = nx.utils.UnionFind(H.edges)
    tol = math.radians(STRAIGHT_TOL_DEG)
    for node_arms in arms.values():
        pairs = sorted((float(_deviation(a, b)), i, j)
                       for i, (a, _) in enumerate(node_arms)
                       for j, (b, _) in enumerate(node_arms) if i < j)
        used: set = set()
        for dev, i, j in pairs:
            if dev <= tol and i not in used and j not in used:
                used |= {i, j}
                strokes.union(node_arms[i][1], node_arms[j][1])
    return {e: strokes[e] for e in H.edges}


def _weighted_median(lengths: np.ndarray) -> float:
    """Length-weighted median: the stroke length that the typical metre of road belongs to
    (an unweighted median would be that of the many short stubs between T-junctions)."""
    if len(lengths) == 0:
        return math.nan
    x = np.sort(lengths)
    cum = np.cumsum(x)
    return float(x[np.searchsorted(cum, cum[-1] / 2)])


def _link_statistics(H: nx.Graph) -> dict:
    """Mean and p10/p50/p90 of road length between road nodes, and circuity (osmnx
    ``circuity_avg``: total length over total straight distance between end nodes)."""
    if H.number_of_edges() == 0:
        return dict.fromkeys(("edge_length_mean", "edge_length_p10", "edge_length_p50",
                              "edge_length_p90", "circuity"), math.nan)
    lengths = np.array([edge_length(H, u, v) for u, v in H.edges])
    straight = sum(math.dist(H.nodes[u]["xy"], H.nodes[v]["xy"]) for u, v in H.edges)
    p10, p50, p90 = np.percentile(lengths, [10, 50, 90])
    return {"edge_length_mean": lengths.mean(), "edge_length_p10": p10, "edge_length_p50": p50,
            "edge_length_p90": p90,
            "circuity": lengths.sum() / straight if straight > 0 else math.nan}


def _blocks(H: nx.Graph) -> np.ndarray:
    """The bounded faces of the road graph (blocks), as shapely polygons."""
    lines = [shapely.LineString(c) for _, _, c in H.edges(data="coords")]
    faces = shapely.get_parts(shapely.polygonize(lines)) if lines else np.array([])
    return np.array([f for f in faces if f.area > 1.0], dtype=object)


def _touches_border(blocks: np.ndarray, bbox: Bbox) -> np.ndarray:
    """Whether each block comes within MARGIN_M of the map border."""
    if len(blocks) == 0:
        return np.zeros(0, dtype=bool)
    b = shapely.bounds(blocks)
    x0, y0, x1, y1 = bbox
    return ((b[:, 0] - x0 < MARGIN_M) | (b[:, 1] - y0 < MARGIN_M)
            | (x1 - b[:, 2] < MARGIN_M) | (y1 - b[:, 3] < MARGIN_M))


def block_statistics(blocks: np.ndarray) -> dict:
    """Median block area, share of blocks under SMALL_BLOCK_M2 and median compactness
    4πA/P² (1 for a disc, π/4 for a square; the isoperimetric quotient)."""
    if len(blocks) == 0:
        return dict.fromkeys(("block_area_median", "small_block_share",
                              "block_compactness_median"), math.nan)
    area, perimeter = shapely.area(blocks), shapely.length(blocks)
    return {"block_area_median": np.median(area),
            "small_block_share": np.mean(area < SMALL_BLOCK_M2),
            "block_compactness_median": np.median(4 * math.pi * area / perimeter**2)}


def _length_layout(H: nx.Graph, bbox: Bbox) -> dict:
    """Where the road length lies: the share within MARGIN_M of the border and parallel to it
    (a frame road; issue 35 finds none in real tiles), and the coefficient of variation of road
    length over CELLS x CELLS cells (real towns are uneven: parks, rail yards, dense cores)."""
    pts, owner = resample_roads(H, SAMPLE_STEP_M)
    same = owner[1:] == owner[:-1]
    d = np.diff(pts, axis=0)[same]
    mid = (pts[1:] + pts[:-1])[same] / 2
    length = np.hypot(*d.T)
    total = length.sum()
    if total <= 0:
        return {"frame_share": math.nan, "length_cv": math.nan}
    x0, y0, x1, y1 = bbox
    near_x = np.minimum(mid[:, 0] - x0, x1 - mid[:, 0]) < MARGIN_M  # by a west or east side
    near_y = np.minimum(mid[:, 1] - y0, y1 - mid[:, 1]) < MARGIN_M
    tol = math.sin(math.radians(PARALLEL_TOL_DEG)) * length
    frame = (near_x & (np.abs(d[:, 0]) <= tol)) | (near_y & (np.abs(d[:, 1]) <= tol))
    ix = np.clip(((mid[:, 0] - x0) / (x1 - x0) * CELLS).astype(int), 0, CELLS - 1)
    iy = np.clip(((mid[:, 1] - y0) / (y1 - y0) * CELLS).astype(int), 0, CELLS - 1)
    cells = np.bincount(iy * CELLS + ix, weights=length, minlength=CELLS * CELLS)
    return {"frame_share": length[frame].sum() / total, "length_cv": cells.std() / cells.mean()}


def _border_distance(xy: np.ndarray, bbox: Bbox) -> float:
    x0, y0, x1, y1 = bbox
    return float(min(xy[0] - x0, x1 - xy[0], xy[1] - y0, y1 - xy[1]))
