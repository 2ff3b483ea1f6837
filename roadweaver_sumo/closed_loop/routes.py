"""Ego routes for closed-loop evaluation (issue 37): long routes through the map's situations.

A driving stack is judged along long routes, where its planning failures accumulate (CARLA
Leaderboard, Bench2Drive; paper §I). A route here chains shortest paths through random inner
waypoints until it reaches the asked length (± :data:`LENGTH_TOLERANCE`), starting and ending
on edges away from the map's fringe. Of :data:`CANDIDATES_PER_ROUTE` candidates per route
asked for, the routes are picked greedily by the situations they add: each turn is named by
its direction and the control of the junction it is made at (``left@traffic_light``,
``straight@priority`` ...), with turns that need a lane change first (not every lane of the
approach leads there) counted as ``lane_change_for_turn``.
"""

from __future__ import annotations

import json
from collections import Counter
from itertools import pairwise
from pathlib import Path

import networkx as nx
import numpy as np
from lxml import etree

from ..errors import RoadweaverError
from ..scenario.xmlfile import write_xml

ROUTES_FILE = "ego_routes.rou.xml"
LIST_FILE = "routes.json"
CARLA_FILE = "carla_routes.xml"
EGO_TYPE = "ego"
EGO_DEPART_S = 120.0  # background traffic has filled the map by then
LENGTH_TOLERANCE = 0.10
FRINGE_M = 100.0  # a route starts and ends at least this far from the map border
CANDIDATES_PER_ROUTE = 12
MAX_TRIES_PER_ROUTE = 100  # a try fails where no road is left to go on or it misses the length
MAX_LEGS = 40
DIRECTION = {"s": "straight", "l": "left", "r": "right", "t": "u_turn", "L": "left",
             "R": "right"}


def pick_ego_routes(net, count: int, length: float, seed: int) -> list[dict]:
    """``count`` routes of about ``length`` metres on the sumolib ``net``, each a dict with
    ``id``, ``edges``, ``length_m`` and ``situations`` (kind -> count)."""
    inner = _inner_edges(net)
    if len(inner) < 2:
        raise RoadweaverError("ego routes: the map has no two roads away from its fringe")
    rng = np.random.default_rng([seed, 37])
    graph = _edge_graph(net)
    candidates = []
    for _ in range(count * MAX_TRIES_PER_ROUTE):
        if len(candidates) == count * CANDIDATES_PER_ROUTE:
            break
        edges = _chained_route(net, graph, inner, length, rng)
        if edges is not None:
            candidates.append({"edges": edges, "situations": situations(net, edges),
                               "length_m": round(sum(net.getEdge(e).getLength()
                                                     for e in edges), 1)})
    if len(candidates) < count:
        raise RoadweaverError(f"ego routes: found {len(candidates)} routes of {length:g} m "
                              f"± {100 * LENGTH_TOLERANCE:g} %, asked for {count}; ask for "
                              "shorter routes (--ego-length) or a larger map")
    chosen, seen = [], Counter()
    for k in range(count):
        best = max(candidates, key=lambda c: (len(set(c["situations"]) - set(seen)),
                                              sum(c["situations"].values())))
        candidates.remove(best)
        seen.update(best["situations"])
        chosen.append({"id": f"ego_route_{k}", "vehicle": f"ego_{k}", **best})
    return chosen


def situations(net, edge_ids: list[str]) -> dict[str, int]:
    """The turns of a route (SUMO edge ids) by direction and junction control, and the turns
    that need a lane change before them."""
    found = Counter()
    for a, b in pairwise(net.getEdge(e) for e in edge_ids):
        links = a.getOutgoing().get(b, [])
        if not links:
            continue
        found[f"{DIRECTION.get(links[0].getDirection(), 'other')}@{a.getToNode().getType()}"] += 1
        if len({c.getFromLane().getIndex() for c in links}) < len(car_lanes(a)):
            found["lane_change_for_turn"] += 1
    return dict(sorted(found.items()))


def write_ego_routes(folder: Path, routes: list[dict], net) -> None:
    """``ego_routes.rou.xml`` (the ``ego`` type, each route and an ego vehicle on it, for
    ``sumo -c scenario.sumocfg --route-files demand.rou.xml,ego_routes.rou.xml``),
    ``routes.json`` (each route's length, edges and situations), ``carla_routes.xml`` and
    one ``ego_route_K.xosc`` per route (OpenSCENARIO on the ``map.xodr`` already in
    ``folder``)."""
    from .openscenario import write_openscenario

    root = etree.Element("routes")
    etree.SubElement(root, "vType", id=EGO_TYPE, vClass="passenger", color="1,0,0",
                     speedFactor="1", speedDev="0")
    for route in routes:
        etree.SubElement(root, "route", id=route["id"], edges=" ".join(route["edges"]))
    for route in routes:
        etree.SubElement(root, "vehicle", id=route["vehicle"], type=EGO_TYPE,
                         route=route["id"], depart=f"{EGO_DEPART_S:g}", departLane="best")
    write_xml(root, Path(folder) / ROUTES_FILE)
    (Path(folder) / LIST_FILE).write_text(json.dumps(routes, indent=2) + "\n", encoding="utf-8")
    write_carla_routes(Path(folder) / CARLA_FILE, routes, net)
    write_openscenario(Path(folder), routes, net)


def write_carla_routes(path: Path, routes: list[dict], net) -> None:
    """The routes in CARLA Leaderboard's route format: a ``position`` in the middle of each
    route edge's right-most driving lane, in CARLA's frame for ``map.xodr`` (CARLA turns OpenDRIVE's y
    round: y = -y; our SUMO net and map.xodr share x and y). ``town`` is ``map``: load
    ``map.xodr`` as a standalone OpenDRIVE world."""
    from sumolib.geomhelper import positionAtShapeOffset

    root = etree.Element("routes")
    for k, route in enumerate(routes):
        element = etree.SubElement(root, "route", id=str(k), town="map")
        waypoints = etree.SubElement(element, "waypoints")
        for edge in route["edges"]:
            lane = car_lanes(net.getEdge(edge))[0]
            x, y = positionAtShapeOffset(lane.getShape(), lane.getLength() / 2)
            etree.SubElement(waypoints, "position", x=f"{x:.3f}", y=f"{-y:.3f}", z="0.0")
    write_xml(root, path)


def car_lanes(edge) -> list:
    """The lanes of a sumolib edge that cars may drive, right-most first (a sidewalk is lane
    0 where the road has one)."""
    return [lane for lane in edge.getLanes() if lane.allows("passenger")]


def read_ego_routes(folder: Path) -> list[dict]:
    """The routes of ``folder/routes.json``; a one-line error if there are none."""
    path = Path(folder) / LIST_FILE
    try:
        return json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise RoadweaverError(f"{folder} has no ego routes ({LIST_FILE}); make the scenario "
                              "with --ego-routes N") from None
    except (OSError, json.JSONDecodeError) as exc:
        raise RoadweaverError(f"cannot read {path}: {exc}") from None


def _road(edge_id: str) -> str:
    """The road of a SUMO edge: ``r7`` for ``r7_f`` and ``r7_b``."""
    return edge_id.rsplit("_", 1)[0]


def _inner_edges(net) -> list:
    """Roads cars may drive whose both ends lie farther than FRINGE_M from the border."""
    x0, y0, x1, y1 = net.getBoundary()

    def inside(node) -> bool:
        x, y = node.getCoord()[:2]
        return min(x - x0, y - y0, x1 - x, y1 - y) > FRINGE_M

    return sorted(e.getID() for e in net.getEdges(withInternal=False)
                  if e.allows("passenger") and inside(e.getFromNode()) and inside(e.getToNode()))


def _edge_graph(net) -> nx.DiGraph:
    """Edges that cars may drive as nodes, a link for each turn but U-turns, weighted by the
    length of the edge turned into."""
    graph = nx.DiGraph()
    for edge in (e for e in net.getEdges(withInternal=False) if e.allows("passenger")):
        for after, links in edge.getOutgoing().items():
            if after.allows("passenger") and any(c.getDirection() not in "tT" for c in links):
                graph.add_edge(edge.getID(), after.getID(), length=after.getLength())
    return graph


def _chained_route(net, graph: nx.DiGraph, inner: list[str], length: float,
                   rng) -> list[str] | None:
    """Shortest paths from a random inner edge through random inner waypoints, cut at the
    first inner edge where the route is long enough; None if it misses the tolerance. No road
    is driven twice: a route that comes back along a road tests less, and players that follow
    OpenSCENARIO routes road by road (esmini) lose their way on it."""
    ends = set(inner)
    route = [inner[rng.integers(len(inner))]]
    used = {_road(route[0])}
    total = net.getEdge(route[0]).getLength()
    for _ in range(MAX_LEGS):
        target = inner[rng.integers(len(inner))]
        if _road(target) in used:
            continue
        free = nx.subgraph_view(graph, filter_node=lambda e: e == route[-1] or _road(e) not in used)
        try:
            path = nx.shortest_path(free, route[-1], target, weight="length")
        except (nx.NetworkXNoPath, nx.NodeNotFound):
            continue
        if len({_road(e) for e in path[1:]}) < len(path) - 1:
            continue  # the path itself drives a road both ways (round a block)
        for edge in path[1:]:
            route.append(edge)
            used.add(_road(edge))
            total += net.getEdge(edge).getLength()
            if total >= (1 - LENGTH_TOLERANCE) * length and edge in ends:
                return route if total <= (1 + LENGTH_TOLERANCE) * length else None
    return None
