"""Stage 2: expand the skeleton into a connected road graph at the target density (§III-C)."""

from __future__ import annotations

import networkx as nx
import numpy as np
import shapely

from ..errors import RoadweaverError
from ..metrics import road_node_count
from ..roadgraph import add_road, edge_coords, edge_length, edge_list, sorted_edge_list
from ..skeleton import Skeleton
from ..skeleton.procedural import block_size
from ..spec import STAGE_FILL, STAGE_GROWTH, TOWN_MARGIN, ScenarioSpec
from .bends import cut_sharp_bends, smooth_bends
from .boundary import on_map_edge, opened, spare_when_opened
from .cleanup import (
    MIN_BLOCK_AREA,
    clean,
    dissolve_degree_two,
    keep_largest_component,
    remove_close_roads,
)
from .dead_ends import add_dead_ends
from .fill import fill_to_density, prune_to_density
from .growth import grow_collectors, skeleton_tensor_field
from .local_density import block_weight
from .planar import build_planar_graph
from .reconnect import link_components, reconnect_dangles

MIN_EDGE = 12.0  # metres: shorter roads are merged into a junction
MIN_ANGLE = 30.0  # degrees between roads at a junction
BORDER_MARGIN = 30.0  # dead ends this close to the border are roads cut off by the map edge
DENSITY_ROUNDS = 4  # fill/prune/clean rounds: clean-up may merge junctions, so measure again
DENSITY_TOLERANCE = 0.02
DENSITY_LIMIT = 0.10  # beyond this the request counts as impossible (issue 2: within 10 %)


def expand_skeleton(spec: ScenarioSpec, skeleton: Skeleton) -> nx.Graph:
    """Growth -> A* reconnection (dead ends, then whole components) -> the ring's component ->
    fill/prune to the target density -> for an open map (``spec.boundary``), built as a larger
    town with a fill that follows the road field (:mod:`.local_density`), the map cut out of
    the town and dead-end streets."""
    town = spec.town()  # an open map is cut out of it at the end
    field = skeleton_tensor_field(skeleton)
    collectors = grow_collectors(town, skeleton, field, spec.rng(STAGE_GROWTH))
    roads = list(zip(skeleton.polylines, skeleton.road_classes()))
    roads += [(c, "collector") for c in collectors]
    roads.append((skeleton.frame, "collector"))
    G = build_planar_graph(roads, town.width, town.height)
    stub = 0.5 * block_size(spec.density)
    clean(G, MIN_EDGE, MIN_ANGLE, stub=MIN_EDGE, margin=BORDER_MARGIN, keep_largest=False)
    cost = skeleton.cost_map()
    links = reconnect_dangles(G, cost, skeleton.res, radius=2 * stub, margin=BORDER_MARGIN)
    links += link_components(G, cost, skeleton.res, radius=4 * stub, pending=links)
    if links:
        G = _renode(G, [(c, "collector") for c in links])
    clean(G, MIN_EDGE, MIN_ANGLE, stub=stub, margin=BORDER_MARGIN)
    target = spec.target_road_nodes
    aim = round(target * town.area_km2 / spec.area_km2)
    rng = spec.rng(STAGE_FILL)
    # The town, the fill that follows the road field and dead-end streets (issue 35) make the
    # maps of an open boundary; a ring map is the map earlier versions made, so that suites
    # written then rebuild unchanged.
    weight = None
    if spec.boundary == "open":
        weight = block_weight(skeleton, (TOWN_MARGIN, TOWN_MARGIN, TOWN_MARGIN + spec.width,
                                         TOWN_MARGIN + spec.height))
    tolerance = max(1, DENSITY_TOLERANCE * target)
    closest = None  # of the opened maps
    for _ in range(DENSITY_ROUNDS):
        fill_to_density(G, aim, field, rng, MIN_EDGE, MIN_ANGLE, stub=stub, weight=weight)
        prune_to_density(G, aim, stub,
                         spare=spare_when_opened(G) if spec.boundary == "open" else None)
        # The fill keeps the graph planar, but the clean-up before it may not have: merging
        # junctions that no road joins moves roads, which can then cross a neighbour. Such
        # a graph is noded again.
        if not _roads_meet_only_at_ends(G):
            G = _renode(G, [])
        clean(G, MIN_EDGE, MIN_ANGLE, stub=stub, margin=BORDER_MARGIN,
              min_block_area=MIN_BLOCK_AREA)
        if spec.boundary == "ring":
            if abs(road_node_count(G) - target) <= tolerance:
                break
            continue
        # What cutting the map out takes varies: aim by the error left (twice a shortfall:
        # part of what the fill adds lands outside the map, and a cut map above the target
        # is pruned to it), keep the closest cut map and stop early only on a hit (one node
        # is 5 % of a small map's target).
        final = _opened_to_density(G, target, stub)
        kept = road_node_count(final)
        if closest is None or abs(kept - target) < abs(road_node_count(closest) - target):
            closest = final
        if abs(kept - target) <= DENSITY_TOLERANCE * target:
            break
        aim += 2 * (target - kept) if kept < target else target - kept
    if spec.boundary == "open":
        G = closest
        city = spec.like["statistics"].get("dead_end_share_inner") if spec.like else None
        add_dead_ends(G, rng, BORDER_MARGIN, MIN_ANGLE, spec.density, share=city)
        _keep_roads_clear(G)
    cut_sharp_bends(G)
    _check_density(spec, road_node_count(G))
    return _relabel(G)


def _opened_to_density(G: nx.Graph, target: int, stub: float) -> nx.Graph:
    """``G`` opened (:func:`.boundary.opened`) and, where opening left more road nodes than
    ``target``, pruned to it: what opening takes varies from map to map, what pruning the
    opened map takes does not."""
    H = opened(G)
    if road_node_count(H) > target:
        prune_to_density(H, target)
        _prune_fringe(H, target)
        dissolve_degree_two(H, MIN_ANGLE)
        smooth_bends(H)
    _keep_roads_clear(H)
    return H


def _keep_roads_clear(G: nx.Graph) -> None:
    """The clean-up's clearance pass once more, for a map changed after its clean-up (cut out
    of its town, pruned, roads joined at dissolved junctions, dead ends cut): a joined road can
    bend within another's lanes (robustness sweep, learned grid 2330 m d90.1 s9409: an
    arterial 4.6 m from a collector's centre line)."""
    if remove_close_roads(G):
        keep_largest_component(G)
        dissolve_degree_two(G, MIN_ANGLE)
        smooth_bends(G)


def _prune_fringe(G: nx.Graph, target: int) -> None:
    """Remove fringe roads (a dead end at the map edge, a junction at the other end) that are
    not arterials, shortest first, while above ``target`` road nodes: what is left to prune in
    a sparse opened map whose roads form a tree."""
    count = road_node_count(G)
    ends = [u for u, degree in G.degree() if degree == 1 and on_map_edge(G, u)]
    fringe = sorted((edge_length(G, u, v), u, v) for u in ends for v in G.neighbors(u)
                    if G.edges[u, v]["road_class"] != "arterial")
    for _, u, v in fringe:
        if count <= target:
            return
        if G.degree(v) >= 3:
            G.remove_node(u)
            count -= 1 + (G.degree(v) == 2)


def _check_density(spec: ScenarioSpec, achieved: int) -> None:
    """A map that misses the requested density is an error, not a silent approximation."""
    target = spec.target_road_nodes
    if abs(achieved - target) > max(1, DENSITY_LIMIT * target):
        raise RoadweaverError(
            f"could place only {achieved} road nodes ({achieved / spec.area_km2:.1f}/km²) "
            f"for the requested {spec.density:g}/km² on a {spec.width:g} x {spec.height:g} m "
            "map; blocks cannot be split further without roads closer than "
            f"{MIN_EDGE:g} m or junction angles below {MIN_ANGLE:g}°"
        )


def _roads_meet_only_at_ends(G: nx.Graph) -> bool:
    """Whether no road crosses or touches another (or itself) anywhere but at their end
    nodes: GEOS's simplicity test of all roads as one multi-line."""
    roads = [data["coords"] for _, _, data in edge_list(G)]
    if not roads:
        return True
    which = np.repeat(np.arange(len(roads)), [len(c) for c in roads])
    lines = shapely.linestrings(np.concatenate(roads), indices=which)
    return bool(shapely.is_simple(shapely.multilinestrings(lines)))


def _renode(G: nx.Graph, extra: list) -> nx.Graph:
    roads = [(data["coords"], data["road_class"]) for _, _, data in sorted_edge_list(G)]
    return build_planar_graph(roads + extra, G.graph["width"], G.graph["height"])


def _relabel(G: nx.Graph) -> nx.Graph:
    """Number nodes 0..n-1 by position so ids and iteration order do not depend on the history
    of edits (determinism of every later file)."""
    order = sorted(G.nodes, key=lambda n: G.nodes[n]["xy"])
    new_id = {n: k for k, n in enumerate(order)}
    H = nx.Graph(**G.graph)
    for n in order:
        H.add_node(new_id[n], xy=tuple(float(c) for c in G.nodes[n]["xy"]))
    edges = sorted((min(new_id[u], new_id[v]), max(new_id[u], new_id[v]), u, v) for u, v in G.edges)
    for a, b, u, v in edges:
        data = G.edges[u, v]
        coords = edge_coords(G, u, v) if new_id[u] == a else edge_coords(G, v, u)
        add_road(H, a, b, coords, data["road_class"])
    return H
