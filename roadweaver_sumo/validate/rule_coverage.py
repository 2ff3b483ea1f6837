"""Rule coverage of a SUMO net (issue 36): how many of each traffic-rule situation it holds.

A traffic-rule regression suite is only as good as the situations it covers: a change to a
driver model shows at a stop sign only if the suite has stop signs. ``report.json`` (``net.
rules``) counts them on ``map.net.xml`` as SUMO built it, so that every scenario, ours or
imported with ``evaluate``, is counted the same way.
"""

from __future__ import annotations

from collections import Counter
from pathlib import Path

import sumolib
from lxml import etree

from .netgraph import road_edges, road_junctions

#: SUMO link states of a turn from a road lane into a junction, by the rule that governs it
APPROACH_RULES = {"O": "signalised", "o": "signalised", "G": "signalised", "g": "signalised",
                  "r": "signalised", "y": "signalised", "M": "priority_major",
                  "m": "yield", "s": "stop", "w": "all_way_stop", "=": "right_before_left",
                  "Z": "zipper"}


def rule_coverage(net: sumolib.net.Net) -> dict:
    """Junctions by control (SUMO node type; places where at least three roads meet, and
    zipper merges where a road loses a lane; a roundabout's ring nodes are its own count),
    turns into junctions by the rule that governs them, one-way road edges, turn bays
    (approaches to a light that gain lanes shortly before it), protected left turns,
    roundabouts and their entries (roads into the ring), pedestrian crossings (at lights, or zebras where pedestrians go first), the
    speed limits in km/h and the speed-limit changes where a road goes straight on into one
    of another limit. Protected lefts need the net read with its programs."""
    rings = {node for ring in net.getRoundabouts() for node in ring.getNodes()}
    entries = sum(e.getToNode().getID() in rings and e.getFromNode().getID() not in rings
                  for e in road_edges(net))
    controls = Counter(node.getType() for node in road_junctions(net) if node.getID() not in rings
                       and (len(_neighbours(node)) >= 3 or node.getType() == "zipper"))
    approaches: Counter = Counter()
    changes = 0
    edges = road_edges(net)
    for edge in edges:
        for after, connections in edge.getOutgoing().items():
            if after.isSpecial():
                continue
            for connection in connections:
                approaches[APPROACH_RULES.get(connection.getState(), "other")] += 1
            straight = any(c.getDirection() == "s" for c in connections)
            changes += straight and round(edge.getSpeed() * 3.6) != round(after.getSpeed() * 3.6)
    pairs = {(e.getFromNode().getID(), e.getToNode().getID()) for e in road_edges(net)}
    one_way = sum((b, a) not in pairs for a, b in pairs)
    crossings = Counter("signalised" if e.getFromNode().getType() == "traffic_light" else "zebra"
                        for e in net.getEdges(withInternal=True) if e.getFunction() == "crossing")
    return {"junction_controls": dict(sorted(controls.items())),
            "turns_by_rule": dict(sorted(approaches.items())),
            "one_way_edges": one_way,
            "turn_bays": sum(_opens_a_bay(edge) for edge in edges),
            "roundabouts": len(net.getRoundabouts()),
            "roundabout_entries": entries,
            "protected_lefts": _protected_lefts(net),
            "pedestrian_crossings": dict(sorted(crossings.items())),
            "speed_limits_kmh": sorted({round(e.getSpeed() * 3.6) for e in road_edges(net)}),
            "speed_limit_changes": changes}


#: the rule an approach edge is under when its turns are under several, most binding first
BINDING = ("stop", "all_way_stop", "signalised", "right_before_left", "yield", "zipper",
           "priority_major", "other")


def approach_rules(net_path: Path) -> dict[str, str]:
    """Each road edge that leads into a junction, by the most binding rule of its turns (read
    from ``map.net.xml``'s connections, without loading the whole net)."""
    turns: dict[str, set[str]] = {}
    for _, connection in etree.iterparse(str(net_path), tag="connection"):
        edge = connection.get("from", "")
        if not edge.startswith(":") and connection.get("via"):
            turns.setdefault(edge, set()).add(APPROACH_RULES.get(connection.get("state"),
                                                                 "other"))
        connection.clear()
    return {edge: min(rules, key=BINDING.index) for edge, rules in sorted(turns.items())}


def rule_waits(edgedata_path: Path, approaches: dict[str, str]) -> dict:
    """Per rule, from SUMO's ``--edgedata-output``: the approach edges under it that traffic
    used, the vehicles that drove them, and their waiting time per vehicle (s, standing
    below 0.1 m/s): a rule a driver model keeps differently shows here first (a regression
    suite compares these figures)."""
    edges: Counter = Counter()
    vehicles: Counter = Counter()
    waiting: Counter = Counter()
    for edge in etree.parse(str(edgedata_path)).iter("edge"):
        rule = approaches.get(edge.get("id", ""))
        used = float(edge.get("departed", 0)) + float(edge.get("entered", 0))
        if rule and used:
            edges[rule] += 1
            vehicles[rule] += int(used)
            waiting[rule] += float(edge.get("waitingTime", 0))
    return {rule: {"approaches": edges[rule], "vehicles": vehicles[rule],
                   "waiting_s": round(waiting[rule] / vehicles[rule], 2)}
            for rule in sorted(vehicles)}


def _opens_a_bay(edge) -> bool:
    """Whether ``edge`` leads to a traffic light with more lanes than the road it continues
    across a two-arm junction: its extra lanes are turn bays."""
    start = edge.getFromNode()
    if edge.getToNode().getType() != "traffic_light" or len(_neighbours(start)) != 2:
        return False
    before = [e for e in start.getIncoming() if not e.isSpecial()
              and e.getFromNode() != edge.getToNode()]
    return any(e.getLaneNumber() < edge.getLaneNumber() for e in before)


def _protected_lefts(net: sumolib.net.Net) -> int:
    """Left turns at traffic lights that have a phase of their own (green without yielding to
    oncoming traffic, ``G``): netconvert gives one where the turn has a lane to itself, as in a
    turn bay. Needs the net read with its programs."""
    count = 0
    for tls in net.getTrafficLights():
        states = [phase.state for program in tls.getPrograms().values()
                  for phase in program.getPhases()]
        for into, out, index in tls.getConnections():
            left = any(c.getToLane() == out and c.getDirection() in "lL"
                       for c in into.getOutgoing())
            count += left and any(state[index] == "G" for state in states)
    return count


def _neighbours(node) -> set[str]:
    """The other road junctions this one has a road to or from."""
    return ({e.getFromNode().getID() for e in node.getIncoming() if not e.isSpecial()} |
            {e.getToNode().getID() for e in node.getOutgoing() if not e.isSpecial()}) - {
                node.getID()}


def rule_lines(rules: dict) -> list[str]:
    """The coverage as two summary lines."""
    def counts(figures: dict) -> str:
        return ", ".join(f"{kind} x{n}" for kind, n in figures.items()) or "none"

    turns = (f"turns by rule: {counts(rules['turns_by_rule'])}; one-way edges "
             f"{rules['one_way_edges']}; turn bays {rules.get('turn_bays', 0)}, protected lefts "
             f"{rules.get('protected_lefts', 0)}; roundabouts {rules.get('roundabouts', 0)} "
             f"({rules.get('roundabout_entries', 0)} entries); "
             f"speed limits {rules['speed_limits_kmh']} km/h, "
             f"{rules['speed_limit_changes']} changes; pedestrian crossings "
             f"{counts(rules.get('pedestrian_crossings', {}))}")
    rings = rules.get("roundabouts", 0)
    return [f"junction controls: {counts(rules['junction_controls'])}"
            + (f", roundabout x{rings}" if rings else ""), turns]
