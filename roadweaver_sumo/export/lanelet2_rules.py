"""The right of way of a lanelet2 map: regulatory elements from the rules SUMO decided
(``hdmap.right_of_way``), so that an Autoware-style planner yields where SUMO's drivers do.

* ``traffic_light``: one per approach to a light, a light way just past a stop line across
  the approach; the approach's lanelets refer to it.
* ``traffic_sign`` (lanelet2's generic sign element): a stop (``de206``) or yield (``de205``)
  sign beside each approach told so, with the approach's stop line; its lanelets refer to it.
* ``all_way_stop``: one per all-way-stop junction; every approach lanelet yields, each with
  its own stop line (lanelet2 pairs ``yield`` lanelets and ``ref_line``s by position), and the
  stop signs of the approaches.
* ``right_of_way``: one per connector (a lanelet inside a junction) that must let other links
  go first, with those links as ``right_of_way`` lanelets: the whole of SUMO's
  ``<request response=...>``, including left turns that yield to oncoming traffic and
  right-before-left junctions, which have no sign.

Sign codes are the StVO ones the OpenDRIVE file uses (``export.opendrive.SIGNAL_TYPES``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..hdmap.model import HDMap
from ..hdmap.right_of_way import approach_control, approaches

LIGHT_OFFSET_M = 1.0  # the traffic light way sits this far past the stop line
SIGN_OFFSET_M = 1.0  # a sign stands this far right of the road edge at the stop line
SIGN_WIDTH_M = 0.6
SIGN_SUBTYPES = {"stop": "de206", "all_way_stop": "de206", "yield": "de205"}
STOP_LINE = (("type", "stop_line"),)
LIGHT = (("type", "traffic_light"), ("subtype", "red_yellow_green"))


@dataclass
class RegulatoryElement:
    """One regulatory element relation: its subtype, its members (OSM member type, id, role)
    and the HD map lanes whose lanelets refer to it."""

    id: int
    subtype: str
    members: list[tuple[str, int, str]]
    lanes: list[str]


def rule_elements(hd: HDMap, lane_end, ids, lanelet_ids: dict[str, int]):
    """The regulatory elements of ``hd`` and the ways they need (way id -> (node ids, tags)).

    ``lane_end(lane, side)`` is the node id at the end of a lane's left or right boundary,
    ``ids`` the file's id counter (``export.lanelet2._Ids``), ``lanelet_ids`` each lane's
    lanelet id."""
    elements, ways = [], {}

    def way(nodes, tags) -> int:
        wid = ids.new()
        ways[wid] = (nodes, tags)
        return wid

    def stop_line(lanes) -> list[int]:
        return [lane_end(lanes[0], "right"), *(lane_end(lane, "left") for lane in lanes)]

    def offset_points(line, forward: float, sideways: list[float]) -> list[int]:
        """New nodes ``forward`` metres past the stop line ``line`` (right to left), at
        ``sideways`` metres left of its right end (negative: right of the road)."""
        right, left = ids.xy(line[0]), ids.xy(line[-1])
        across = (left - right) / np.hypot(*(left - right))
        ahead = np.array([across[1], -across[0]])
        return [ids.node(right + forward * ahead + d * across) for d in sideways]

    all_way = {}  # junction -> (approach lanes, their stop lines, the signs)
    for (node, _), lanes in approaches(hd).items():
        control = approach_control(hd, lanes)
        if control is None:
            continue
        line = stop_line(lanes)
        if control == "traffic_light":
            width = float(np.hypot(*(ids.xy(line[-1]) - ids.xy(line[0]))))
            light = way(offset_points(line, LIGHT_OFFSET_M, [0.0, width]), LIGHT)
            members = [("way", light, "refers"), ("way", way(line, STOP_LINE), "ref_line")]
            elements.append(RegulatoryElement(ids.new(), "traffic_light", members, lanes))
            continue
        sign = way(offset_points(line, 0.0, [-SIGN_OFFSET_M - SIGN_WIDTH_M, -SIGN_OFFSET_M]),
                   (("type", "traffic_sign"), ("subtype", SIGN_SUBTYPES[control])))
        if control == "all_way_stop":
            entry = all_way.setdefault(node, ([], [], []))
            entry[0].extend(lanes)
            entry[1].extend(way(stop_line([lane]), STOP_LINE) for lane in lanes)
            entry[2].append(sign)
            continue
        members = [("way", sign, "refers"), ("way", way(line, STOP_LINE), "ref_line")]
        elements.append(RegulatoryElement(ids.new(), "traffic_sign", members, lanes))
    for node in sorted(all_way):
        lanes, lines, signs = all_way[node]
        members = [*(("relation", lanelet_ids[lane], "yield") for lane in lanes),
                   *(("way", line, "ref_line") for line in lines),
                   *(("way", sign, "refers") for sign in signs)]
        elements.append(RegulatoryElement(ids.new(), "all_way_stop", members, lanes))
    for connector in hd.connectors():
        if connector.yields_to:
            members = [("relation", lanelet_ids[connector.id], "yield"),
                       *(("relation", lanelet_ids[other], "right_of_way")
                         for other in connector.yields_to)]
            elements.append(RegulatoryElement(ids.new(), "right_of_way", members,
                                              [connector.id]))
    return elements, ways
