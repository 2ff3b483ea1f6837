"""Right of way as SUMO decided it, carried back onto the HD map's connectors (issue 36,
"one truth, three formats").

netconvert works out who yields to whom at every junction from the node type we chose
(``hdmap.control``), the arms' priorities and their angles: a left turn from the main road
yields to oncoming traffic, every link of a stop approach stops, a right-before-left link yields
to the links from its right. Re-deriving those rules for OpenDRIVE and lanelet2 would give a
second answer that disagrees with the simulation wherever the two rule books differ in a corner
case; reading SUMO's answer gives all three formats the one the simulation drives by.

From ``map.net.xml`` each connector gets its link state (SUMO's letter: ``M`` major, ``m``
minor, ``s`` stop, ``w`` all-way stop, ``=`` right before left, ...), its traffic light if any
and the connectors it must yield to (the junction's ``<request response=...>`` bits; link
indices as sumolib's ``Node.getLinkIndex`` counts them: the junction's incoming lanes in order,
each lane's connections in file order).
"""

from __future__ import annotations

from collections import defaultdict
from pathlib import Path

from lxml import etree

from .model import HDMap

#: what an approach (the lanes of one road direction arriving at a junction) is told to do,
#: judged from the link states of its connectors; ``None``: nothing (a main road, or right
#: before left, which in the towns whose rules we follow has no sign)
APPROACH_CONTROLS = ("traffic_light", "all_way_stop", "stop", "yield")


def read_links(net_path: Path) -> dict[tuple[str, str], dict]:
    """Every link of ``net_path`` between two normal lanes, keyed by (from lane, to lane):
    ``state``, ``tl`` (the traffic light's id or None), ``junction`` and ``prohibitors`` (the
    keys of the vehicle links it must yield to; pedestrians on crossings are left out)."""
    connections = defaultdict(list)  # from lane -> its connections' attributes, file order
    junctions = []  # (junction id, incoming lanes, response strings)
    functions = {}  # edge id -> function (internal, walkingarea, crossing) of special edges
    for _, element in etree.iterparse(str(net_path), tag=("edge", "junction", "connection")):
        a = element.attrib
        if element.tag == "edge" and "function" in a:
            functions[a["id"]] = a["function"]
        elif element.tag == "junction" and a.get("type") != "internal":
            responses = {int(r.get("index")): r.get("response") for r in element}
            junctions.append((a["id"], a.get("incLanes", "").split(),
                              [responses[k] for k in sorted(responses)]))
        elif element.tag == "connection":
            key = (f"{a['from']}_{a['fromLane']}", f"{a['to']}_{a['toLane']}")
            connections[key[0]].append({"key": key, "state": a.get("state"), "tl": a.get("tl"),
                                        "to_function": functions.get(a["to"]),
                                        "from_function": functions.get(a["from"])})
        element.clear()
    links = {}
    for junction, incoming, responses in junctions:
        indexed = [c for lane in incoming for c in connections[lane] if _counted(c)]
        for index, link in enumerate(indexed):
            if link["from_function"] or link["to_function"]:
                continue  # a pedestrian link: not a vehicle's right of way
            bits = responses[index] if index < len(responses) else ""
            prohibitors = [indexed[k]["key"] for k in range(len(bits))
                           if bits[-(k + 1)] == "1" and k < len(indexed)
                           and not (indexed[k]["from_function"] or indexed[k]["to_function"])]
            links[link["key"]] = {"state": link["state"], "tl": link["tl"],
                                  "junction": junction, "prohibitors": prohibitors}
    return links


def _counted(connection: dict) -> bool:
    """Whether sumolib's link index counts this connection (it skips links into walking
    areas and links out of them other than into crossings)."""
    if connection["to_function"] == "walkingarea":
        return False
    return not (connection["from_function"] == "walkingarea"
                and connection["to_function"] != "crossing")


def attach_right_of_way(hd: HDMap, net_path: Path) -> None:
    """Give every connector of ``hd`` its SUMO link state, traffic light and the connectors
    it yields to, read from ``net_path`` (the net netconvert built from ``hd``)."""
    by_link = {(c.predecessors[0], c.successors[0]): c for c in hd.connectors()}
    for key, link in read_links(net_path).items():
        connector = by_link.get(key)
        if connector is None:
            raise ValueError(f"{net_path} has a link {key[0]} -> {key[1]} the HD map lacks")
        connector.link_state = link["state"]
        connector.traffic_light = link["tl"]
        connector.yields_to = sorted(by_link[k].id for k in link["prohibitors"])


def approach_control(hd: HDMap, lanes: list[str]) -> str | None:
    """What the approach made of road lanes ``lanes`` is told to do (``APPROACH_CONTROLS``):
    a traffic light if any of its links has one, else an all-way stop or a stop sign if any
    link must stop, else a yield sign if every link yields (SUMO's ``m``), else None."""
    links = [hd.lanes[c] for lane in lanes for c in hd.lanes[lane].successors]
    states = {c.link_state for c in links}
    if any(c.traffic_light for c in links):
        return "traffic_light"
    if "w" in states:
        return "all_way_stop"
    if "s" in states:
        return "stop"
    if states == {"m"}:
        return "yield"
    return None


def approaches(hd: HDMap) -> dict[tuple[int, str], list[str]]:
    """Each approach, keyed by (junction node, SUMO edge id): its road lanes, rightmost
    first, for every road direction that arrives at a junction with connectors."""
    found = {}
    for rid in sorted(hd.roads):
        road = hd.roads[rid]
        for direction in ("f", "b"):
            lanes = road.lanes(direction)
            node = road.ends_at(direction)
            if lanes and hd.junctions[node].connectors:
                found[node, hd.lanes[lanes[0]].edge] = list(lanes)
    return found

