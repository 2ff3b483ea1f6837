"""Run a scenario in libsumo and time random routing queries on its net.

libsumo keeps one simulation per process and a second ``start`` silently replaces the first
(shared NOTES), so every run happens in a fresh ``python -m roadweaver_sumo.validate.simulation``
child process. A subprocess rather than a multiprocessing pool: a crash inside libsumo then ends
the run with an error at once (a pool would silently respawn the worker and wait for its timeout),
and nothing depends on how the caller's ``__main__`` can be re-imported. SUMO's console chatter,
the statistic output and the result go to a temporary folder, never into the scenario folder.
Gridlocked runs crawl (~30 sim-s per wall-s), hence the wall-clock cap.
"""

from __future__ import annotations

import json
import math
import subprocess
import sys
import tempfile
import time
from collections import Counter
from pathlib import Path

import numpy as np
from lxml import etree

from ..errors import RoadweaverError
from ..scenario.sumocfg import SUMOCFG_FILE
from ..sumo_tools import child_env

VEHICLE_TYPE = "DEFAULT_VEHTYPE"  # SUMO's default car (vClass passenger)
VEHICLE_CLASS = "passenger"
HARD_TIMEOUT_MARGIN_S = 120.0
MAX_COLLISION_SITES = 10  # reported in the results, most frequent first  # loading and routing time on top of the cap, before we kill it


def run_simulation(
    out_dir: Path, *, wall_cap_s: float, routing_tasks: int = 1000, seed: int = 0
) -> tuple[dict, dict]:
    """Simulate ``out_dir/scenario.sumocfg`` until every car arrived or the configured end, then
    answer ``routing_tasks`` random edge-to-edge routing queries (pairs drawn from ``seed``).

    Returns (results, timing): results are deterministic for a given scenario and seed
    (``completed`` is False when ``wall_cap_s`` stopped the run); timing holds wall-clock figures.
    """
    cfg = Path(out_dir).resolve() / SUMOCFG_FILE
    if not cfg.exists():
        raise RoadweaverError(f"simulation: {cfg} not found")
    started = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="roadweaver-sim-") as tmp:
        job = {"cfg": str(cfg), "tmp": tmp, "wall_cap_s": wall_cap_s,
               "routing_tasks": routing_tasks, "seed": seed}  # fmt: skip
        log, result = Path(tmp) / "sumo.log", Path(tmp) / "result.json"
        with log.open("w") as out:
            try:
                proc = subprocess.run(
                    [sys.executable, "-m", __name__, json.dumps(job)],
                    check=False, stdout=out, stderr=subprocess.STDOUT, env=child_env(),
                    timeout=wall_cap_s + HARD_TIMEOUT_MARGIN_S,
                )  # fmt: skip
            except subprocess.TimeoutExpired:
                raise RoadweaverError(
                    f"simulation of {cfg} did not return within {wall_cap_s:.0f} s "
                    f"+ {HARD_TIMEOUT_MARGIN_S:.0f} s; killed"
                ) from None
        if not result.exists():
            raise RoadweaverError(
                f"simulation of {cfg} crashed (exit code {proc.returncode}): {_last_line(log)}"
            )
        payload = json.loads(result.read_text(encoding="utf-8"))
    if "error" in payload:
        raise RoadweaverError(payload["error"])
    payload["timing"]["process_wall_s"] = time.perf_counter() - started
    return payload["results"], payload["timing"]


def _main(job: dict) -> None:
    """Child process: run the job, write ``result.json`` (results and timing, or an error)."""
    result = Path(job["tmp"]) / "result.json"
    try:
        results, timing = _simulate(
            job["cfg"], job["tmp"], job["wall_cap_s"], job["routing_tasks"], job["seed"]
        )
        payload = {"results": results, "timing": timing}
    except RoadweaverError as exc:
        payload = {"error": str(exc)}
    result.write_text(json.dumps(payload), encoding="utf-8")


def _simulate(
    cfg: str, tmp: str, wall_cap_s: float, routing_tasks: int, seed: int
) -> tuple[dict, dict]:
    """Load, step, route, close. Runs in the child only: libsumo is imported here so the
    caller's process never loads it (SUMO_HOME is already set by ``child_env``)."""
    import libsumo

    stats, collisions = Path(tmp) / "statistics.xml", Path(tmp) / "collisions.xml"
    edgedata = Path(tmp) / "edgedata.xml"
    t0 = time.perf_counter()
    try:
        libsumo.start(["sumo", "-c", cfg, "--statistic-output", str(stats),
                       "--collision-output", str(collisions),
                       "--edgedata-output", str(edgedata),
                       "--duration-log.statistics", "true", "--no-step-log", "true",
                       "--routing-algorithm", "astar"])  # fmt: skip
    except libsumo.TraCIException as exc:
        message = " ".join(str(exc).split()) or "see SUMO's messages"
        raise RoadweaverError(f"sumo could not load {cfg}: {message}") from None
    t1 = time.perf_counter()
    try:
        completed = _step_until_done(libsumo, deadline=t1 + wall_cap_s)
        sim_end = libsumo.simulation.getTime()
        t2 = time.perf_counter()
        routing = _routing_success(libsumo, routing_tasks, seed)
        t3 = time.perf_counter()
    finally:
        libsumo.close()
    results = {"completed": completed, "sim_end_s": sim_end, **_read_statistics(stats)}
    results.update(routing, collision_sites=_collision_sites(collisions),
                   edge_flows=_edge_flows(edgedata))
    timing = {
        "load_s": t1 - t0,
        "simulation_wall_s": t2 - t1,
        "sim_s_per_wall_s": sim_end / max(t2 - t1, 1e-9),
        "routing_ms_per_route": 1000 * (t3 - t2) / max(routing_tasks, 1),
    }
    return results, timing


def _step_until_done(libsumo, deadline: float) -> bool:
    """Step until no car is left or the configured end; False if the wall clock ran out first.
    (libsumo would happily step past ``end``, so the end is checked here.)"""
    end = libsumo.simulation.getEndTime()
    end = end if end >= 0 else math.inf
    sim = libsumo.simulation
    while sim.getMinExpectedNumber() > 0 and sim.getTime() < end:
        if time.perf_counter() > deadline:
            return False
        sim.step()
    return True


def _routing_success(libsumo, tasks: int, seed: int) -> dict:
    """Share of ``tasks`` random pairs of distinct car edges with a non-empty fastest route."""
    edges = sorted(
        e for e in libsumo.edge.getIDList()
        if not e.startswith(":") and _allows_cars(libsumo, e)
    )  # fmt: skip
    n = len(edges)
    if n < 2 or tasks < 1:
        return {"routing_tasks": tasks, "routing_success_rate": 0.0}
    rng = np.random.default_rng(seed)
    src = rng.integers(n, size=tasks)
    dst = (src + rng.integers(1, n, size=tasks)) % n  # never the same edge
    found = 0
    for a, b in zip(src, dst):
        try:
            found += len(libsumo.simulation.findRoute(edges[a], edges[b], VEHICLE_TYPE).edges) > 0
        except libsumo.TraCIException:
            pass
    return {"routing_tasks": tasks, "routing_success_rate": found / tasks}


def _allows_cars(libsumo, edge: str) -> bool:
    lanes = range(libsumo.edge.getLaneNumber(edge))
    return any(VEHICLE_CLASS in libsumo.lane.getAllowed(f"{edge}_{i}") for i in lanes)


def _read_statistics(path: Path) -> dict:
    """The figures we report from SUMO's ``--statistic-output`` file."""
    root = etree.parse(str(path)).getroot()

    def number(tag: str, attr: str) -> float:
        element = root.find(tag)
        return float(element.get(attr)) if element is not None else 0.0

    return {
        "loaded": int(number("vehicles", "loaded")),
        "inserted": int(number("vehicles", "inserted")),
        "running": int(number("vehicles", "running")),
        "waiting_to_insert": int(number("vehicles", "waiting")),
        "arrived": int(number("vehicleTripStatistics", "count")),
        "teleports_total": int(number("teleports", "total")),
        "teleports_jam": int(number("teleports", "jam")),
        "teleports_yield": int(number("teleports", "yield")),
        "teleports_wrong_lane": int(number("teleports", "wrongLane")),
        "collisions": int(number("safety", "collisions")),
        "emergency_stops": int(number("safety", "emergencyStops")),
        "mean_travel_time_s": number("vehicleTripStatistics", "duration"),
        "mean_waiting_time_s": number("vehicleTripStatistics", "waitingTime"),
        "mean_time_loss_s": number("vehicleTripStatistics", "timeLoss"),
        "mean_route_length_m": number("vehicleTripStatistics", "routeLength"),
    }


def _collision_sites(path: Path, most: int = MAX_COLLISION_SITES) -> list:
    """Where collisions happened, most frequent first: ``[["junction n206", 7], ...]`` (a list,
    so the order survives JSON with sorted keys); points a failed check at the geometry to fix."""
    counts = Counter(_site(c.get("lane", "")) for c in etree.parse(str(path)).iter("collision"))
    return [[site, n] for site, n in sorted(counts.items(), key=lambda kv: (-kv[1], kv[0]))[:most]]


def _edge_flows(path: Path) -> dict[str, int]:
    """Vehicles that used each normal edge during the run (departed on it or entered it), from
    SUMO's ``--edgedata-output``; edges nobody used are left out to keep ``report.json`` short.
    The preview draws them as a heat overlay."""
    flows: Counter = Counter()
    if path.exists():
        for edge in etree.parse(str(path)).iter("edge"):
            edge_id = edge.get("id", "")
            if not edge_id.startswith(":"):
                used = float(edge.get("departed", 0)) + float(edge.get("entered", 0))
                flows[edge_id] += int(used)
    return {edge: n for edge, n in sorted(flows.items()) if n > 0}


def _site(lane: str) -> str:
    """``junction <id>`` for an internal lane (``:<junction>_<link>_<lane>``), else ``lane <id>``."""
    return f"junction {lane[1:].rsplit('_', 2)[0]}" if lane.startswith(":") else f"lane {lane}"


def _last_line(log: Path) -> str:
    """The last error SUMO logged, else its last line: one line for the user."""
    text = log.read_text(errors="replace") if log.exists() else ""
    lines = [ln.strip() for ln in text.splitlines() if ln.strip()]
    errors = [ln for ln in lines if ln.startswith("Error")]
    return (errors or lines or ["no output"])[-1]


if __name__ == "__main__":
    _main(json.loads(sys.argv[1]))
