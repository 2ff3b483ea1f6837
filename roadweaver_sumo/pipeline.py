"""The whole path from a spec to a validated scenario folder (DESIGN.md, "Data flow").

The folder is built in a hidden temporary sibling and moved into place only when complete
(``staging.staged_folder``), so an interrupted or failed run never leaves something that looks
like a finished scenario, and an existing folder is replaced only with ``force``.

Each stage imports what it runs when it begins (numba's compiled tracer, scipy, shapely,
sumolib, ...): a run that stops early, on bad input or an existing folder, never waits for
them, and each stage's time in ``timing.json`` includes what it loaded.
"""

from __future__ import annotations

import json
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from functools import partial
from pathlib import Path

from .gc_pause import cyclic_gc_paused
from .spec import DEFAULT_BUS_LINES, ScenarioSpec
from .staging import staged_folder

SPEC_FILE = "spec.json"
TIMING_FILE = "timing.json"


@dataclass
class ScenarioResult:
    """What ``make_scenario`` built: the folder, its report (None without validation), timings."""

    out_dir: Path
    report: dict | None
    timing: dict = field(default_factory=dict)

    @property
    def failures(self) -> list[str]:
        from .validate.report import check_thresholds

        return check_thresholds(self.report) if self.report else []


def make_scenario(
    spec: ScenarioSpec,
    out_dir: Path,
    *,
    force: bool = False,
    validate: bool = True,
    cores_busy: bool = False,
    log: Callable[[str], None] = lambda msg: None,
) -> ScenarioResult:
    """Generate, export, and (unless ``validate`` is False) validate one scenario.
    ``cores_busy``: other jobs keep every core busy (a suite's workers), so validation does
    not load the net a second time to answer the routing queries beside the simulation.
    ``timing.json`` holds each stage's wall time and the whole run's (``total_s``)."""
    out_dir = Path(out_dir)
    began = time.perf_counter()
    stages: dict[str, float] = {}
    stage = partial(_timed, stages, log)
    with staged_folder(out_dir, force) as tmp:
        generation = build_scenario_files(spec, tmp, stages, log)
        timing: dict = {"stages_s": stages}
        drawing = None
        from .validate.report import write_report

        if validate:
            with stage("validating: net metrics, libsumo run and routing tasks", "validate"):
                from .render import net_drawing
                from .scenario.sumocfg import NET_FILE
                from .validate.net_metrics import loaded_net_metrics
                from .validate.netgraph import load_net
                from .validate.report import validate_scenario

                net = load_net(tmp / NET_FILE)
                drawing = net_drawing(net)
                report, timing["validation"] = validate_scenario(
                    tmp, net_figures=loaded_net_metrics(net, spec.area_km2),
                    split_routing=not cores_busy)
                del net
            write_report(tmp, report | {"generation": generation})
        else:
            write_report(tmp, {"generation": generation, "validated": False})
        with stage("preview", "preview"):  # after the report: it shows the edge flows
            from .render import render_preview

            render_preview(tmp, net=drawing)
        timing["total_s"] = time.perf_counter() - began
        (tmp / TIMING_FILE).write_text(_json(_rounded_timing(timing)), encoding="utf-8")
    report = json.loads((out_dir / "report.json").read_text(encoding="utf-8")) \
        if validate else None
    return ScenarioResult(out_dir, report, timing)


def build_scenario_files(spec: ScenarioSpec, folder: Path, stages: dict, log) -> dict:
    """Every stage up to the runnable scenario, one after another (paper Fig. 1: skeleton,
    expansion, HD map, export with SUMO's netconvert; then the demand); returns the generation
    metrics for the report."""
    stage = partial(_timed, stages, log)
    with cyclic_gc_paused():
        like = None
        if spec.like:
            with stage(f"map like {spec.like['name']}: the closest of a few ...", "like"):
                from .like import closest_map

                provenance, graph, like = closest_map(spec, log)
        else:
            with stage("skeleton ...", "skeleton"):
                from .skeleton import make_skeleton

                skeleton = make_skeleton(spec)
            with stage("expansion ...", "expansion"):
                from .expand import expand_skeleton

                graph = expand_skeleton(spec, skeleton)
            provenance = skeleton.provenance
            del skeleton
        with stage("hdmap ...", "hdmap"):
            from .hdmap import build_hdmap_for, hdmap_metrics

            hdmap = build_hdmap_for(graph, spec)
        from .export.map_files import write_map_files

        write_map_files(hdmap, folder, spec.netconvert_template, timed=stage)
        (folder / SPEC_FILE).write_text(spec.to_json(), encoding="utf-8")
    from .metrics import graph_metrics
    from .validate.overlaps import hdmap_overlaps

    generation = {
        "target_density": spec.density,
        "skeleton": provenance,
        "road_graph": graph_metrics(graph, spec.area_km2),
        "hdmap": hdmap_metrics(hdmap) | {"lane_overlaps": len(hdmap_overlaps(hdmap))},
    }
    if like:
        generation["like"] = like
    del graph, hdmap  # their memory is free for the simulation
    with stage("demand ...", "demand"):
        from .scenario.demand import write_demand
        from .scenario.sumocfg import write_sumocfg

        write_demand(folder, vehicles=spec.vehicles, duration=spec.duration, seed=spec.seed,
                     vehicle_mix=spec.vehicle_mix, departures=spec.departures,
                     fringe_factor=spec.fringe_factor)
        if spec.persons:
            from .scenario.persons import write_persons

            write_persons(folder, persons=spec.persons, duration=spec.duration, seed=spec.seed,
                          departures=spec.departures)
        if spec.bus_lines is None or spec.bus_lines:
            from .scenario.bus_lines import write_bus_lines

            asked = spec.bus_lines is not None
            generation["bus_lines"] = write_bus_lines(
                folder, spec.bus_lines if asked else DEFAULT_BUS_LINES, spec.duration, asked=asked)
        from .scenario.signal_plans import coordinate_lights

        generation["traffic_lights"] = coordinate_lights(folder)
        write_sumocfg(folder, duration=spec.duration, seed=spec.seed, persons=spec.persons > 0,
                      buses=generation.get("bus_lines", {}).get("lines", 0) > 0,
                      coordinated=generation["traffic_lights"]["coordinated"] > 0)
    if spec.ego_routes:
        with stage(f"{spec.ego_routes} ego routes of {spec.ego_length:g} m ...", "ego_routes"):
            import sumolib

            from .closed_loop.routes import pick_ego_routes, write_ego_routes
            from .scenario.sumocfg import NET_FILE

            net = sumolib.net.readNet(str(folder / NET_FILE))
            write_ego_routes(folder, pick_ego_routes(net, spec.ego_routes, spec.ego_length,
                                                     spec.seed), net)
    return generation


@contextmanager
def _timed(stages: dict, log, message: str, name: str) -> Iterator[None]:
    """Log ``message``, then record the block's wall time as ``stages[name]``."""
    log(message)
    start = time.perf_counter()
    yield
    stages[name] = time.perf_counter() - start


def _rounded_timing(obj):
    if isinstance(obj, float):
        return round(obj, 4)
    if isinstance(obj, dict):
        return {k: _rounded_timing(v) for k, v in obj.items()}
    return obj


def _json(data) -> str:
    return json.dumps(data, indent=2, sort_keys=True) + "\n"
