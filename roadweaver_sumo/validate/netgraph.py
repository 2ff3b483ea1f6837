"""Graphs read back from a SUMO ``.net.xml``: what netconvert actually built, not what we asked for.

* :func:`road_graph`: the undirected road graph in :mod:`roadweaver_sumo.roadgraph` convention, so
  the shared metrics (density, LCC, dead ends, ...) run on the net exactly as on our own graphs;
* :func:`lane_graph`: the directed lane graph cars drive on (connections and lane changes), for
  lane- and junction-level reachability.

Both read the net with sumolib (``withInternal=True``, so the internal junction lanes are there
for the alignment check as well).
"""

from __future__ import annotations

from itertools import pairwise
from pathlib import Path

import networkx as nx
import numpy as np
import sumolib

from ..errors import RoadweaverError
from ..gc_pause import cyclic_gc_paused
from ..roadgraph import new_road_graph

VEHICLE_CLASS = "passenger"


def load_net(net_path: Path) -> sumolib.net.Net:
    """The net with internal lanes, connections and traffic-light programs; a one-line error
    if it cannot be read."""
    require_net(net_path)
    try:
        with cyclic_gc_paused():
            return sumolib.net.readNet(str(net_path), withInternal=True, withPrograms=True)
    except Exception as exc:  # sumolib raises whatever its SAX handler hits
        raise RoadweaverError(f"cannot read SUMO network {net_path}: {exc}") from exc


def require_net(net_path: Path) -> None:
    """A one-line error if there is no net at ``net_path``."""
    if not Path(net_path).exists():
        raise RoadweaverError(f"network {net_path} not found")


def road_junctions(net: sumolib.net.Net) -> list:
    """Junctions that are places on the map (not the internal junctions inside intersections)."""
    return [n for n in net.getNodes() if n.getType() != "internal"]


def road_edges(net: sumolib.net.Net) -> list:
    """Normal edges: no internal, crossing, walking-area or connector edges."""
    return [e for e in net.getEdges(withInternal=False) if not e.isSpecial()]


def road_graph(net: sumolib.net.Net) -> nx.Graph:
    """Undirected road graph: a node per junction (attr ``xy``), one edge per junction pair
    joined by any normal edge. The polyline is that edge's geometry (the one with the smallest
    id when several, e.g. both directions), with the junction positions as its ends; the road
    class that of :func:`road_class`."""
    x0, y0, x1, y1 = net.getBoundary()
    G = new_road_graph(x1 - x0, y1 - y0)
    for node in road_junctions(net):
        G.add_node(node.getID(), xy=tuple(float(c) for c in node.getCoord()))
    for k, ring in enumerate(net.getRoundabouts()):  # one junction each (metrics)
        for node in ring.getNodes():
            G.nodes[node]["roundabout"] = f"roundabout{k}"
    for edge in sorted(road_edges(net), key=lambda e: e.getID()):
        u, v = edge.getFromNode().getID(), edge.getToNode().getID()
        if u == v or G.has_edge(u, v):
            continue
        G.add_edge(u, v, coords=_edge_polyline(G, edge, u, v), start=u,
                   road_class=road_class(edge))
    return G


def road_class(edge) -> str:
    """An edge's road class: from its OSM highway type where netconvert imported one
    (``highway.primary``), else from the edge priority our export gives each class
    (``hdmap.lanes.LANE_CONFIGS``); local otherwise."""
    from ..data.osm import road_class as osm_road_class
    from ..hdmap.lanes import LANE_CONFIGS

    kind = edge.getType() or ""
    if kind.startswith("highway."):
        return osm_road_class(kind.split(".", 1)[1]) or "local"
    by_priority = {config.priority: cls for cls, config in LANE_CONFIGS.items()}
    return by_priority.get(edge.getPriority(), "local")


#: m: a raw shape that ends this close to its junction is only shifted sideways (netconvert
#: shifts a one-way edge with a sidewalk by half the sidewalk): its end moves onto the
#: junction, where a spur from the junction to it would read as a sharp bend; one farther
#: off gets the junction added
SHIFTED_END_M = 2.0


def _edge_polyline(G: nx.Graph, edge, u: str, v: str) -> np.ndarray:
    """The edge's raw (centreline) shape with both ends on the junction positions."""
    pts = [tuple(p[:2]) for p in edge.getRawShape()]
    ends = (G.nodes[u]["xy"], G.nodes[v]["xy"])
    if np.hypot(*np.subtract(pts[0], ends[0])) > SHIFTED_END_M:
        pts.insert(0, ends[0])
    if np.hypot(*np.subtract(pts[-1], ends[1])) > SHIFTED_END_M:
        pts.append(ends[1])
    coords = np.array(pts, dtype=float)
    coords[0], coords[-1] = ends
    return coords


def lane_graph(net: sumolib.net.Net, vclass: str = VEHICLE_CLASS) -> nx.DiGraph:
    """Directed lane graph for ``vclass``: a node per normal lane that allows it (attrs ``edge``,
    ``from_junction``, ``to_junction``), an arc per connection (``kind="connection"``) and per
    lane change between neighbouring lanes of one edge, both ways (``kind="lane_change"``).

    Lane-change restrictions (``changeLeft``/``changeRight``) are not read: sumolib ignores them
    and our nets do not write them.
    """
    D = nx.DiGraph()
    edges = road_edges(net)
    for edge in edges:
        lanes = [lane for lane in edge.getLanes() if lane.allows(vclass)]
        for lane in lanes:
            D.add_node(
                lane.getID(),
                edge=edge.getID(),
                from_junction=edge.getFromNode().getID(),
                to_junction=edge.getToNode().getID(),
            )
        for a, b in pairwise(lanes):
            if b.getIndex() == a.getIndex() + 1:
                D.add_edge(a.getID(), b.getID(), kind="lane_change")
                D.add_edge(b.getID(), a.getID(), kind="lane_change")
    for edge in edges:
        for conns in edge.getOutgoing().values():
            for conn in conns:
                a, b = conn.getFromLane().getID(), conn.getToLane().getID()
                if a in D and b in D and conn.allows(vclass):
                    D.add_edge(a, b, kind="connection")
    return D


def internal_chain(net: sumolib.net.Net, conn) -> list:
    """The internal lanes a connection drives through, in order (empty without ``via``)."""
    chain = []
    via = conn.getViaLaneID()
    while via:
        lane = net.getLane(via)
        chain.append(lane)
        outgoing = lane.getOutgoing()
        via = outgoing[0].getViaLaneID() if outgoing else ""
    return chain
