"""The whole path from a spec to a validated scenario folder (DESIGN.md, "Data flow").

The folder is built in a hidden temporary sibling and moved into place only when complete
(``staging.staged_folder``), so an interrupted or failed run never leaves something that looks
like a finished scenario, and an existing folder is replaced only with ``force``.
"""

from __future__ import annotations

import json
import time
from collections.abc import Callable, Iterator
from concurrent.futures import Future, ThreadPoolExecutor
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path

from .expand import expand_skeleton
from .export.map_files import write_map_files
from .export.netconvert import run_netconvert
from .gc_pause import cyclic_gc_paused
from .hdmap import build_hdmap, hdmap_metrics
from .metrics import graph_metrics
from .render import matplotlib_parts, net_drawing, render_preview
from .scenario.demand import DrawnTrips, draw_first_trips, write_demand
from .scenario.sumocfg import NET_FILE, write_sumocfg
from .skeleton import make_skeleton
from .spec import ScenarioSpec
from .staging import staged_folder
from .validate.net_metrics import loaded_net_metrics
from .validate.netgraph import load_net
from .validate.overlaps import hdmap_overlaps
from .validate.report import check_thresholds, validate_scenario, write_report

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

    ``timing.json`` holds each stage's own wall time and the whole run's (``total_s``): the
    stages after generation overlap (the net is measured while the demand is routed), so
    their sum is more than the total."""
    out_dir = Path(out_dir)
    began = time.perf_counter()
    stages: dict[str, float] = {}
    with staged_folder(out_dir, force) as tmp:
        measured: dict = {}
        after_net = (lambda: _measure_net(tmp, spec.area_km2, measured)) if validate else None
        generation = build_scenario_files(spec, tmp, stages, log, after_net=after_net)
        report = None
        if validate:
            log("validating: libsumo run and routing tasks")
            start = time.perf_counter()
            # This process only waits for the libsumo children now: meanwhile, a thread
            # imports what the preview draws with.
            with ThreadPoolExecutor(1, thread_name_prefix="preview-import") as importer:
                importer.submit(matplotlib_parts)
                report, sim_timing = validate_scenario(
                    tmp, net_figures=measured["figures"], split_routing=not cores_busy)
            stages["validate"] = time.perf_counter() - start
            report["generation"] = generation
            write_report(tmp, report)
            sim_timing["net_metrics_s"] = measured["seconds"]
            timing = {"stages_s": stages, "validation": sim_timing}
        else:
            write_report(tmp, {"generation": generation, "validated": False})
            timing = {"stages_s": stages}
        start = time.perf_counter()
        # after the report: the picture shows the validation's edge flows
        render_preview(tmp, net=measured.get("drawing"))
        stages["preview"] = time.perf_counter() - start
        timing["total_s"] = time.perf_counter() - began
        (tmp / TIMING_FILE).write_text(_json(_rounded_timing(timing)), encoding="utf-8")
    if report is not None:
        report = json.loads((out_dir / "report.json").read_text(encoding="utf-8"))
    return ScenarioResult(out_dir, report, timing)


def build_scenario_files(
    spec: ScenarioSpec, folder: Path, stages: dict, log,
    after_net: Callable[[], None] | None = None,
) -> dict:
    """Every stage up to the runnable scenario; returns the generation metrics for the report.

    netconvert and the demand tools run from worker threads, which only wait for them, so this
    process does its own work on the other core meanwhile: the generation metrics while
    netconvert builds the net, then ``after_net`` (make-scenario measures the net there for
    validation) while the demand is sampled and routed. When netconvert runs a second time
    (``export.netconvert``), randomTrips draws the demand's trips from its first net, whose
    edges are the same, meanwhile."""

    @contextmanager
    def stage(name: str) -> Iterator[None]:
        log(f"{name} ...")
        start = time.perf_counter()
        yield
        stages[name] = time.perf_counter() - start

    drawn: list[Future] = []  # the demand's first trips, drawn from netconvert's draft

    def draw_trips(draft: Path) -> DrawnTrips:
        try:
            return draw_first_trips(folder, draft.name, vehicles=spec.vehicles,
                                    duration=spec.duration, seed=spec.seed)
        finally:
            draft.unlink()

    def netconvert() -> None:
        with stage("netconvert"):
            run_netconvert(folder, spec.netconvert_template,
                           on_draft=lambda draft: drawn.append(sumo_tools.submit(draw_trips,
                                                                                 draft)))

    def demand() -> None:
        with stage("demand"):
            write_demand(folder, vehicles=spec.vehicles, duration=spec.duration, seed=spec.seed,
                         first_trips=drawn[0].result() if drawn else None)
            write_sumocfg(folder, duration=spec.duration, seed=spec.seed)

    with cyclic_gc_paused():
        with stage("skeleton"):
            skeleton = make_skeleton(spec)
        with stage("expansion"):
            graph = expand_skeleton(spec, skeleton)
        with stage("hdmap"):
            hdmap = build_hdmap(graph, spec.geo_origin, traffic_lights=spec.traffic_lights)
        with stage("export"):
            write_map_files(hdmap, folder)
            (folder / SPEC_FILE).write_text(spec.to_json(), encoding="utf-8")
    # Two threads: randomTrips may read netconvert's draft while netconvert runs again.
    with ThreadPoolExecutor(2, thread_name_prefix="sumo-tools") as sumo_tools:
        net_built = sumo_tools.submit(netconvert)
        generation = {
            "target_density": spec.density,
            "skeleton": skeleton.provenance,
            "road_graph": graph_metrics(graph, spec.area_km2),
            "hdmap": hdmap_metrics(hdmap) | {"lane_overlaps": len(hdmap_overlaps(hdmap))},
        }
        del skeleton, graph, hdmap  # their memory is free before the net is measured
        net_built.result()
        demand_written = sumo_tools.submit(demand)
        if after_net is not None:
            after_net()
        demand_written.result()
    return generation


def _measure_net(folder: Path, area_km2: float, into: dict) -> None:
    """The validation's net figures and the preview's drawing from one read of the net."""
    start = time.perf_counter()
    net = load_net(folder / NET_FILE)
    into["figures"] = loaded_net_metrics(net, area_km2)
    into["drawing"] = net_drawing(net)
    into["seconds"] = time.perf_counter() - start


def _rounded_timing(obj):
    if isinstance(obj, float):
        return round(obj, 4)
    if isinstance(obj, dict):
        return {k: _rounded_timing(v) for k, v in obj.items()}
    return obj


def _json(data) -> str:
    return json.dumps(data, indent=2, sort_keys=True) + "\n"
