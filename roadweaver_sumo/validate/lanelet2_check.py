"""Read a lanelet2-format ``lanelet2_map.osm`` back with the real lanelet2 library and measure routing.

lanelet2 (PyPI ``lanelet2``) can take the interpreter down on malformed maps (NOTES.md), so
:func:`check_lanelet2` runs the measurement in a child process and turns a crash into a result.
The child loads the map with ``LocalCartesianProjector`` at the map's geo origin (the writer's
transverse Mercator agrees with it to well under a millimetre; UTM would not), builds a
``RoutingGraph`` with German traffic rules for vehicles and plans between random lanelet pairs.

Usage as a script: ``python -m roadweaver_sumo.validate.lanelet2_check lanelet2_map.osm LAT LON``.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time
from collections import Counter, defaultdict
from pathlib import Path

import numpy as np
from lxml import etree

from .. import children
from ..export.lanelet2 import LANE_TAG
from ..projection import latlon_to_local

ROUTE_SUCCESS_TARGET = 0.99
PROJECTION_TOLERANCE_M = 0.001


def check_lanelet2(osm: Path, origin: tuple[float, float], *, pairs: int = 1000, seed: int = 0,
                   timeout: float = 600.0) -> dict:
    """Measure ``osm`` with lanelet2 in a child process (see :func:`measure_lanelet2`).

    A crash, a time-out or a missing lanelet2 gives ``{"ok": False, "error": ...}`` instead of
    taking the caller down."""
    cmd = [sys.executable, "-m", __name__, str(osm), repr(float(origin[0])), repr(float(origin[1])),
           "--pairs", str(pairs), "--seed", str(seed)]
    try:
        proc = children.run(cmd, timeout=timeout)
    except subprocess.TimeoutExpired:
        return {"ok": False, "error": f"lanelet2 check took longer than {timeout:g} s"}
    if proc.returncode < 0:
        return {"ok": False, "error": f"lanelet2 crashed (signal {-proc.returncode})"}
    if proc.returncode != 0:
        tail = proc.stderr.strip().splitlines()[-1:] or ["no message"]
        return {"ok": False, "error": f"lanelet2 check failed: {tail[0]}"}
    return json.loads(proc.stdout.strip().splitlines()[-1])  # the report is the last line


def lanelet2_failures(result: dict) -> list[str]:
    """Human-readable reasons why a :func:`check_lanelet2` result misses our targets."""
    if not result.get("ok"):
        return [result.get("error", "lanelet2 check failed")]
    failures = []
    if result["load_errors"]:
        failures.append(f"{result['load_errors']} lanelet2 load errors, e.g. "
                        f"{result['load_error_examples'][0]}")
    if result["inverted_bounds"]:
        failures.append(f"lanelet2 reversed {len(result['inverted_bounds'])} lanelets on "
                        f"loading, e.g. {result['inverted_bounds'][0]}")
    if result["topology_mismatches"]:
        failures.append(f"lanelet2 sees other successors or neighbours than the file encodes "
                        f"for {len(result['topology_mismatches'])} lanelets, e.g. "
                        f"{result['topology_mismatches'][0]}")
    if result["routing_graph_errors"]:
        failures.append(f"{result['routing_graph_errors']} routing graph errors")
    if result["route_success"] < ROUTE_SUCCESS_TARGET:
        failures.append(f"only {result['route_success']:.1%} of random lanelet pairs route "
                        f"(target {ROUTE_SUCCESS_TARGET:.0%})")
    if result.get("pedestrian_route_success", 1.0) < ROUTE_SUCCESS_TARGET:
        failures.append(f"only {result['pedestrian_route_success']:.1%} of random sidewalk "
                        f"pairs route for pedestrians (target {ROUTE_SUCCESS_TARGET:.0%})")
    if result["projection_max_error_m"] > PROJECTION_TOLERANCE_M:
        failures.append(f"points move {result['projection_max_error_m']:.4f} m on loading")
    return failures


def measure_lanelet2(osm: Path, origin: tuple[float, float], pairs: int = 1000,
                     seed: int = 0) -> dict:
    """Load ``osm`` with lanelet2 in this process and measure it. May crash on bad maps."""
    import lanelet2
    from lanelet2.projection import LocalCartesianProjector

    start = time.perf_counter()
    lmap, errors = lanelet2.io.loadRobust(str(osm), LocalCartesianProjector(
        lanelet2.io.Origin(*origin)))
    loaded = time.perf_counter()
    rules = lanelet2.traffic_rules.create(lanelet2.traffic_rules.Locations.Germany,
                                          lanelet2.traffic_rules.Participants.Vehicle)
    graph = lanelet2.routing.RoutingGraph(lmap, rules)
    built = time.perf_counter()
    lanelets = sorted((ll for ll in lmap.laneletLayer if ll.attributes["subtype"] == "road"),
                      key=lambda ll: ll.id)
    result = {
        "ok": True,
        "load_errors": len(errors),
        "load_error_examples": [str(e) for e in errors[:5]],
        "load_s": round(loaded - start, 3),
        "routing_graph_s": round(built - loaded, 3),
        "lanelets": len(lanelets),
        "traffic_lights": sum(1 for r in lmap.regulatoryElementLayer
                              if r.attributes["subtype"] == "traffic_light"),
        "regulatory_elements": dict(sorted(Counter(
            r.attributes["subtype"] for r in lmap.regulatoryElementLayer).items())),
        "inverted_bounds": _inverted_bounds(lanelets),
        "topology_mismatches": _topology_mismatches(osm, graph, lanelets),
        "routing_graph_errors": len(graph.checkValidity(False)),
        "lanelets_without_following": sum(1 for ll in lanelets if not graph.following(ll)),
        "lane_change_relations": sum(len(graph.lefts(ll)) + len(graph.rights(ll))
                                     for ll in lanelets),
        "speed_limit_mismatches": _speed_limit_mismatches(lanelets, rules),
        "projection_max_error_m": _projection_error(osm, lmap, origin),
    }
    result.update(_route_pairs(graph, lanelets, pairs, seed))
    result.update(_pedestrian_routes(lanelet2, lmap, pairs, seed))
    return result


def _pedestrian_routes(lanelet2, lmap, pairs: int, seed: int) -> dict:
    """On a map with sidewalks: the share of random pairs of sidewalk lanelets that
    lanelet2's router for pedestrians (German rules) connects, walking each either way."""
    sidewalks = sorted((ll for ll in lmap.laneletLayer if ll.attributes["subtype"] == "walkway"
                        and ll.attributes[LANE_TAG].startswith("r")), key=lambda ll: ll.id)
    if len(sidewalks) < 2:
        return {}
    rules = lanelet2.traffic_rules.create(lanelet2.traffic_rules.Locations.Germany,
                                          lanelet2.traffic_rules.Participants.Pedestrian)
    graph = lanelet2.routing.RoutingGraph(lmap, rules)
    tasks = random_pairs(len(sidewalks), pairs, seed)
    routed = 0
    for i, j in tasks:
        a, b = sidewalks[i], sidewalks[j]
        routed += any(graph.getRoute(x, y) is not None
                      for x in (a, a.invert()) for y in (b, b.invert()))
    return {"sidewalks": len(sidewalks), "crosswalks": sum(
                1 for ll in lmap.laneletLayer if ll.attributes["subtype"] == "crosswalk"),
            "pedestrian_route_success": routed / max(len(tasks), 1)}


def osm_lane_relations(osm: Path) -> dict[str, dict[str, list[str]]]:
    """The lane graph as lanelet2 reads it from ``osm``: B succeeds A when B's bounds start at
    the nodes where A's end; neighbours share a boundary way. Keyed by our lane ids."""
    root = etree.parse(str(osm)).getroot()
    ends = {}
    for way in root.iter("way"):
        nodes = way.findall("nd")
        ends[way.get("id")] = (nodes[0].get("ref"), nodes[-1].get("ref"))
    bounds = {}
    for rel in root.iter("relation"):
        tags = {t.get("k"): t.get("v") for t in rel.iter("tag")}
        if tags.get("type") != "lanelet" or tags.get("subtype") != "road":
            continue  # the vehicles' lane graph (pedestrians': export.lanelet2_walks)
        if LANE_TAG not in tags:
            raise ValueError(f"lanelet {rel.get('id')} of {osm} has no {LANE_TAG} tag: "
                             "not a map written by roadweaver-sumo")
        members = {m.get("role"): m.get("ref") for m in rel.iter("member")}
        bounds[tags[LANE_TAG]] = (members["left"], members["right"])
    starting_at, left_of, right_of = defaultdict(list), {}, {}
    for lane, (left, right) in bounds.items():
        starting_at[(ends[left][0], ends[right][0])].append(lane)
        left_of[right] = lane  # the lane whose right bound is this way lies left of it
        right_of[left] = lane
    relations = {lane: {"successors": sorted(starting_at[(ends[left][1], ends[right][1])]),
                        "predecessors": [], "left": [], "right": []}
                 for lane, (left, right) in bounds.items()}
    for lane, (left, right) in sorted(bounds.items()):
        for succ in relations[lane]["successors"]:
            relations[succ]["predecessors"].append(lane)
        relations[lane]["left"] = [left_of[left]] if left in left_of else []
        relations[lane]["right"] = [right_of[right]] if right in right_of else []
    return relations


def _topology_mismatches(osm: Path, graph, lanelets) -> list[str]:
    """Lanelets whose successors or neighbours in lanelet2's routing graph differ from what the
    file encodes (:func:`osm_lane_relations`): what lanelet2 sees is what we wrote."""
    expected = osm_lane_relations(osm)
    wrong = []
    for ll in lanelets:
        left, right = graph.left(ll), graph.right(ll)
        seen = {"successors": sorted(_name(x) for x in graph.following(ll)),
                "left": [_name(left)] if left else [], "right": [_name(right)] if right else []}
        want = expected.get(_name(ll))
        if want is None or any(seen[key] != want[key] for key in seen):
            wrong.append(_name(ll))
    return wrong


def _inverted_bounds(lanelets) -> list[str]:
    """Lanelets whose bound lanelet2 turned round while loading (its ``geometry::align`` guesses
    from middle points). Our ways all run in driving direction, so any turn is a wrong guess
    that reverses the lanelet and breaks its successor links."""
    return [_name(ll) for ll in lanelets if ll.leftBound.inverted() or ll.rightBound.inverted()]


def _speed_limit_mismatches(lanelets, rules) -> int:
    """Lanelets whose traffic-rule speed limit is not their ``speed_limit`` tag (km/h)."""
    return sum(1 for ll in lanelets if "speed_limit" in ll.attributes and abs(
        rules.speedLimit(ll).speedLimitKmH - float(ll.attributes["speed_limit"])) > 0.01)


def _projection_error(osm: Path, lmap, origin: tuple[float, float]) -> float:
    """Largest distance between where lanelet2 put a point and where our projection puts its
    lat/lon: both should be the writer's local metres."""
    ids, lat, lon = [], [], []
    for _, node in etree.iterparse(str(osm), tag="node"):
        ids.append(int(node.get("id")))
        lat.append(float(node.get("lat")))
        lon.append(float(node.get("lon")))
        node.clear()
    x, y = latlon_to_local(np.array(lat), np.array(lon), origin)
    ours = dict(zip(ids, zip(x, y)))
    return max((float(np.hypot(p.x - ours[p.id][0], p.y - ours[p.id][1]))
                for p in lmap.pointLayer), default=0.0)


def _route_pairs(graph, lanelets: list, pairs: int, seed: int) -> dict:
    """Share of random ordered pairs of distinct lanelets that ``getRoute`` (lane changes
    allowed) and ``shortestPath`` connect, and the mean time per query."""
    tasks = random_pairs(len(lanelets), pairs, seed)
    if not tasks:
        return {"pairs": 0, "route_success": 0.0, "route_ms": 0.0,
                "shortest_path_success": 0.0, "shortest_path_ms": 0.0, "unrouted_examples": []}
    routed = paths = 0
    route_s = path_s = 0.0
    unrouted = []
    for i, j in tasks:
        a, b = lanelets[i], lanelets[j]
        start = time.perf_counter()
        route = graph.getRoute(a, b)
        route_s += time.perf_counter() - start
        routed += route is not None
        start = time.perf_counter()
        paths += graph.shortestPath(a, b) is not None
        path_s += time.perf_counter() - start
        if route is None and len(unrouted) < 5:
            unrouted.append([_name(a), _name(b)])
    return {"pairs": pairs, "route_success": routed / pairs,
            "route_ms": round(1000 * route_s / pairs, 4),
            "shortest_path_success": paths / pairs,
            "shortest_path_ms": round(1000 * path_s / pairs, 4),
            "unrouted_examples": unrouted}


def random_pairs(n: int, count: int, seed: int) -> list[tuple[int, int]]:
    """``count`` ordered pairs of distinct indices below ``n``, uniform, from a seeded rng."""
    if n < 2:
        return []
    rng = np.random.default_rng(seed)
    first = rng.integers(n, size=count)
    second = rng.integers(n - 1, size=count)
    second += second >= first
    return list(zip(first.tolist(), second.tolist()))


def _name(lanelet) -> str:
    attributes = lanelet.attributes
    return attributes[LANE_TAG] if LANE_TAG in attributes else str(lanelet.id)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("osm", type=Path)
    parser.add_argument("lat", type=float)
    parser.add_argument("lon", type=float)
    parser.add_argument("--pairs", type=int, default=1000)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)
    result = measure_lanelet2(args.osm, (args.lat, args.lon), args.pairs, args.seed)
    print(json.dumps(result, sort_keys=True))
    return 0


if __name__ == "__main__":
    sys.exit(main())
