"""Drive a controller along an ego route through a scenario, over libsumo (issue 37).

Each step the controller gets an observation (:func:`observe`) and returns what the ego should
do: ``{"acceleration": a}`` or ``{"speed": v}`` (m/s², m/s), optionally with ``"lane_change":
-1 | 0 | 1`` (right, keep, left). SUMO runs the rest: the background traffic, and the ego's
steering along its route. An external controller drives with all of SUMO's own safety checks
off (speed mode 0), so what it does is what is scored. ``controller=None`` lets SUMO's own
driver drive (``--controller sumo``): the reference that must finish every route cleanly.

Infractions are detected from the run itself: a red light is a signal link the ego passes
whose state was red in the step it crossed the stop line (read from the traffic light itself
after the step, beside what the ego saw before it); a stop sign is a link of SUMO's state
``s`` or ``w`` (all-way) the ego takes without having stood still within STOP_ZONE_M of its
line; speeding is a stretch above the lane's limit (``score``); collisions are SUMO's,
junctions included; near misses come from SUMO's SSM device. libsumo holds one simulation per
process.
"""

from __future__ import annotations

import contextlib
import importlib
import math
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

from ..errors import RoadweaverError
from ..scenario.sumocfg import SUMOCFG_FILE
from ..sumo_tools import binary
from .routes import EGO_DEPART_S, read_ego_routes
from .score import SPEEDING_MIN_S, driving_score, over_limit

EGO = "ego"
RADIUS_M = 50.0  # vehicles and persons within this distance are observed
BLOCKED_S = 180.0  # standing this long (not at a red light) ends the run as blocked
ROUTE_AHEAD = 5  # edges of the route ahead in an observation
MIN_SPEED_MS = 3.0  # the run's time limit assumes at least this average speed, plus BLOCKED_S
RED = "rR"
STOP_STATES = "sw"  # SUMO link states: a stop sign, an all-way stop
HALT_MS, STOP_ZONE_M = 0.1, 10.0  # standing still this close to a stop line counts as a stop
SSM_THRESHOLDS = "1.5 1.0"  # s: TTC and PET below which SUMO's SSM device logs a conflict

Controller = Callable[[dict], dict]


def run(scenario_dir: Path, controller: Controller | str | None, route: int = 0,
        remote_port: int | None = None) -> dict:
    """Drive ``controller`` (a callable, ``"sumo"``, ``"naive"`` or ``"module:function"``)
    along ego route ``route`` of the scenario; returns the drive report (score, infractions,
    step timing).

    With ``remote_port`` the ego is driven by a stack in another process instead: SUMO serves
    TraCI on that port for two clients, this loop (client order 1) adds the ego ``"ego"`` and
    scores it, the stack connects as the second client (``traci.init(port);
    traci.setOrder(2)``), steps along and controls the ego itself."""
    folder = Path(scenario_dir)
    routes = read_ego_routes(folder)
    if not 0 <= route < len(routes):
        raise RoadweaverError(f"--route {route}: the scenario has routes 0..{len(routes) - 1}")
    plan = routes[route]
    if remote_port is not None and controller is not None:
        raise RoadweaverError("give --controller or --remote-port, not both: with "
                              "--remote-port the stack on that port drives the ego")
    control = resolve_controller(controller)
    with tempfile.TemporaryDirectory(prefix="roadweaver-drive-") as tmp:
        command = [binary("sumo"), "-c", str(folder / SUMOCFG_FILE), "--no-warnings", "true",
                   "--error-log", str(Path(tmp) / "errors.log"),
                   "--collision.action", "warn", "--collision.check-junctions", "true"]
        if remote_port is None:
            import libsumo as traci

            traci.start(command)
        else:
            import traci

            with contextlib.redirect_stdout(sys.stderr):  # its connection retries: not --json
                traci.start(command + ["--num-clients", "2"], port=remote_port)
            traci.setOrder(1)
        try:
            report = _drive(traci, plan, control, Path(tmp) / "ssm.xml")
        finally:
            traci.close()
        report["near_misses"] = near_misses(Path(tmp) / "ssm.xml")
    label = (f"external (TraCI port {remote_port})" if remote_port is not None else
             controller if isinstance(controller, str) or controller is None
             else getattr(controller, "__name__", "callable"))
    return {"route": plan["id"], "route_length_m": plan["length_m"], "controller": label,
            **report}


def resolve_controller(controller) -> Controller | None:
    if controller is None or controller == "sumo":
        return None
    if controller == "naive":
        return naive_controller
    if callable(controller):
        return controller
    module, _, name = str(controller).partition(":")
    try:
        found = getattr(importlib.import_module(module), name)
    except (ImportError, AttributeError, ValueError):
        raise RoadweaverError(f"--controller {controller!r}: not sumo, naive or an importable "
                              "module:function") from None
    if not callable(found):
        raise RoadweaverError(f"--controller {controller!r} is not a function")
    return found


def naive_controller(obs: dict) -> dict:
    """Ignores signals and speed limits (drives 30 % above the limit) but keeps its distance
    to the vehicle ahead: what the score must catch."""
    target = 1.3 * obs["speed_limit"]
    accel = max(-4.5, min(2.6, target - obs["speed"]))
    leader = obs["leader"]
    if leader is not None and leader["gap"] < 5.0 + 1.5 * obs["speed"]:
        accel = -4.5
    return {"acceleration": accel}


def _drive(traci, plan: dict, control: Controller | None, ssm_file: Path) -> dict:
    traci.vehicletype.copy("DEFAULT_VEHTYPE", EGO)
    traci.vehicletype.setSpeedFactor(EGO, 1.0)
    traci.vehicletype.setSpeedDeviation(EGO, 0.0)
    traci.vehicletype.setColor(EGO, (255, 0, 0, 255))
    for key, value in {"has.ssm.device": "true", "device.ssm.measures": "TTC PET",
                       "device.ssm.thresholds": SSM_THRESHOLDS, "device.ssm.file": str(ssm_file),
                       "device.ssm.trajectories": "false"}.items():
        traci.vehicletype.setParameter(EGO, key, value)
    traci.route.add(plan["id"], plan["edges"])
    traci.vehicle.add(EGO, plan["id"], typeID=EGO, depart=f"{EGO_DEPART_S:g}",
                      departLane="best", departSpeed="0")
    dt = traci.simulation.getDeltaT()
    while EGO not in traci.vehicle.getIDList():
        if traci.simulation.getTime() > EGO_DEPART_S + BLOCKED_S:
            raise RoadweaverError(f"the ego could not enter {plan['edges'][0]} within "
                                  f"{BLOCKED_S:g} s")
        traci.simulationStep()
    traci.vehicle.subscribeContext(EGO, traci.constants.CMD_GET_VEHICLE_VARIABLE, RADIUS_M,
                                   [traci.constants.VAR_POSITION, traci.constants.VAR_SPEED])
    if control is not None:
        traci.vehicle.setSpeedMode(EGO, 0)
    deadline = traci.simulation.getTime() + plan["length_m"] / MIN_SPEED_MS + BLOCKED_S
    edges, infractions = set(plan["edges"]), []
    speeding_since, speeding_reported, standing_since, arrived = None, False, None, False
    halted_on = None  # the last lane the ego stood still on, near its end
    sumo_s = loop_s = 0.0
    steps = 0
    while True:
        began = time.perf_counter()
        now = traci.simulation.getTime()
        obs = observe(traci, plan, halted_on)
        signal = obs["next_signal"]
        # inside a junction the lane speed is a curve speed, not a legal limit
        if not obs["edge"].startswith(":") and over_limit(obs["speed"], obs["speed_limit"]):
            speeding_since = now if speeding_since is None else speeding_since
            if now - speeding_since >= SPEEDING_MIN_S and not speeding_reported:
                infractions.append({"type": "speeding", "time": speeding_since,
                                    "edge": obs["edge"], "limit_ms": obs["speed_limit"],
                                    "speed_ms": round(obs["speed"], 2)})
                speeding_reported = True
        elif not obs["edge"].startswith(":"):
            speeding_since, speeding_reported = None, False
        if control is not None:
            _apply(traci, control(obs), obs["speed"], dt)
        stepped = time.perf_counter()
        traci.simulationStep()
        done = time.perf_counter()
        sumo_s += done - stepped
        loop_s += stepped - began
        steps += 1
        if EGO in traci.simulation.getArrivedIDList():
            arrived = True
            break
        for c in traci.simulation.getCollisions():
            if EGO in (c.collider, c.victim):
                other = c.victim if c.collider == EGO else c.collider
                kind = "collision_person" if "person" in (c.colliderType, c.victimType) \
                    else "collision"
                infractions.append({"type": kind, "time": now + dt, "lane": c.lane,
                                    "other": other, "ego_role": "collider"
                                    if c.collider == EGO else "victim"})
        if EGO in traci.simulation.getStartingTeleportIDList() or \
                EGO not in traci.vehicle.getIDList():
            infractions.append({"type": "teleport", "time": now + dt, "edge": obs["edge"]})
            break
        crossed = _crossed_red(traci, signal)
        if crossed:
            infractions.append({"type": "red_light", "time": now, **crossed})
        lane = traci.vehicle.getLaneID(EGO)
        if lane != obs["lane"] and not obs["lane"].startswith(":"):
            sign = _passed_stop_sign(traci, obs["lane"], lane, halted_on == obs["lane"])
            if sign:
                infractions.append({"type": "stop_sign", "time": now, **sign})
        if traci.vehicle.getSpeed(EGO) < HALT_MS and not lane.startswith(":") and \
                traci.lane.getLength(lane) - traci.vehicle.getLanePosition(EGO) < STOP_ZONE_M:
            halted_on = lane
        road = traci.vehicle.getRoadID(EGO)
        if not road.startswith(":") and road not in edges:
            infractions.append({"type": "off_route", "time": now + dt, "edge": road})
            break
        standing = traci.vehicle.getSpeed(EGO) < 0.1 and not (
            signal and signal["state"] in RED and signal["distance"] < 30.0)
        standing_since = (standing_since or now) if standing else None
        if standing_since is not None and now - standing_since >= BLOCKED_S:
            infractions.append({"type": "blocked", "time": standing_since, "edge": road})
            break
        if now >= deadline:
            break
    distance = plan["length_m"] if arrived else traci.vehicle.getDistance(EGO)
    completion = 1.0 if arrived else min(1.0, max(0.0, distance / plan["length_m"]))
    return {"arrived": arrived, "end_time": traci.simulation.getTime(),
            **driving_score(completion, infractions), "infractions": infractions,
            "steps": steps, "sumo_step_ms": round(1e3 * sumo_s / max(steps, 1), 4),
            "loop_overhead_ms": round(1e3 * loop_s / max(steps, 1), 4)}


def near_misses(ssm_file: Path) -> dict:
    """The ego's conflicts that SUMO's SSM device logged (time to collision or post-encroachment
    time below :data:`SSM_THRESHOLDS`): each with its time, the other vehicle and the least
    TTC and PET, and the least of each over the run. Near misses are reported, not scored."""
    from lxml import etree

    conflicts = []
    if ssm_file.exists():
        for conflict in etree.parse(str(ssm_file)).getroot().iter("conflict"):
            found = {tag: conflict.find(tag) for tag in ("minTTC", "PET")}
            least = {tag: float(e.get("value")) for tag, e in found.items()
                     if e is not None and e.get("value") not in (None, "NA")}
            if least:
                conflicts.append({"time": float(conflict.get("begin")),
                                  "other": conflict.get("foe"), **least})
    return {"count": len(conflicts), "conflicts": conflicts,
            **{f"least_{tag}": min((c[tag] for c in conflicts if tag in c), default=None)
               for tag in ("minTTC", "PET")}}


def observe(traci, plan: dict, halted_on: str | None = None) -> dict:
    """What a driving stack sees of the ego and around it this step (``halted_on``: the lane
    the ego last stood still on near its end, which settles the stop at a stop sign)."""
    x, y = traci.vehicle.getPosition(EGO)
    edge = traci.vehicle.getRoadID(EGO)
    index = traci.vehicle.getRouteIndex(EGO)
    ahead = plan["edges"][index + 1: index + 1 + ROUTE_AHEAD] if index >= 0 else []
    upcoming = traci.vehicle.getNextTLS(EGO)
    signal = None
    if upcoming:
        tls, link, distance, state = upcoming[0]
        signal = {"id": tls, "link": link, "distance": round(distance, 3), "state": state}
    next_limit = None
    if ahead:
        next_limit = {"distance": round(traci.lane.getLength(traci.vehicle.getLaneID(EGO))
                                        - traci.vehicle.getLanePosition(EGO), 3),
                      "limit": traci.lane.getMaxSpeed(f"{ahead[0]}_0")}
    leader = traci.vehicle.getLeader(EGO, RADIUS_M)
    around = traci.vehicle.getContextSubscriptionResults(EGO) or {}
    vehicles = []
    for vid, values in sorted(around.items()):
        if vid == EGO:
            continue
        px, py = values[traci.constants.VAR_POSITION]
        vehicles.append({"id": vid, "x": px, "y": py,
                         "speed": values[traci.constants.VAR_SPEED],
                         "distance": math.hypot(px - x, py - y)})
    persons = []
    for pid in traci.person.getIDList():
        px, py = traci.person.getPosition(pid)
        if math.hypot(px - x, py - y) <= RADIUS_M:
            persons.append({"id": pid, "x": px, "y": py, "distance": math.hypot(px - x, py - y)})
    return {"time": traci.simulation.getTime(), "step_length": traci.simulation.getDeltaT(),
            "x": x, "y": y,
            "angle": traci.vehicle.getAngle(EGO), "speed": traci.vehicle.getSpeed(EGO),
            "acceleration": traci.vehicle.getAcceleration(EGO), "edge": edge,
            "lane": traci.vehicle.getLaneID(EGO), "lane_index": traci.vehicle.getLaneIndex(EGO),
            "lane_position": traci.vehicle.getLanePosition(EGO),
            "speed_limit": traci.vehicle.getAllowedSpeed(EGO), "next_speed_limit": next_limit,
            "route_ahead": ahead, "route_driven_m": traci.vehicle.getDistance(EGO),
            "route_length_m": plan["length_m"], "next_signal": signal,
            "next_stop": _next_stop(traci, halted_on),
            "leader": None if not leader or not leader[0] else
            {"id": leader[0], "gap": leader[1]}, "vehicles": vehicles, "persons": persons}


def _apply(traci, action: dict, speed: float, dt: float) -> None:
    if "speed" in action:
        target = float(action["speed"])
    else:
        target = speed + float(action.get("acceleration", 0.0)) * dt
    traci.vehicle.setSpeed(EGO, max(0.0, target))
    change = int(action.get("lane_change", 0))
    if change:
        traci.vehicle.changeLaneRelative(EGO, change, dt)


def _next_stop(traci, halted_on: str | None) -> dict | None:
    """The next stop sign along the route within ROUTE_AHEAD links: its distance, whether it
    is an all-way stop, and whether the ego has already stopped for it."""
    lane = traci.vehicle.getLaneID(EGO)
    distance = traci.lane.getLength(lane) - traci.vehicle.getLanePosition(EGO)
    for k, link in enumerate(traci.vehicle.getNextLinks(EGO)[:ROUTE_AHEAD]):
        if link[5] in STOP_STATES and not (k == 0 and lane.startswith(":")):  # a sign's link
            # leaves a road lane; inside a junction an internal link may read 's' too
            return {"distance": round(distance, 3), "all_way": link[5] == "w",
                    "stopped": k == 0 and halted_on == lane}
        distance += link[7] + traci.lane.getLength(link[0])
    return None


def _passed_stop_sign(traci, before: str, now: str, halted: bool) -> dict | None:
    """The stop sign the ego passed leaving lane ``before`` for lane ``now`` (the junction's
    internal lane, or the next lane where it crossed the junction within a step) without
    having stood still near the end of ``before``: SUMO's link states ``s`` (stop) and ``w``
    (all-way stop)."""
    links = traci.lane.getLinks(before)
    used = [link for link in links if now in (link[4], link[0])]
    if halted or not used or used[0][5] not in STOP_STATES:
        return None
    return {"lane": before, "link_state": used[0][5],
            "junction": traci.lane.getEdgeID(now) if now.startswith(":") else None}


def _crossed_red(traci, before: dict | None) -> dict | None:
    """The signal link the ego was heading for before this step, if it has now passed its
    stop line and the light showed red for the link in this step. SUMO switches its lights at
    the start of a step, before vehicles move, so the state read after the step is the one
    the ego crossed under."""
    if before is None:
        return None
    upcoming = traci.vehicle.getNextTLS(EGO)
    if any(tls == before["id"] and distance <= before["distance"] + 0.01
           for tls, _, distance, _ in upcoming):
        return None
    state = traci.trafficlight.getRedYellowGreenState(before["id"])[before["link"]]
    if state not in RED:
        return None
    return {"signal": before["id"], "link": before["link"], "state": state,
            "ego_saw": before["state"], "distance_before_m": before["distance"]}

