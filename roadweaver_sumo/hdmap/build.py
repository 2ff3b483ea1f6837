"""Road graph to lane-level HD map, the steps of paper Algorithm 1 in order."""

from __future__ import annotations

import networkx as nx

from ..spec import ScenarioSpec
from .control import DEFAULT_RULES, plan_controls
from .geometry import arc_lengths
from .junctions import add_connectors, folding_turns, make_junctions
from .lane_counts import give_lanes
from .lanes import (
    MAX_TRIM_SHARE,
    SIDEWALK_WIDTH,
    build_road_lanes,
    lane_ends,
    make_roads,
    plan_reference_lines,
)
from .model import HDMap, Road
from .movements import junction_plan
from .one_way import choose_one_way
from .roundabouts import add_roundabouts
from .topology import add_successor_links, repair_topology
from .turn_bays import TAPER_LENGTH, add_turn_bays

#: A junction whose turn bends tighter than half its lane's width (its inner lane edge folds
#: over where a reader offsets the lane from its centre line) grows by this factor, up to
#: WIDEN_ROUNDS times; ``junction_trims`` give enough room where roads run straight to it. A
#: junction one of whose roads is too short to be trimmed further (``lanes.MAX_TRIM_SHARE``)
#: does not grow: its other roads alone ended 56 m out beside one ending at 15 m, and SUMO's
#: walkers were lost on the sliver of a walking area between them.
#: A turn that still folds then is banned where its lanes have other ways on, up to
#: BAN_ROUNDS times (the lanes it served take a neighbour lane's movement, which may fold too).
WIDEN_FACTOR, WIDEN_ROUNDS, BAN_ROUNDS = 1.25, 4, 3


def build_hdmap_for(G: nx.Graph, spec: ScenarioSpec) -> HDMap:
    """The HD map of road graph ``G`` with everything ``spec`` asks of it (what
    ``make-scenario`` and ``roadweaver_sumo.generate_map`` build)."""
    return build_hdmap(G, spec.geo_origin, traffic_lights=spec.traffic_lights, rules=spec.rules,
                       one_way_share=spec.one_way_share, sidewalks=spec.sidewalks,
                       speeds=spec.speeds, roundabouts=spec.roundabouts,
                       junction_mix=spec.junction_mix, lanes=spec.lanes)


def build_hdmap(
    G: nx.Graph, geo_origin: tuple[float, float] | None = None, *, traffic_lights: bool = True,
    rules: str = DEFAULT_RULES, one_way_share: float = 0.0, sidewalks: bool = False,
    speeds: dict[str, float] | None = None, roundabouts: int = 0,
    junction_mix: dict[str, float] | None = None, lanes: dict[str, int] | None = None,
) -> HDMap:
    """Build the lane-level HD map of a RoadGraph (paper Algorithm 1).

    ``geo_origin`` is the (lat, lon) of the local origin, written by exporters as the map's
    geo-reference; by default ``G.graph["geo_origin"]`` if present. Junction control follows the
    regional ``rules`` (``control.RULES``); ``traffic_lights=False`` leaves out the lights
    (suburban maps); a ``junction_mix`` (control -> share) overrides both (``control``).
    ``lanes``: lanes per direction by road class, where not the class's own (``lane_counts``).
    Up to ``one_way_share`` of the local street length becomes one-way (``one_way``).
    ``sidewalks``: every road gets a sidewalk of ``SIDEWALK_WIDTH`` right of each driving
    direction. ``speeds``: speed limits in km/h by road class, where not the class's own
    (``lanes.LANE_CONFIGS``). Up to ``roundabouts`` junctions become roundabouts
    (``roundabouts``). Approaches to traffic lights get left-turn bays (``turn_bays``;
    ``HDMap.graph`` is then the road graph with their taper nodes). RepairLaneGeometry needs no
    pass of its own: connectors end exactly on the lanes they join and junction trims leave
    every road a lane section (see ``lanes.MAX_TRIM_SHARE``).
    """
    G = give_lanes(G, lanes)
    plan = plan_controls(G, rules, traffic_lights, junction_mix)
    G = add_roundabouts(G, roundabouts, plan)
    G = add_turn_bays(G, plan)
    hd = HDMap(
        width=float(G.graph["width"]),
        height=float(G.graph["height"]),
        geo_origin=geo_origin if geo_origin is not None else G.graph.get("geo_origin"),
        graph=G,
    )
    sidewalk_width = SIDEWALK_WIDTH if sidewalks else 0.0
    hd.roads = make_roads(G, sidewalk_width, speeds)  # RefineRoadGraph, AssignLaneConfig
    choose_one_way(G, hd.roads, one_way_share)
    nodes = {n: G.nodes[n]["xy"] for n in G.nodes}
    tapers = {n: TAPER_LENGTH / 2 for n, taper in G.nodes(data="taper") if taper}
    rings = {n: ring for n, ring in G.nodes(data="roundabout") if ring is not None}
    hd.junctions = make_junctions(nodes, hd.roads, plan, tapers, rings)
    roads, junctions = list(hd.roads.values()), list(hd.junctions)
    for _ in range(WIDEN_ROUNDS + 1):
        tight = {lane.junction for lane in _lanes_and_connectors(hd, roads, junctions)}
        tight = {node for node in tight if not _trims_at_most(hd, node)}
        if not tight:
            break
        for node in tight:
            trims = hd.junctions[node].trims
            for r, trim in trims.items():
                trims[r] = min(trim * WIDEN_FACTOR, _most_trim(hd, r))
        roads = [hd.roads[r] for r in sorted({r for node in tight for r in hd.junctions[node].roads})]
        junctions = sorted({node for road in roads for node in (road.from_node, road.to_node)})
    banned: set[tuple[str, str]] = set()
    folds = folding_turns(hd.connectors())
    for _ in range(BAN_ROUNDS):
        new = {(lane.predecessors[0], lane.successors[0]): lane.junction for lane in folds}
        new = {pair: node for pair, node in new.items() if pair not in banned}
        if not new:
            break
        banned |= new.keys()
        folds = _lanes_and_connectors(hd, [], sorted(set(new.values())), banned)
    add_successor_links(hd)  # AddSuccessorLinks
    repair_topology(hd)  # RepairTopology
    return hd


def _lanes_and_connectors(hd: HDMap, roads: list[Road], junctions: list[int],
                          banned: set[tuple[str, str]] = frozenset()) -> list:
    """(Re)build the lane section, reference line and lanes of ``roads`` and the connectors of
    ``junctions`` (those at the ends of ``roads``, or all; ``banned`` lane pairs left out
    where ``movements.junction_plan`` can); return the connectors that fold
    (``junctions.folding_turns``)."""
    plan_reference_lines(roads, [(hd.junctions[road.from_node].trims[road.id],
                                  hd.junctions[road.to_node].trims[road.id]) for road in roads])
    for road in roads:  # GenerateLaneBoundaries, ConstructDirectionalLanes
        lanes, sidewalks = build_road_lanes(road)
        hd.lanes.update((lane.id, lane) for lane in lanes)
        hd.sidewalks.update((lane.id, lane) for lane in sidewalks)
    for node in junctions:
        for lane_id in hd.junctions[node].connectors:
            del hd.lanes[lane_id]
        hd.junctions[node].connectors = []
    touching = dict.fromkeys(lane_id for node in junctions for r in hd.junctions[node].roads
                             for direction in "fb" for lane_id in hd.roads[r].lanes(direction))
    ends = lane_ends(map(hd.lanes.__getitem__, touching))
    plan = [(node, *entry) for node in junctions
            for entry in junction_plan(hd, node, ends, banned)]
    return folding_turns(add_connectors(hd, plan, ends))  # ConstructJunctionConnections


def _most_trim(hd: HDMap, rid: int) -> float:
    """How far road ``rid`` may be trimmed at either end (``lanes.MAX_TRIM_SHARE``)."""
    return MAX_TRIM_SHARE * arc_lengths(hd.roads[rid].centreline)[-1]


def _trims_at_most(hd: HDMap, node: int) -> bool:
    """Whether a road of junction ``node`` is trimmed as far as its length allows."""
    return any(trim >= _most_trim(hd, r) for r, trim in hd.junctions[node].trims.items())
