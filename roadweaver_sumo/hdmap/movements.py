"""Legal movements through a junction and which lanes serve them (paper Algorithm 1,
ConstructJunctionConnections: the lane-to-lane plan before any geometry is built).

Rules, right-hand traffic, lane index 0 = rightmost:

* every pair (incoming direction, outgoing direction of another road) is a movement; U-turns
  only at dead ends, where the road's own reverse is the only way on; no left turn sharper
  than 135°, nor one of less than 60° at a fork, where the arrival has another way on;
* the movement closest to straight ahead is *straight* if it turns less than 50 degrees, or if
  every movement turns the same way (the road bends); the others are left or right turns;
* straight spreads the incoming lanes over all outgoing lanes; right turns leave from the
  rightmost lane into the rightmost lane, left turns from the leftmost into the leftmost (with
  no straight movement, the incoming lanes are split between the right and the left turns);
  where the road ahead has fewer lanes, only as many go straight on, beside the turn lane,
  so that no two lanes merge inside the junction;
* a lane pair found to fold however wide the junction (``build.build_hdmap``) is banned,
  unless it is the only way out of its arrival or into its departure;
* gaps are closed: an incoming lane without a movement or an outgoing lane nobody enters
  copies the movement of its nearest served neighbour lane.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cache

import numpy as np

from .geometry import signed_angles
from .lanes import LaneEnds
from .model import DIRECTIONS, HDMap

STRAIGHT_MAX = np.radians(50.0)
#: A left turn sharper than this (into a road leaving less than 45° from the arriving one) runs
#: beside the oncoming lanes instead of across them, and SUMO puts the left-turner's waiting
#: point within a car's width of them: at an acute priority junction of a 20 km learned map a
#: waiting car 0.7 m from the oncoming lane's centre was hit. Such a turn is left out where
#: the arrival has another way on (as at real acute junctions, which ban it).
SHARP_LEFT_MAX = np.radians(135.0)
#: At a fork, where the way ahead bends right by ``FORK_BEND`` or more and the left branch
#: leaves less than ``FORK_LEFT_MAX`` to the left, the left-turner's path runs beside the
#: oncoming traffic's until it crosses it at a shallow angle, and SUMO stops the left-turner
#: where oncoming cars clip it (learned organic 2 km d60 s1: a waiting car hit at 7.8 m/s).
#: That left is left out where the arrival has another way on and its departure another way in.
FORK_BEND, FORK_LEFT_MAX = np.radians(15.0), np.radians(60.0)

Plan = list[tuple[str, str, str]]  # (incoming lane id, outgoing lane id, movement)


@dataclass
class Approach:
    """One driving direction touching a junction: its road, lanes (rightmost first) and
    its unit driving direction at the junction."""

    road: int
    lanes: list[str]
    tangent: np.ndarray


def approaches(hd: HDMap, node: int, ends: LaneEnds) -> tuple[list[Approach], list[Approach]]:
    """Driving directions arriving at and leaving ``node``, in road and direction order
    (``ends``: the road lanes' ends)."""
    arrivals, departures = [], []
    for rid in hd.junctions[node].roads:
        road = hd.roads[rid]
        for direction in DIRECTIONS:
            lanes = road.lanes(direction)
            if not lanes:  # the missing direction of a one-way road
                continue
            row = ends.row[lanes[0]]
            if road.ends_at(direction) == node:
                arrivals.append(Approach(rid, lanes, ends.end_tangent[row]))
            if road.starts_at(direction) == node:
                departures.append(Approach(rid, lanes, ends.start_tangent[row]))
    return arrivals, departures


def classify(arrival: Approach, departures: list[Approach]) -> list[tuple[Approach, str]]:
    """Movement type of every legal departure for one arrival; a shallow left at a fork is
    ``"fork_left"`` (planned as a left, then dropped where it is not the last way on)."""
    others = [d for d in departures if d.road != arrival.road]
    if not others:  # dead end: the turnaround is the only way on
        return [(d, "uturn") for d in departures]
    angles = signed_angles(arrival.tangent, np.array([d.tangent for d in others]))
    k = int(np.argmin(np.abs(angles)))
    turns = angles.tolist()  # a few values: Python is quicker than numpy's calls on them
    one_side = all(t > 0 for t in turns) or all(t < 0 for t in turns)
    has_straight = abs(turns[k]) < STRAIGHT_MAX or one_side
    labels = ["left" if t > 0 else "right" for t in turns]
    if has_straight:
        labels[k] = "straight"
    moves = list(zip(others, labels, strict=True))
    fork = has_straight and turns[k] <= -FORK_BEND
    moves = [(dep, "fork_left" if m == "left" and fork and t < FORK_LEFT_MAX else m)
             for (dep, m), t in zip(moves, turns, strict=True)]
    kept = [m for m, t in zip(moves, turns, strict=True)
            if not (m[1] == "left" and t > SHARP_LEFT_MAX)]
    return kept or moves


def _spread(ins: list[str], outs: list[str]) -> list[tuple[str, str]]:
    """Map lanes onto lanes in order so that every lane on both sides is used at least once."""
    return sorted({(ins[i], outs[j]) for i, j in _spread_pairs(len(ins), len(outs))})


@cache
def _spread_pairs(n_in: int, n_out: int) -> tuple[tuple[int, int], ...]:
    """The index pairs of ``_spread`` for lists of these lengths (a handful of lengths serve
    every junction of a map)."""
    def scale(i: int, n_from: int, n_to: int) -> int:
        return int(i * (n_to - 1) / max(n_from - 1, 1) + 0.5)

    pairs = {(i, scale(i, n_in, n_out)) for i in range(n_in)}
    pairs |= {(scale(j, n_out, n_in), j) for j in range(n_out)}
    return tuple(sorted(pairs))


def lane_plan(arrival: Approach, moves: list[tuple[Approach, str]]) -> Plan:
    """Lane-to-lane connections of one arrival's movements (the lane rules above)."""
    n = len(arrival.lanes)
    n_right, n_left = _turn_lane_counts(n, moves)
    plan: Plan = []
    turns = {"left" if m == "fork_left" else m for _, m in moves}
    for dep, movement in moves:
        if movement == "straight":
            pairs = _spread(_straight_lanes(arrival.lanes, len(dep.lanes), turns), dep.lanes)
        elif movement == "uturn":
            pairs = _spread(arrival.lanes, dep.lanes)
        elif movement == "right":  # the innermost turn lanes, one into each outgoing lane
            k = min(n_right, len(dep.lanes))
            pairs = _spread(arrival.lanes[:k], dep.lanes[:k])
        else:  # left, or a fork's shallow left (``classify``)
            k = min(n_left, len(dep.lanes))
            pairs = _spread(arrival.lanes[n - k :], dep.lanes[len(dep.lanes) - k :])
        plan.extend((a, b, movement) for a, b in pairs)
    return plan


def _turn_lane_counts(n: int, moves: list[tuple[Approach, str]]) -> tuple[int, int]:
    """How many of an arrival's ``n`` lanes, rightmost and leftmost, turn right and left.

    One each beside a straight movement; without one the lanes are split between the turns,
    and a turn whose widest departure has fewer lanes hands the rest to the other turn where
    that has room: two turn lanes into one outgoing lane merge inside the junction, where two
    cars turning side by side touch (learned mixed 2 km d30 s7: three arterial lanes at a
    light, no way straight on, two of them turning left into a one-lane street)."""
    if n == 1 or any(m == "straight" for _, m in moves):
        return 1, 1
    n_right, n_left = n // 2, n - n // 2
    room_right = max((len(d.lanes) for d, m in moves if m == "right"), default=0)
    room_left = max((len(d.lanes) for d, m in moves if m in ("left", "fork_left")), default=0)
    if n_right > room_right and n_left < room_left:
        shift = min(n_right - room_right, room_left - n_left)
        return n_right - shift, n_left + shift
    if n_left > room_left and n_right < room_right:
        shift = min(n_left - room_left, room_right - n_right)
        return n_right + shift, n_left - shift
    return n_right, n_left


def _straight_lanes(lanes: list[str], ahead: int, movements: set[str]) -> list[str]:
    """The incoming lanes that go straight on. Where the road ahead has fewer lanes, only as
    many as it has, beside the turn lane: lanes that merge inside a junction run on
    converging internal lanes, and two cars side by side on them touch before the merge
    point (SUMO counts a junction collision; 5 at priority T's of a 10 km map). With room
    for both (a turn bay's approach onto a narrower road), between the right-turn and the
    left-turn lane."""
    if ahead >= len(lanes):
        return lanes
    if "right" in movements and "left" not in movements:
        return lanes[len(lanes) - ahead:]  # the rightmost lane is the right-turn lane
    if {"right", "left"} <= movements and len(lanes) - ahead >= 2:
        return lanes[1 : 1 + ahead]
    return lanes[:ahead]  # the leftmost lane turns left (or, with no turn, lanes must merge)


def _close_gaps(plan: Plan, groups: list[list[str]], side: int) -> Plan:
    """For every lane of ``groups`` that no plan entry uses on ``side`` (0 = incoming,
    1 = outgoing), copy the entry of its nearest used neighbour lane in the same group."""
    first: dict[str, tuple[str, str, str]] = {}
    for entry in plan:
        first.setdefault(entry[side], entry)
    added: Plan = []
    for lanes in groups:
        used = [i for i, lane in enumerate(lanes) if lane in first]
        if not used:
            continue
        for i, lane in enumerate(lanes):
            if lane in first:
                continue
            src = first[lanes[min(used, key=lambda j: (abs(j - i), j))]]
            added.append((lane, src[1], src[2]) if side == 0 else (src[0], lane, src[2]))
    return plan + added


def _drop_banned(plan: Plan, banned: set[tuple[str, str]], arrivals: list[Approach],
                 departures: list[Approach]) -> Plan:
    """``plan`` less its ``banned`` lane pairs, each kept where it is the last entry of its
    arrival's lanes or of its departure's (gap closing then has no lane to copy from)."""
    group = {lane: tuple(a.lanes) for a in arrivals + departures for lane in a.lanes}
    for entry in [e for e in plan if (e[0], e[1]) in banned]:
        rest = [e for e in plan if e != entry]
        if any(e[0] in group[entry[0]] for e in rest) and \
                any(e[1] in group[entry[1]] for e in rest):
            plan = rest
    return plan


def junction_plan(hd: HDMap, node: int, ends: LaneEnds,
                  banned: set[tuple[str, str]] = frozenset()) -> Plan:
    """The full, gap-free lane-to-lane plan of a junction, sorted for deterministic ids
    (``ends``: the road lanes' ends; ``banned``: (incoming, outgoing) lane pairs to leave
    out where the lanes have another way on)."""
    arrivals, departures = approaches(hd, node, ends)
    plan: Plan = []
    for arrival in arrivals:
        plan.extend(lane_plan(arrival, classify(arrival, departures)))
    forks = {(a, b) for a, b, movement in plan if movement == "fork_left"}
    plan = [(a, b, "left" if m == "fork_left" else m) for a, b, m in plan]
    plan = _drop_banned(plan, set(banned) | forks, arrivals, departures)
    plan = _close_gaps(plan, [a.lanes for a in arrivals], side=0)
    plan = _close_gaps(plan, [d.lanes for d in departures], side=1)
    return sorted(set(plan))
