"""Validate a scenario folder and write its ``report.json``: net metrics, a libsumo run, routing
tasks, and a pass/fail verdict against one table of thresholds.

``report.json`` is byte-identical for the same scenario (sorted keys, rounded floats, no wall-clock
figures): those go into the separate timing dict that the caller writes as ``timing.json``.
"""

from __future__ import annotations

import json
import operator
import time
from pathlib import Path
from typing import NamedTuple

import numpy as np

from ..errors import RoadweaverError
from ..scenario.sumocfg import NET_FILE, end_time
from .net_metrics import net_metrics
from .netgraph import require_net
from .rule_coverage import rule_lines
from .simulation import started_simulation

SCHEMA_VERSION = 1
REPORT_FILE = "report.json"
SPEC_FILE = "spec.json"
DIGITS = 6  # floats in report.json are rounded to this many decimals
# Wall-clock cap of the simulation: a minute for loading plus the configured horizon at 20 sim-s
# per wall-s for every 1000 vehicles (a step costs about as much as the vehicles in it). Healthy
# runs of 500 vehicles go 1000+ sim-s/s; only gridlock (~30 sim-s/s) comes near the cap. A 20 km
# map with 10,000 vehicles runs at 10-17 sim-s/s, healthy, and hit a cap that ignored them.
WALL_CAP_BASE_S = 60.0
WALL_CAP_MIN_SPEED = 20.0
WALL_CAP_VEHICLES = 1000


class Threshold(NamedTuple):
    figure: str  # dotted path into the report
    op: str  # ">=", "<=" or "=="
    limit: float | bool
    what: str
    optional: bool = False  # judged only where the report has the figure (pedestrians)


THRESHOLDS: tuple[Threshold, ...] = (
    Threshold("net.lcc_ratio", ">=", 1.0, "share of road nodes in the largest component"),
    Threshold("net.lane_reachability", ">=", 0.995, "share of lane pairs with a drivable path"),
    Threshold("net.crossings_without_junction", "<=", 0,
              "roads whose lanes cross or overlap outside a junction"),
    Threshold("net.sharp_bends", "<=", 0, "roads turning over 120° within 12 m"),
    Threshold("net.alignment.mean", "<=", 0.05, "mean lane-end gap at junctions (m)"),
    Threshold("simulation.arrived_ratio", ">=", 0.99, "share of vehicles that arrived"),
    Threshold("simulation.teleport_ratio", "<=", 0.01, "teleports per vehicle"),
    Threshold("simulation.persons_arrived_ratio", ">=", 0.99,
              "share of pedestrians that arrived", optional=True),
    Threshold("simulation.collisions", "<=", 0, "collisions"),
    Threshold("simulation.routing_success_rate", ">=", 0.995, "share of routing tasks solved"),
    Threshold("simulation.completed", "==", True, "simulation finished within its wall cap"),
)
_OPS = {">=": operator.ge, "<=": operator.le, "==": operator.eq}


def validate_scenario(
    out_dir: Path, net_figures: dict | None = None, *, split_routing: bool = True
) -> tuple[dict, dict]:
    """Measure the scenario in ``out_dir`` (net metrics + simulation + routing) and judge it.

    The simulation and the routing queries run in child processes while this one measures the
    net, so the work spreads over the cores (``split_routing``: see
    :func:`~.simulation.started_simulation`). ``net_figures`` are :func:`net_metrics` of the
    folder's net when the caller measured them already (make-scenario does, while the demand
    is routed).

    Returns (report, timing); the report carries ``passed`` and ``failures``.
    """
    out_dir = Path(out_dir)
    spec = read_spec(out_dir)
    area_km2 = spec["width"] * spec["height"] / 1e6
    net_path = out_dir / NET_FILE
    require_net(net_path)
    t0 = time.perf_counter()
    with started_simulation(
        out_dir, wall_cap_s=wall_cap_s(spec["duration"], spec["vehicles"]), seed=spec["seed"],
        split_routing=split_routing,
    ) as finish_simulation:
        timing = {}
        if net_figures is None:
            net_figures = net_metrics(net_path, area_km2)
            timing["net_metrics_s"] = time.perf_counter() - t0
        sim, sim_timing = finish_simulation()
    vehicles = max(spec["vehicles"], sim["loaded"])  # with the buses of the bus lines
    sim["arrived_ratio"] = sim["arrived"] / vehicles
    sim["teleport_ratio"] = sim["teleports_total"] / vehicles
    if spec["persons"]:
        sim["persons_arrived_ratio"] = sim["persons_arrived"] / spec["persons"]
    scenario = {k: spec[k] for k in ("width", "height", "seed", "vehicles", "duration")}
    scenario.update(area_km2=area_km2, end_s=end_time(spec["duration"]))
    report = _with_verdict({"scenario": scenario, "net": net_figures, "simulation": sim})
    timing.update(sim_timing, total_s=time.perf_counter() - t0)
    return report, _rounded(timing, 3)


def wall_cap_s(duration: float, vehicles: int) -> float:
    """Wall-clock cap (s) of the validation run of a scenario whose demand of ``vehicles``
    lasts ``duration``."""
    load = max(1.0, vehicles / WALL_CAP_VEHICLES)
    return WALL_CAP_BASE_S + end_time(duration) / WALL_CAP_MIN_SPEED * load


def read_spec(out_dir: Path) -> dict:
    """The fields of ``spec.json`` validation needs, checked, with a one-line error otherwise."""
    path = Path(out_dir) / SPEC_FILE
    try:
        spec = json.loads(path.read_text(encoding="utf-8"))
        fields = {
            "width": float(spec["width"]),
            "height": float(spec["height"]),
            "seed": int(spec["seed"]),
            "vehicles": int(spec["vehicles"]),
            "duration": float(spec["duration"]),
            "persons": int(spec.get("persons", 0)),
        }
    except FileNotFoundError:
        raise RoadweaverError(f"{path} not found; is {out_dir} a scenario folder?") from None
    except (ValueError, KeyError, TypeError) as exc:
        raise RoadweaverError(f"{path}: missing or invalid field {exc}") from None
    if min(fields["width"], fields["height"], fields["vehicles"], fields["duration"]) <= 0:
        raise RoadweaverError(f"{path}: width, height, vehicles and duration must be > 0")
    return fields


def check_thresholds(report: dict) -> list[str]:
    """One readable line per failed threshold: figure, its value, the limit (a single line when
    the report holds no validation figures at all, e.g. a scenario written unvalidated)."""
    if "net" not in report and "simulation" not in report:
        return ["not validated: the report has no net or simulation figures"]
    failures = []
    for t in THRESHOLDS:
        value = _lookup(report, t.figure)
        if value is None and t.optional:
            continue
        if value is None:
            failures.append(f"{t.figure} ({t.what}) is missing from the report")
        elif not _OPS[t.op](value, t.limit):
            failures.append(f"{t.figure} ({t.what}) is {_fmt(value)}, limit {t.op} {_fmt(t.limit)}")
    return failures


def write_report(out_dir: Path, report: dict) -> Path:
    """Write ``out_dir/report.json`` deterministically, with the verdict recomputed on the
    rounded figures so that the file always agrees with itself."""
    text = json.dumps(_with_verdict(report), indent=2, sort_keys=True, allow_nan=False)
    path = Path(out_dir) / REPORT_FILE
    path.write_text(text + "\n", encoding="utf-8")
    return path


def summary_lines(report: dict) -> list[str]:
    """A short human summary of a report for the command line."""
    sc, net, sim = report["scenario"], report["net"], report["simulation"]
    al = net["alignment"]
    verdict = "PASSED" if report["passed"] else "FAILED"
    ending = "completed" if sim["completed"] else "STOPPED by the wall-clock cap"
    sites = ", ".join(f"{site} x{n}" for site, n in sim.get("collision_sites", [])[:3])
    lines = [
        (
            f"{verdict}: {sc['vehicles']} vehicles over {sc['duration']:g} s"
            f" on {sc['width']:g} x {sc['height']:g} m"
        ),
        (
            f"net: {net['road_nodes']} road nodes ({net['density']:.1f}/km²), {net['lanes']} lanes,"
            f" LCC {net['lcc_ratio']:.3f}, dead ends {net['dead_end_ratio']:.3f},"
            f" crossings without junction {net['crossings_without_junction']},"
            f" sharp bends {net['sharp_bends']}"
        ),
        (
            f"reachability: junctions {net['junction_reachability']:.4f},"
            f" lanes {net['lane_reachability']:.4f}; lane-end gaps mean {al['mean']:.3f} m,"
            f" p95 {al['p95']:.3f} m, max {al['max']:.3f} m"
        ),
        *(rule_lines(net["rules"])[:1] if "rules" in net else []),
        (
            f"simulation: {sim['arrived']}/{max(sim['loaded'], sc['vehicles'])} arrived"
            f" ({100 * sim['arrived_ratio']:.1f} %), {sim['teleports_total']} teleports,"
            f" {sim['collisions']} collisions{f' ({sites})' if sites else ''},"
            f" {ending} at {sim['sim_end_s']:g} s"
        ),
        *([(f"pedestrians: {sim['persons_arrived']}/{sim['persons_loaded']} arrived, "
            f"{sim['persons_jammed']} jammed, {sim.get('persons_time_loss_s', 0):.1f} s lost "
            "per walk")] if sim.get("persons_loaded") else []),
        (
            f"trips: mean travel {sim['mean_travel_time_s']:.1f} s,"
            f" waiting {sim['mean_waiting_time_s']:.1f} s; routing success"
            f" {100 * sim['routing_success_rate']:.1f} % of {sim['routing_tasks']} tasks"
        ),
    ]
    like = report.get("generation", {}).get("like")
    if like:
        figures = ", ".join(f"{name.removesuffix('_inner').replace('_', ' ')} {v['map']:.3g}"
                            f" ({v['city']:.3g})" for name, v in like["statistics"].items())
        lines.append(f"like {like['name']} (its figures in brackets; closest of "
                     f"{like['candidates']} maps, distance {like['distance']:.3f}): {figures}")
    return lines + [f"  failed: {f}" for f in report["failures"]]


def _with_verdict(report: dict) -> dict:
    """The report, rounded, with schema version, ``failures`` and ``passed`` (re)computed."""
    body = {k: v for k, v in report.items() if k not in ("passed", "failures")}
    body = _rounded({**body, "schema_version": SCHEMA_VERSION}, DIGITS)
    failures = check_thresholds(body)
    return {**body, "failures": failures, "passed": not failures}


def _rounded(obj, digits: int):
    """Floats rounded (and -0.0 made 0.0) all through nested dicts and lists; numpy scalars
    become plain Python numbers so that json can write them."""
    if isinstance(obj, np.generic):
        obj = obj.item()
    if isinstance(obj, float):
        return round(obj, digits) + 0.0
    if isinstance(obj, dict):
        return {k: _rounded(v, digits) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_rounded(v, digits) for v in obj]
    return obj


def _lookup(report: dict, figure: str):
    value = report
    for part in figure.split("."):
        if not isinstance(value, dict) or part not in value:
            return None
        value = value[part]
    return value


def _fmt(value) -> str:
    return f"{value:.6g}" if isinstance(value, float) else str(value)
