"""Run a scenario in libsumo and time random routing queries on its net.

libsumo keeps one simulation per process and a second ``start`` silently replaces the first
(shared NOTES), so every run happens in fresh ``python -m roadweaver_sumo.validate.simulation``
child processes: one simulates, one answers the routing queries. A subprocess rather than a multiprocessing pool: a crash inside libsumo then ends
the run with an error at once (a pool would silently respawn the worker and wait for its timeout),
and nothing depends on how the caller's ``__main__`` can be re-imported. SUMO's console chatter,
the statistic output and the result go to a temporary folder, never into the scenario folder
(inside the staging folder of a scenario being made: ``staging.scratch_dir``). The children die
with this process (``children``). Gridlocked runs crawl (~30 sim-s per wall-s), hence the wall-clock cap.
"""

from __future__ import annotations

import json
import math
import subprocess
import sys
import tempfile
import time
from collections import Counter
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path

import numpy as np
from lxml import etree

from .. import children
from ..errors import RoadweaverError
from ..scenario.sumocfg import NET_FILE, SUMOCFG_FILE
from ..staging import scratch_dir
from ..sumo_tools import child_env
from .rule_coverage import approach_rules, rule_waits

VEHICLE_TYPE = "DEFAULT_VEHTYPE"  # SUMO's default car (vClass passenger)
VEHICLE_CLASS = "passenger"
HARD_TIMEOUT_MARGIN_S = 120.0  # loading and routing time on top of the cap, before we kill it
MAX_COLLISION_SITES = 10  # reported in the results, most frequent first


def run_simulation(
    out_dir: Path, *, wall_cap_s: float, routing_tasks: int = 1000, seed: int = 0
) -> tuple[dict, dict]:
    """Simulate ``out_dir/scenario.sumocfg`` until every car arrived or the configured end, then
    answer ``routing_tasks`` random edge-to-edge routing queries (pairs drawn from ``seed``).

    Returns (results, timing): results are deterministic for a given scenario and seed
    (``completed`` is False when ``wall_cap_s`` stopped the run); timing holds wall-clock figures.
    """
    with started_simulation(out_dir, wall_cap_s=wall_cap_s, routing_tasks=routing_tasks,
                            seed=seed) as finish:
        return finish()


@contextmanager
def started_simulation(
    out_dir: Path, *, wall_cap_s: float, routing_tasks: int = 1000, seed: int = 0,
    split_routing: bool = True,
) -> Iterator[Callable[[], tuple[dict, dict]]]:
    """:func:`run_simulation` started in child processes, so the caller can work meanwhile
    (validation measures the net). Yields ``finish``, which waits for the children and returns
    what :func:`run_simulation` returns; children still running when the block is left (the
    caller's own work failed) are killed.

    With ``split_routing`` the routing queries run in a second child on the same configuration
    without its demand, alongside the simulation rather than after it: whether a route exists
    depends on the net alone, and on a 10 km map the queries take as long as the simulation
    itself. That child loads the net a second time, which costs CPU time where other jobs keep
    every core busy (a suite's workers): without it, the simulation's child answers the
    queries after its run, as SUMO's one loaded net allows."""
    cfg = Path(out_dir).resolve() / SUMOCFG_FILE
    if not cfg.exists():
        raise RoadweaverError(f"simulation: {cfg} not found")
    started = time.perf_counter()
    hard_limit = wall_cap_s + HARD_TIMEOUT_MARGIN_S
    with tempfile.TemporaryDirectory(prefix="roadweaver-sim-", dir=scratch_dir()) as tmp:
        common = {"cfg": str(cfg), "wall_cap_s": wall_cap_s, "routing_tasks": routing_tasks,
                  "seed": seed}  # fmt: skip
        kinds = ("simulate", "route") if split_routing else ("simulate and route",)
        children = [_Child(Path(tmp) / kind.replace(" ", "-"), {**common, "kind": kind})
                    for kind in kinds]

        def finish() -> tuple[dict, dict]:
            results, timing = {}, {}
            for child in children:
                found, took = child.result(cfg, started + hard_limit, wall_cap_s)
                results.update(found)
                timing.update(took)
            timing["process_wall_s"] = time.perf_counter() - started
            return results, timing

        try:
            yield finish
        finally:
            for child in children:
                child.kill()



class _Child:
    """One ``python -m roadweaver_sumo.validate.simulation`` child with its own folder for
    SUMO's output, its log and its ``result.json``."""

    def __init__(self, folder: Path, job: dict) -> None:
        folder.mkdir()
        self.log, self.result_file = folder / "sumo.log", folder / "result.json"
        with self.log.open("w") as out:
            self.proc = children.popen(
                [sys.executable, "-m", __name__, json.dumps({**job, "tmp": str(folder)})],
                stdout=out, stderr=subprocess.STDOUT, env=child_env(),
            )  # fmt: skip

    def result(self, cfg: Path, deadline: float, wall_cap_s: float) -> tuple[dict, dict]:
        try:
            children.wait(self.proc, timeout=max(0.0, deadline - time.perf_counter()))
        except subprocess.TimeoutExpired:
            raise RoadweaverError(
                f"simulation of {cfg} did not return within {wall_cap_s:.0f} s "
                f"+ {HARD_TIMEOUT_MARGIN_S:.0f} s; killed"
            ) from None
        if not self.result_file.exists():
            raise RoadweaverError(
                f"simulation of {cfg} crashed (exit code {self.proc.returncode}): "
                f"{_last_line(self.log)}"
            )
        payload = json.loads(self.result_file.read_text(encoding="utf-8"))
        if "error" in payload:
            raise RoadweaverError(payload["error"])
        return payload["results"], payload["timing"]

    def kill(self) -> None:
        children.kill(self.proc)


def _main(job: dict) -> None:
    """Child process: run the job, write ``result.json`` (results and timing, or an error)."""
    result = Path(job["tmp"]) / "result.json"
    try:
        if job["kind"] == "route":
            results, timing = _route(job["cfg"], job["routing_tasks"], job["seed"])
        else:
            tasks = job["routing_tasks"] if job["kind"] == "simulate and route" else 0
            results, timing = _simulate(job["cfg"], job["tmp"], job["wall_cap_s"], tasks,
                                        job["seed"])
        payload = {"results": results, "timing": timing}
    except RoadweaverError as exc:
        payload = {"error": str(exc)}
    result.write_text(json.dumps(payload), encoding="utf-8")


def _start(libsumo, cfg: str, options: list[str]) -> None:
    """``libsumo.start`` on ``cfg``; a one-line error if SUMO cannot load it. libsumo is
    imported in the children only, so the caller's process never loads it (SUMO_HOME is
    already set by ``child_env``)."""
    try:
        libsumo.start(["sumo", "-c", cfg, *options, "--no-step-log", "true",
                       "--routing-algorithm", "astar"])  # fmt: skip
    except libsumo.TraCIException as exc:
        message = " ".join(str(exc).split()) or "see SUMO's messages"
        raise RoadweaverError(f"sumo could not load {cfg}: {message}") from None


def _simulate(cfg: str, tmp: str, wall_cap_s: float, routing_tasks: int = 0,
              seed: int = 0) -> tuple[dict, dict]:
    """Load, step until done, answer ``routing_tasks`` routing queries, close; the figures
    from SUMO's output files."""
    import libsumo

    stats, collisions = Path(tmp) / "statistics.xml", Path(tmp) / "collisions.xml"
    edgedata = Path(tmp) / "edgedata.xml"
    t0 = time.perf_counter()
    _start(libsumo, cfg, ["--statistic-output", str(stats), "--collision-output",
                          str(collisions), "--edgedata-output", str(edgedata),
                          "--duration-log.statistics", "true"])  # fmt: skip
    t1 = time.perf_counter()
    try:
        completed = _step_until_done(libsumo, deadline=t1 + wall_cap_s)
        sim_end = libsumo.simulation.getTime()
        t2 = time.perf_counter()
        routing = _answered(libsumo, routing_tasks, seed) if routing_tasks else ({}, {})
    finally:
        libsumo.close()
    results = {"completed": completed, "sim_end_s": sim_end, **_read_statistics(stats),
               "collision_sites": _collision_sites(collisions),
               "edge_flows": _edge_flows(edgedata),
               "rules": rule_waits(edgedata, approach_rules(Path(cfg).parent / NET_FILE))
               if edgedata.exists() else {}, **routing[0]}  # fmt: skip
    timing = {
        "load_s": t1 - t0,
        "simulation_wall_s": t2 - t1,
        "sim_s_per_wall_s": sim_end / max(t2 - t1, 1e-9),
        **routing[1],
    }
    return results, timing


def _route(cfg: str, routing_tasks: int, seed: int) -> tuple[dict, dict]:
    """Load the net (the configuration without its demand), answer the routing queries."""
    import libsumo

    _start(libsumo, cfg, ["--route-files", ""])
    try:
        return _answered(libsumo, routing_tasks, seed)
    finally:
        libsumo.close()


def _answered(libsumo, routing_tasks: int, seed: int) -> tuple[dict, dict]:
    """:func:`_routing_success` and its time per query."""
    t0 = time.perf_counter()
    routing = _routing_success(libsumo, routing_tasks, seed)
    return routing, {"routing_ms_per_route": 1000 * (time.perf_counter() - t0)
                     / max(routing_tasks, 1)}


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
    """The figures we report from SUMO's ``--statistic-output`` file. SUMO counts bicycles
    apart (``bikeTripStatistics``): they arrive like any vehicle; the trip means are those of
    the motor vehicles. Pedestrians: loaded, arrived (walks completed), jammed (teleported
    past a blocked sidewalk or crossing), and the time a walk lost against walking freely:
    waiting at crossings and lights, where a changed driver model or light program shows."""
    root = etree.parse(str(path)).getroot()

    def number(tag: str, attr: str) -> float:
        element = root.find(tag)
        return float(element.get(attr)) if element is not None else 0.0

    return {
        "loaded": int(number("vehicles", "loaded")),
        "inserted": int(number("vehicles", "inserted")),
        "running": int(number("vehicles", "running")),
        "waiting_to_insert": int(number("vehicles", "waiting")),
        "arrived": int(number("vehicleTripStatistics", "count")
                       + number("bikeTripStatistics", "count")),
        "teleports_total": int(number("teleports", "total")),
        "teleports_jam": int(number("teleports", "jam")),
        "teleports_yield": int(number("teleports", "yield")),
        "teleports_wrong_lane": int(number("teleports", "wrongLane")),
        "collisions": int(number("safety", "collisions")),
        "persons_loaded": int(number("persons", "loaded")),
        "persons_arrived": int(number("pedestrianStatistics", "number")),
        "persons_jammed": int(number("persons", "jammed")),
        "persons_time_loss_s": number("pedestrianStatistics", "timeLoss"),
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
