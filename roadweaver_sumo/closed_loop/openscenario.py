"""Ego routes as OpenSCENARIO 1.2 files (issue 37): ``ego_route_K.xosc`` on ``map.xodr``.

Users of esmini, CARLA's ScenarioRunner and other OpenSCENARIO players replay our ego routes
without SUMO. Each file places the ego at the middle of its route's first road, assigns the
route as OpenSCENARIO waypoints and drives it at a constant speed with the player's default
controller, which keeps its lane: so the route pins every lane. Per route edge a waypoint in
the middle of the lane the ego leaves it from (``LanePosition`` on the road the edge was
exported to), and one on the junction's connecting road to the next edge's lane; where the
ego must change lanes on an edge, a lane change starts as it enters the edge. A few
background cars drive the roads of the route against the ego. The story ends when the ego,
having driven most of the route, is within :data:`ARRIVAL_M` of the last waypoint, or at a
time limit (the route at half the ego speed).

Ids follow the exporters: SUMO edge ``r<road>_<f|b>`` is OpenDRIVE road ``<road>``, ``f``
lanes to the right of the reference line (SUMO lane 0, the right-most, is ``-n``), ``b`` lanes
to its left (``+n``); see :func:`roadweaver_sumo.export.opendrive.xodr_lane_id`.
"""

from __future__ import annotations

from itertools import pairwise
from pathlib import Path

from lxml import etree

from ..scenario.xmlfile import write_xml
from .routes import car_lanes

FILE = "ego_route_{k}.xosc"
MAP_FILE = "map.xodr"
EGO_SPEED = 10.0  # m/s, below every speed limit the maps use
ARRIVAL_M = 10.0
LANE_CHANGE_SHARE = 0.6  # of the edge where the ego changes lanes
LANE_CHANGE_AT_M = 4.0  # into the edge (at most half of it): where a lane change starts
TRIGGER_M = 1.0  # the ego is there when this close (it moves 0.5 m a step at 10 m/s, 20 Hz)
BACKGROUND_CARS = 3
# A mid-size car: OpenSCENARIO needs a bounding box, performance and axles for every vehicle.
CAR = {"width": 1.8, "length": 4.5, "height": 1.5}


def write_openscenario(folder: Path, routes: list[dict], net) -> list[str]:
    """One ``ego_route_K.xosc`` per route in ``folder``; returns the file names."""
    lengths, connecting = _read_map(Path(folder) / MAP_FILE)
    names = []
    for k, route in enumerate(routes):
        names.append(FILE.format(k=k))
        write_xml(_scenario(route, net, lengths, connecting), Path(folder) / names[-1])
    return names


def lane_position(net, edge_id: str, lengths: dict[str, float], s_share: float = 0.5,
                  lane_index: int | None = None) -> etree._Element:
    """The ``<Position><LanePosition>`` of a point ``s_share`` along the road of SUMO edge
    ``edge_id``, on its lane ``lane_index`` (SUMO's index; None: the right-most driving
    lane)."""
    road, direction = edge_id[1:].rsplit("_", 1)
    if lane_index is None:
        lane_index = car_lanes(net.getEdge(edge_id))[0].getIndex()
    rank = net.getEdge(edge_id).getLaneNumber() - lane_index  # 1: next to the reference line
    along = s_share * lengths[road] if direction == "f" else (1 - s_share) * lengths[road]
    position = etree.Element("Position")
    etree.SubElement(position, "LanePosition", roadId=road,
                     laneId=str(-rank if direction == "f" else rank),
                     s=f"{min(max(along, 0.01), lengths[road] - 0.01):.3f}", offset="0")
    return position


def _scenario(route: dict, net, lengths: dict[str, float],
              connecting: dict[tuple, str]) -> etree._Element:
    root = etree.Element("OpenSCENARIO")
    etree.SubElement(root, "FileHeader", revMajor="1", revMinor="2",
                     date="2026-01-01T00:00:00", author="roadweaver-sumo",
                     description=f"{route['id']}: {route['length_m']:g} m on {MAP_FILE}")
    etree.SubElement(root, "ParameterDeclarations")
    etree.SubElement(root, "CatalogLocations")
    network = etree.SubElement(root, "RoadNetwork")
    etree.SubElement(network, "LogicFile", filepath=MAP_FILE)
    entities = etree.SubElement(root, "Entities")
    board = etree.SubElement(root, "Storyboard")
    actions = etree.SubElement(etree.SubElement(board, "Init"), "Actions")

    edges = route["edges"]
    lanes = _route_lanes(net, edges)
    entities.append(_vehicle("ego"))
    ego = _private(actions, "ego", lane_position(net, edges[0], lengths, lane_index=lanes[0][1]),
                   EGO_SPEED)
    assign = etree.SubElement(etree.SubElement(etree.SubElement(
        ego, "PrivateAction"), "RoutingAction"), "AssignRouteAction")
    assign.append(_route(route["id"], net, edges, lanes, lengths, connecting))
    _lane_changes(board, net, edges, lanes, lengths)

    oncoming = [_reverse(e) for e in edges[1:] if net.hasEdge(_reverse(e))]
    step = max(1, len(oncoming) // (BACKGROUND_CARS + 1))
    for n, edge in enumerate(oncoming[step::step][:BACKGROUND_CARS]):
        entities.append(_vehicle(f"car{n}"))
        _private(actions, f"car{n}", lane_position(net, edge, lengths), EGO_SPEED * 0.8)

    _stop_trigger(etree.SubElement(board, "StopTrigger"), route["length_m"],
                  lane_position(net, edges[-1], lengths, lane_index=lanes[-1][1]))
    return root


def _route(name: str, net, edges: list[str], lanes: list[tuple[int, int]],
           lengths: dict[str, float], connecting: dict[tuple, str]) -> etree._Element:
    """The ``<Route>``: per edge a waypoint on the lane the ego leaves it from, and one on the
    connecting road from there to the lane it enters the next edge on."""
    plan = etree.Element("Route", name=name, closed="false")
    for k, (edge, (_, lane)) in enumerate(zip(edges, lanes)):
        here = lane_position(net, edge, lengths, lane_index=lane)
        etree.SubElement(plan, "Waypoint", routeStrategy="shortest").append(here)
        if k + 1 < len(edges):
            there = lane_position(net, edges[k + 1], lengths, lane_index=lanes[k + 1][0])[0]
            road = connecting[(here[0].get("roadId"), here[0].get("laneId"),
                               there.get("roadId"), there.get("laneId"))]
            etree.SubElement(etree.SubElement(etree.SubElement(
                plan, "Waypoint", routeStrategy="shortest"), "Position"), "LanePosition",
                roadId=road, laneId="-1", s=f"{lengths[road] / 2:.3f}", offset="0")
    return plan


def _stop_trigger(stop: etree._Element, length: float, end: etree._Element) -> None:
    """End the story when the ego has driven 80 % of the route's ``length`` and is near its
    ``end`` (a route may pass near its end before), or at the time limit."""
    arrived = _condition(stop, "arrived", "ByEntityCondition")
    _ego_near(arrived, ARRIVAL_M, end)
    driven = _condition(stop.find("ConditionGroup"), "driven_most", "ByEntityCondition",
                        group=False)
    triggering = etree.SubElement(driven, "TriggeringEntities", triggeringEntitiesRule="any")
    etree.SubElement(triggering, "EntityRef", entityRef="ego")
    etree.SubElement(etree.SubElement(driven, "EntityCondition"), "TraveledDistanceCondition",
                     value=f"{0.8 * length:.0f}")
    timeout = _condition(stop, "time_limit", "ByValueCondition")
    etree.SubElement(timeout, "SimulationTimeCondition",
                     value=f"{2 * length / EGO_SPEED:.0f}", rule="greaterThan")


def _route_lanes(net, edges: list[str]) -> list[tuple[int, int]]:
    """Per route edge, the lane the ego enters it on and the lane it leaves it from (SUMO's
    lane indices; it starts on the right-most driving lane): it keeps its lane where that lane leads on, else it changes to
    the right-most lane that does. Players such as esmini find their way between waypoints
    lane by lane and change lanes only when told."""
    lanes, entered = [], car_lanes(net.getEdge(edges[0]))[0].getIndex()
    for edge, after in pairwise(edges):
        links = net.getEdge(edge).getOutgoing()[net.getEdge(after)]
        usable = sorted(c.getFromLane().getIndex() for c in links)
        leave = entered if entered in usable else usable[0]
        lanes.append((entered if lanes else leave, leave))  # the ego starts on its lane
        entered = next(c.getToLane().getIndex() for c in links
                       if c.getFromLane().getIndex() == leave)
    return lanes + [(entered, entered)]


def _lane_changes(board: etree._Element, net, edges: list[str],
                  lanes: list[tuple[int, int]], lengths: dict[str, float]) -> None:
    """A story of the ego's lane changes: each starts as the ego enters the edge where its
    lane does not lead on, and takes at most :data:`LANE_CHANGE_SHARE` of the edge."""
    changes = [(k, edge, entered, leave) for k, (edge, (entered, leave))
               in enumerate(zip(edges, lanes)) if entered != leave]
    if not changes:
        return
    act = etree.SubElement(etree.SubElement(board, "Story", name="ego_lane_changes"), "Act",
                           name="lane_changes")
    group = etree.SubElement(act, "ManeuverGroup", maximumExecutionCount="1",
                             name="ego_lane_changes")
    actors = etree.SubElement(group, "Actors", selectTriggeringEntities="false")
    etree.SubElement(actors, "EntityRef", entityRef="ego")
    maneuver = etree.SubElement(group, "Maneuver", name="lane_changes")
    for k, edge, entered, leave in changes:
        event = etree.SubElement(maneuver, "Event", name=f"change_{k}", priority="parallel")
        action = etree.SubElement(etree.SubElement(event, "Action", name=f"change_{k}"),
                                  "PrivateAction")
        change = etree.SubElement(etree.SubElement(action, "LateralAction"), "LaneChangeAction")
        length = net.getEdge(edge).getLength()
        etree.SubElement(change, "LaneChangeActionDynamics", dynamicsShape="sinusoidal",
                         dynamicsDimension="distance", value=f"{LANE_CHANGE_SHARE * length:.1f}")
        target = lane_position(net, edge, lengths, lane_index=leave)[0]
        etree.SubElement(etree.SubElement(change, "LaneChangeTarget"), "AbsoluteTargetLane",
                         value=target.get("laneId"))
        _ego_near(_condition(etree.SubElement(event, "StartTrigger"), f"enter_{k}",
                             "ByEntityCondition"), TRIGGER_M,
                  lane_position(net, edge, lengths, lane_index=entered,
                                s_share=min(0.5, LANE_CHANGE_AT_M / length)))
    start = _condition(etree.SubElement(act, "StartTrigger"), "start", "ByValueCondition")
    etree.SubElement(start, "SimulationTimeCondition", value="0", rule="greaterThan")


def _ego_near(condition: etree._Element, metres: float, position: etree._Element) -> None:
    """Fill a ``ByEntityCondition``: the ego is closer than ``metres`` to ``position``."""
    triggering = etree.SubElement(condition, "TriggeringEntities", triggeringEntitiesRule="any")
    etree.SubElement(triggering, "EntityRef", entityRef="ego")
    distance = etree.SubElement(etree.SubElement(condition, "EntityCondition"),
                                "DistanceCondition", value=f"{metres:g}", freespace="false",
                                rule="lessThan")
    distance.append(position)


def _reverse(edge_id: str) -> str:
    """The SUMO edge of the other driving direction of the same road."""
    return edge_id[:-1] + ("b" if edge_id.endswith("f") else "f")


def _condition(parent: etree._Element, name: str, kind: str,
               group: bool = True) -> etree._Element:
    """A condition in a new condition group of trigger ``parent`` (groups are OR-ed), or with
    ``group=False`` in the condition group ``parent`` (conditions are AND-ed); returns its
    ``kind`` element."""
    parent = etree.SubElement(parent, "ConditionGroup") if group else parent
    condition = etree.SubElement(parent, "Condition", name=name, delay="0",
                                 conditionEdge="none")
    return etree.SubElement(condition, kind)


def _vehicle(name: str) -> etree._Element:
    """A ``ScenarioObject`` holding a mid-size car."""
    obj = etree.Element("ScenarioObject", name=name)
    car = etree.SubElement(obj, "Vehicle", name="car", vehicleCategory="car")
    etree.SubElement(car, "ParameterDeclarations")
    box = etree.SubElement(car, "BoundingBox")
    etree.SubElement(box, "Center", x=f"{CAR['length'] * 0.3:g}", y="0",
                     z=f"{CAR['height'] / 2:g}")
    etree.SubElement(box, "Dimensions", **{k: f"{v:g}" for k, v in CAR.items()})
    etree.SubElement(car, "Performance", maxSpeed="50", maxAcceleration="5",
                     maxDeceleration="10")
    axles = etree.SubElement(car, "Axles")
    for tag, x, steering in (("FrontAxle", "2.8", "0.5"), ("RearAxle", "0", "0")):
        etree.SubElement(axles, tag, maxSteering=steering, wheelDiameter="0.6",
                         trackWidth="1.6", positionX=x, positionZ="0.3")
    etree.SubElement(car, "Properties")
    return obj


def _private(actions: etree._Element, name: str, position: etree._Element,
             speed: float) -> etree._Element:
    """Init actions of entity ``name``: teleport to ``position``, then hold ``speed``."""
    private = etree.SubElement(actions, "Private", entityRef=name)
    teleport = etree.SubElement(etree.SubElement(private, "PrivateAction"), "TeleportAction")
    teleport.append(position)
    speed_action = etree.SubElement(etree.SubElement(etree.SubElement(
        private, "PrivateAction"), "LongitudinalAction"), "SpeedAction")
    etree.SubElement(speed_action, "SpeedActionDynamics", dynamicsShape="step", value="0",
                     dynamicsDimension="time")
    target = etree.SubElement(speed_action, "SpeedActionTarget")
    etree.SubElement(target, "AbsoluteTargetSpeed", value=f"{speed:g}")
    return private


def _read_map(xodr: Path) -> tuple[dict[str, float], dict[tuple, str]]:
    """The length of every ``<road>`` of the OpenDRIVE map, and the connecting road of each
    lane-to-lane link through a junction: (incoming road, lane, outgoing road, lane) -> id."""
    lengths, connecting = {}, {}
    for road in etree.parse(str(xodr)).getroot().iterfind("road"):
        lengths[road.get("id")] = float(road.get("length"))
        link = road.find("lanes/laneSection/right/lane/link")
        if road.get("junction") != "-1" and link is not None:
            ends = [road.find(f"link/{tag}").get("elementId") for tag in ("predecessor",
                                                                          "successor")]
            lanes = [link.find(tag).get("id") for tag in ("predecessor", "successor")]
            connecting[(ends[0], lanes[0], ends[1], lanes[1])] = road.get("id")
    return lengths, connecting
