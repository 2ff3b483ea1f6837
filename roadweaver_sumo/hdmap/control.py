"""Junction control as towns choose it (issue 36): lights, priority, stop signs and
right-before-left from the classes of the roads that meet and a regional rule set.

A traffic-rule regression suite needs the rules a driving stack meets in the towns it will
drive in, not one kind of junction. The rule sets follow what national traffic codes make
common, judged by the classes of the roads meeting and the number of arms:

* ``de`` (Germany, StVO): residential streets meet under right-before-left (the rule of
  Tempo-30 zones, no signs); a local street joins a collector with a yield sign
  (``priority``) and an arterial with a stop sign (``priority_stop``: the arterial's speed
  leaves no time to judge gaps while rolling), where there is no light.
* ``us`` (MUTCD practice): local four-way crossings and collector crossings are all-way stops;
  every other minor approach stops (``priority_stop``).
* ``priority``: every junction without a light is a priority junction (yield), as every map
  of earlier versions was.

Traffic lights are the same in every set: where two arterials cross or meet, or an arterial
crosses a collector (``signalised``), on maps dense enough for lights. Dead ends are
``dead_end``; a road that just goes on through a two-arm node is ``priority``, or ``zipper``
where it loses a lane there (an arterial going on as a collector: its two lanes take turns
into one, as SUMO's zipper merge and German law, StVO 7(4), have it). The names
are SUMO's node types; netconvert turns them into each link's right of way, which
``right_of_way`` carries to OpenDRIVE and lanelet2.

A user can also ask for a mix (``--junction-mix``, as netgenerate's
``--default-junction-type`` asks for one kind): shares of the junctions of three or more arms.
Each asked kind gets its share, rounded, where a town would put it first: lights, stop signs
and yield signs at the junctions of the most major roads still free, right-before-left and
all-way stops at those of the most minor; the other junctions keep their rule set's choice, or
the rule set's choice without lights where that kind is already full, or the first kind not
asked for.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

import networkx as nx

from ..spec import DEFAULT_RULES, MIX_CONTROLS
from .lanes import LANE_CONFIGS

CONTROLS = ("traffic_light", "priority", "priority_stop", "right_before_left", "allway_stop",
            "zipper", "dead_end")


def junction_control(classes: list[str], rules: str = DEFAULT_RULES,
                     traffic_lights: bool = True, lanes: list[int] | None = None) -> str:
    """The control of a junction whose arms have road ``classes`` (and ``lanes`` per
    direction, by default their classes'), under ``rules``."""
    degree = len(classes)
    if degree == 1:
        return "dead_end"
    if traffic_lights and signalised(classes):
        return "traffic_light"
    if degree == 2:  # a road that just goes on (its class may change)
        counts = set(lanes or (LANE_CONFIGS[c].lanes for c in classes))
        return "zipper" if len(counts) > 1 else "priority"
    locals_only = set(classes) == {"local"}
    minor_roads = set(classes) <= {"local", "collector"}
    if rules == "de":
        if locals_only:
            return "right_before_left"
        if "local" in classes and "arterial" in classes:
            return "priority_stop"
        return "priority"
    if rules == "us":
        if degree >= 4 and minor_roads:
            return "allway_stop"
        return "priority_stop"
    return "priority"


def signalised(classes: list[str]) -> bool:
    """Traffic lights where two arterials cross or meet (three arterial arms, or two in a
    four-way or larger junction) or an arterial meets a collector at a four-way (or larger)
    junction. A side street ending on an arterial (a T with two arterial arms) is not: in real
    towns it is a priority junction, and signalling every such T puts a light at nearly every
    side street of an arterial and more than doubles the mean waiting."""
    degree = len(classes)
    arterials, collectors = classes.count("arterial"), classes.count("collector")
    return (arterials >= 3 or (arterials >= 2 and degree >= 4)
            or (arterials >= 1 and collectors >= 1 and degree >= 4))


@dataclass(frozen=True)
class ControlPlan:
    """Which control each junction gets: the rule set's choice, or the kind a junction mix
    assigned to that node (``assigned``; ``asked``: the kinds the mix named)."""

    rules: str = DEFAULT_RULES
    traffic_lights: bool = True
    assigned: Mapping[int, str] = field(default_factory=dict)
    asked: frozenset[str] = frozenset()

    def control(self, node: int, classes: list[str], lanes: list[int] | None = None) -> str:
        """The control of junction ``node`` whose arms have road ``classes`` (and ``lanes``)."""
        return self.assigned.get(node) or junction_control(classes, self.rules,
                                                           self.traffic_lights, lanes)

    def counts_for_mix(self, node: int) -> bool:
        """Whether ``node`` holds one of the kinds the mix asked for (a roundabout there
        would take it from its share)."""
        return self.assigned.get(node) in self.asked


#: a mix's kinds in the order they are placed: the first three from the most major junctions
FROM_MAJOR = ("traffic_light", "priority_stop", "priority")
FROM_MINOR = ("right_before_left", "allway_stop")
CLASS_RANK = {"arterial": 2, "collector": 1, "local": 0}


def plan_controls(G: nx.Graph, rules: str = DEFAULT_RULES, traffic_lights: bool = True,
                  mix: Mapping[str, float] | None = None) -> ControlPlan:
    """The controls of road graph ``G``'s junctions: the rule set's, or ``mix`` (control ->
    share of the junctions of three or more arms) placed as the module says."""
    if not mix:
        return ControlPlan(rules, traffic_lights)
    classes = {n: [G.edges[e]["road_class"] for e in sorted(G.edges(n))]
               for n in sorted(G.nodes) if G.degree(n) >= 3}
    free = sorted(classes, key=lambda n: (-_majorness(classes[n]), n))  # most major first
    assigned: dict[int, str] = {}
    left = len(classes)
    for kind in (k for k in (*FROM_MAJOR, *FROM_MINOR) if k in mix):
        count = min(round(mix[kind] * len(classes)), left)
        picked = free[:count] if kind in FROM_MAJOR else free[len(free) - count:]
        assigned.update(dict.fromkeys(picked, kind))
        free = [n for n in free if n not in assigned]
        left -= count
    unasked = [k for k in MIX_CONTROLS if k not in mix]
    for node in free:
        choice = junction_control(classes[node], rules, traffic_lights)
        if choice in mix:
            choice = junction_control(classes[node], rules, traffic_lights=False)
        if choice in mix and unasked:
            choice = unasked[0]
        assigned[node] = choice
    return ControlPlan(rules, traffic_lights, assigned, frozenset(mix))


def _majorness(classes: list[str]) -> int:
    """How major a junction is: its two highest road classes, then its number of arms."""
    top = sorted((CLASS_RANK[c] for c in classes), reverse=True)
    return 100 * top[0] + 10 * top[1] + len(classes)
