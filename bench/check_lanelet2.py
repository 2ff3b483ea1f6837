"""Read our lanelet2_map.osm back with lanelet2 and Tactics2D and route on it (issue 3, part 2).

Usage:
  python bench/check_lanelet2.py SCENARIO_DIR ...      # folders with lanelet2_map.osm and/or spec.json
  python bench/check_lanelet2.py --densities 10,20,30,40,50,60 --seeds 0-4 --size 2000
Options: --pairs 1000 (random lanelet pairs for lanelet2), --tactics2d-tasks 100 (searches on
Tactics2D's own routing graph: its pure-Python Dijkstra takes up to seconds per task on 2 km
maps), --router-tasks 20 (``Router.plan`` calls through ``plan_routes``, on one routing graph),
--router-rebuild-tasks 3 (plain ``Router.plan`` calls, which rebuild the graph every time),
--tactics2d-python PATH (an interpreter with tactics2d installed; Tactics2D is GPL-3.0 and
pins older numpy/shapely, so it usually lives in its own venv), --json PATH.

Per map: lanelet2 load errors, bounds lanelet2 reversed, routing success and ms per route
(``getRoute`` on random lanelet pairs), on maps with sidewalks the share of sidewalk pairs
lanelet2 routes pedestrians between; whether the file's lanelet2 topology equals the HD map's
lane graph; Tactics2D load time, search success on its own routing graph, ``Router.plan``
success (start and goal lanes matched) and ms per route, with and without the graph rebuild.
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from roadweaver_sumo import generate_map
from roadweaver_sumo.export.map_files import write_map_files
from roadweaver_sumo.integrations.tactics2d import hd_lane_relations
from roadweaver_sumo.validate.lanelet2_check import (
    check_lanelet2,
    lanelet2_failures,
    osm_lane_relations,
    random_pairs,
)


def seeds_arg(text: str) -> list[int]:
    if "-" in text:
        lo, hi = text.split("-")
        return list(range(int(lo), int(hi) + 1))
    return [int(s) for s in text.split(",")]


def cases(args, work: Path):
    """(name, lanelet2_map.osm, HD map) per scenario folder or sweep point; missing maps are written."""
    from roadweaver_sumo.spec import ScenarioSpec

    specs = []
    for folder in args.scenarios:
        specs.append((ScenarioSpec.from_json_file(folder / "spec.json"), folder / "lanelet2_map.osm"))
    for density in [float(d) for d in args.densities.split(",")] if not args.scenarios else []:
        for seed in seeds_arg(args.seeds):
            spec = ScenarioSpec(density=density, vehicles=1, seed=seed, style=args.style,
                                width=args.size, height=args.size)
            specs.append((spec, work / spec.name / "lanelet2_map.osm"))
    for spec, osm in specs:
        start = time.perf_counter()
        hd = generate_map(spec)  # as make-scenario builds it, sidewalks and --like included
        generate_s = time.perf_counter() - start
        write_s = None
        if not osm.exists():
            osm.parent.mkdir(parents=True, exist_ok=True)
            start = time.perf_counter()
            write_map_files(hd, osm.parent)  # after netconvert: with its right of way
            write_s = time.perf_counter() - start
        yield spec, osm, hd, {"generate_s": generate_s, "write_s": write_s}


def measure(spec, osm: Path, hd, timing: dict, args) -> dict:
    file_graph = osm_lane_relations(osm)
    row = {"name": spec.name, "density": spec.density, "seed": spec.seed,
           "lanes": len(hd.lanes), "osm_mb": osm.stat().st_size / 1e6, **timing,
           "topology_matches_hdmap": file_graph == hd_lane_relations(hd)}
    row["lanelet2"] = check_lanelet2(osm, hd.geo_origin, pairs=args.pairs, seed=args.seed)
    row["lanelet2_failures"] = lanelet2_failures(row["lanelet2"])
    row["tactics2d"] = run_tactics2d(osm, hd.geo_origin, args)
    return row


def run_tactics2d(osm: Path, origin, args) -> dict | None:
    """Tactics2D figures, in this interpreter or in ``--tactics2d-python``."""
    worker_args = [str(osm), "--origin", repr(float(origin[0])), repr(float(origin[1])),
                   "--tactics2d-tasks", str(args.tactics2d_tasks),
                   "--router-tasks", str(args.router_tasks),
                   "--router-rebuild-tasks", str(args.router_rebuild_tasks),
                   "--seed", str(args.seed)]
    if args.tactics2d_python:
        proc = subprocess.run([args.tactics2d_python, __file__, "--tactics2d-worker",
                               *worker_args], capture_output=True, text=True, check=False)
        if proc.returncode != 0:
            return {"error": (proc.stderr.strip().splitlines() or ["failed"])[-1]}
        return json.loads(proc.stdout.strip().splitlines()[-1])
    try:
        import tactics2d  # noqa: F401
    except ImportError:
        return None
    return tactics2d_figures(osm, origin, args.tactics2d_tasks, args.router_tasks,
                             args.router_rebuild_tasks, args.seed)


def tactics2d_figures(osm: Path, origin, tasks: int, router_tasks: int, rebuild_tasks: int,
                      seed: int) -> dict:
    """Load with :func:`load_tactics2d_map` (relations from the file's lanelet2 topology, which
    the main process checked against the HD map) and route random lane-to-lane tasks."""
    import logging

    from tactics2d.routing import Router
    from tactics2d.routing.algorithm_adapter import AlgorithmAdapter
    from tactics2d.routing.graph_builder import GraphBuilder

    from roadweaver_sumo.integrations.tactics2d import load_tactics2d_map, plan_routes

    logging.disable(logging.WARNING)  # one warning per oddity would flood the bench output
    start = time.perf_counter()
    map_ = load_tactics2d_map(osm, origin=origin)
    load_s = time.perf_counter() - start
    ids = sorted(map_.lanes)
    pairs = random_pairs(len(ids), max(tasks, router_tasks, rebuild_tasks), seed)
    start = time.perf_counter()
    graph = GraphBuilder().build(map_)
    graph_s = time.perf_counter() - start
    start = time.perf_counter()
    searched = sum(bool(AlgorithmAdapter.dijkstra(graph, graph.lane_id_to_index[ids[i]],
                                                  graph.lane_id_to_index[ids[j]])[0])
                   for i, j in pairs[:tasks])
    search_ms = 1000 * (time.perf_counter() - start) / max(len(pairs[:tasks]), 1)

    def planned(routes, task_pairs) -> int:
        return sum(bool(route.lane_ids) and (route.start_lane_id, route.goal_lane_id)
                   == (ids[i], ids[j]) for route, (i, j) in zip(routes, task_pairs))

    def tasks_for(task_pairs):
        return [(lane_middle(map_.lanes[ids[i]]), lane_middle(map_.lanes[ids[j]]))
                for i, j in task_pairs]

    figures = {"lanes": len(ids), "load_s": load_s, "graph_s": graph_s,
               "lanes_with_successors": sum(1 for lane in map_.lanes.values() if lane.successors),
               "search_tasks": len(pairs[:tasks]),
               "search_success": searched / max(len(pairs[:tasks]), 1), "search_ms": search_ms}
    for key, n, plan in (("router", router_tasks, lambda t: plan_routes(map_, t, Router())),
                         ("router_rebuild", rebuild_tasks,
                          lambda t: [Router().plan(map_, a, b) for a, b in t])):
        task_pairs = pairs[:n]
        start = time.perf_counter()
        routes = plan(tasks_for(task_pairs))
        figures |= {f"{key}_tasks": len(task_pairs),
                    f"{key}_success": planned(routes, task_pairs) / max(len(task_pairs), 1),
                    f"{key}_ms": 1000 * (time.perf_counter() - start) / max(len(task_pairs), 1)}
    return figures


def lane_middle(lane) -> tuple[float, float]:
    point = lane.centerline().interpolate(0.5, normalized=True)
    return point.x, point.y


def format_row(r: dict) -> str:
    l2, t2 = r["lanelet2"], r["tactics2d"]
    text = f"{r['name']:40s} lanes={r['lanes']:5d} topo={'ok' if r['topology_matches_hdmap'] else 'DIFF'}"
    if l2.get("ok"):
        text += (f" | l2 err={l2['load_errors']} rev={len(l2['inverted_bounds'])} "
                 f"topo={len(l2['topology_mismatches'])} "
                 f"route={l2['route_success']:.3f} {l2['route_ms']:.2f}ms "
                 f"proj={1000 * l2['projection_max_error_m']:.3f}mm")
        if "pedestrian_route_success" in l2:
            text += f" walk={l2['pedestrian_route_success']:.3f}"
    else:
        text += f" | l2 {l2.get('error')}"
    if t2 and "error" not in t2:
        text += (f" | t2d load={t2['load_s']:.1f}s search={t2['search_success']:.3f} "
                 f"{t2['search_ms']:.1f}ms router={t2['router_success']:.3f} "
                 f"{t2['router_ms']:.0f}ms (rebuilding the graph: "
                 f"{t2['router_rebuild_ms']:.0f}ms)")
    elif t2:
        text += f" | t2d {t2['error']}"
    return text


def summary(rows: list[dict]) -> str:
    l2 = [r["lanelet2"] for r in rows if r["lanelet2"].get("ok")]
    matches = sum(r["topology_matches_hdmap"] for r in rows)
    lines = [f"{len(rows)} maps; topology equals HD map on {matches}; lanelet2 loaded {len(l2)}"]
    if l2:
        lines.append(
            f"lanelet2: load errors {sum(x['load_errors'] for x in l2)}, reversed lanelets "
            f"{sum(len(x['inverted_bounds']) for x in l2)} of {sum(x['lanelets'] for x in l2)}, "
            f"lanelets with other links than written "
            f"{sum(len(x['topology_mismatches']) for x in l2)}, "
            f"route success min {min(x['route_success'] for x in l2):.3f} mean "
            f"{statistics.mean(x['route_success'] for x in l2):.4f}, ms/route mean "
            f"{statistics.mean(x['route_ms'] for x in l2):.2f} max "
            f"{max(x['route_ms'] for x in l2):.2f}, projection max "
            f"{1000 * max(x['projection_max_error_m'] for x in l2):.3f} mm")
        walks = [x["pedestrian_route_success"] for x in l2 if "pedestrian_route_success" in x]
        if walks:
            lines.append(f"pedestrian routing (maps with sidewalks: {len(walks)}): min "
                         f"{min(walks):.3f} mean {statistics.mean(walks):.4f}")
    t2 = [r["tactics2d"] for r in rows if r["tactics2d"] and "error" not in r["tactics2d"]]
    if t2:
        lines.append(
            f"Tactics2D: load s mean {statistics.mean(x['load_s'] for x in t2):.1f} max "
            f"{max(x['load_s'] for x in t2):.1f}; search success min "
            f"{min(x['search_success'] for x in t2):.3f}, ms mean "
            f"{statistics.mean(x['search_ms'] for x in t2):.1f}; Router.plan success min "
            f"{min(x['router_success'] for x in t2):.3f}, ms mean "
            f"{statistics.mean(x['router_ms'] for x in t2):.0f} max "
            f"{max(x['router_ms'] for x in t2):.0f} (rebuilding the graph per call: mean "
            f"{statistics.mean(x['router_rebuild_ms'] for x in t2):.0f})")
    return "\n".join(lines)


def parse_args(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scenarios", nargs="*", type=Path)
    ap.add_argument("--densities", default="10,20,30,40,50,60")
    ap.add_argument("--seeds", default="0-4")
    ap.add_argument("--style", default="mixed")
    ap.add_argument("--size", type=float, default=2000.0)
    ap.add_argument("--pairs", type=int, default=1000)
    ap.add_argument("--tactics2d-tasks", type=int, default=100)
    ap.add_argument("--router-tasks", type=int, default=20)
    ap.add_argument("--router-rebuild-tasks", type=int, default=3)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--tactics2d-python", default=None)
    ap.add_argument("--json", type=Path, default=Path("bench/results/check_lanelet2.json"))
    ap.add_argument("--tactics2d-worker", action="store_true", help=argparse.SUPPRESS)
    ap.add_argument("--origin", type=float, nargs=2, help=argparse.SUPPRESS)
    return ap.parse_args(argv)


def main(argv=None) -> None:
    args = parse_args(argv)
    if args.tactics2d_worker:  # child mode, run by --tactics2d-python
        print(json.dumps(tactics2d_figures(args.scenarios[0], tuple(args.origin),
                                           args.tactics2d_tasks, args.router_tasks,
                                           args.router_rebuild_tasks, args.seed)))
        return
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for spec, osm, hd, timing in cases(args, Path(tmp)):
            rows.append(measure(spec, osm, hd, timing, args))
            print(format_row(rows[-1]), flush=True)
    print(summary(rows))
    args.json.parent.mkdir(parents=True, exist_ok=True)
    args.json.write_text(json.dumps(rows, indent=2) + "\n")


if __name__ == "__main__":
    sys.exit(main())
