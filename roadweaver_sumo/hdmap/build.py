"""Road graph to lane-level HD map, the steps of paper Algorithm 1 in order."""

from __future__ import annotations

import networkx as nx

from .junctions import add_connectors, make_junctions
from .lanes import build_road_lanes, lane_ends, make_roads, plan_reference_lines
from .model import HDMap
from .movements import junction_plan
from .topology import add_successor_links, repair_topology


def build_hdmap(
    G: nx.Graph, geo_origin: tuple[float, float] | None = None, *, traffic_lights: bool = True
) -> HDMap:
    """Build the lane-level HD map of a RoadGraph (paper Algorithm 1).

    ``geo_origin`` is the (lat, lon) of the local origin, written by exporters as the map's
    geo-reference; by default ``G.graph["geo_origin"]`` if present. ``traffic_lights=False``
    makes every junction but dead ends a priority junction (suburban maps).
    RepairLaneGeometry needs no pass of its own: connectors end exactly on the lanes they join
    and junction trims leave every road a lane section (see ``lanes.MAX_TRIM_SHARE``).
    """
    hd = HDMap(
        width=float(G.graph["width"]),
        height=float(G.graph["height"]),
        geo_origin=geo_origin if geo_origin is not None else G.graph.get("geo_origin"),
        graph=G,
    )
    hd.roads = make_roads(G)  # RefineRoadGraph, AssignLaneConfig
    nodes = {n: G.nodes[n]["xy"] for n in G.nodes}
    hd.junctions = make_junctions(nodes, hd.roads, traffic_lights)
    roads = list(hd.roads.values())
    plan_reference_lines(roads, [(hd.junctions[road.from_node].radius,
                                  hd.junctions[road.to_node].radius) for road in roads])
    for road in roads:  # GenerateLaneBoundaries, ConstructDirectionalLanes
        hd.lanes.update((lane.id, lane) for lane in build_road_lanes(road))
    ends = lane_ends(hd.lanes.values())
    nodes = list(hd.junctions)
    plans = [junction_plan(hd, node, ends) for node in nodes]
    plan = [(node, *entry) for node, entries in zip(nodes, plans, strict=True)
            for entry in entries]
    add_connectors(hd, plan, ends)  # ConstructJunctionConnections, MergeLaneInstances
    add_successor_links(hd)  # AddSuccessorLinks
    repair_topology(hd)  # RepairTopology
    return hd
