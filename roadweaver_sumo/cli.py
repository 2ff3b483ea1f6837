"""Command line: ``roadweaver-sumo make-scenario``, ``validate``, ``evaluate``, ``data prepare``,
``train``, ``make-suite``, ``check-suite`` and ``render``; ``drive`` and ``drive-suite`` are in
``cli_drive``.

Every argument is checked before any work starts, and ``--help`` states its range and default
(``cli_parser``).
Every run ends in one of four ways, never with a traceback: 0; 1 and one line on stderr for a
scenario or suite that fails its checks; 2 and one line ``roadweaver-sumo: error: ...`` for bad
input (or a failed external tool); 3 and one line naming a log file with the traceback, for a
bug. SIGTERM is handled like Ctrl-C: every child process is killed and nothing half-written
is left (``children``, ``staging``).
"""

from __future__ import annotations

import datetime
import importlib.util
import json
import os
import signal
import sys
import tempfile
import time
import traceback
import warnings
from pathlib import Path

from . import __version__, children
from .cli_drive import drive_command, drive_suite_command
from .cli_parser import EXIT_BAD_INPUT, EXIT_FAILED_CHECKS, EXIT_INTERNAL_ERROR, PROG, build_parser
from .errors import RoadweaverError
from .option_text import (
    parse_geo_origin,
    parse_junction_mix,
    parse_lanes,
    parse_size,
    parse_speeds,
    parse_vehicle_mix,
)
from .spec import DEFAULT_PERSONS, PRIOR_RANGES, ScenarioSpec
from .staging import remove_staged


def _one_line_warning(message, category, filename, lineno, file=None, line=None):
    print(f"{PROG}: warning: {message}", file=sys.stderr)


def main(argv: list[str] | None = None) -> int:
    warnings.showwarning = _one_line_warning
    try:
        with children.handle_termination(_stopped):
            return _run(build_parser().parse_args(argv))
    except RoadweaverError as exc:
        print(f"{PROG}: error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except KeyboardInterrupt:
        print(f"{PROG}: interrupted; nothing was left half-written", file=sys.stderr)
        return 130
    except Exception as exc:  # noqa: BLE001 - a bug: one line here, the traceback in a log
        log = _crash_log(argv)
        message = " ".join(str(exc).split())[:200]
        print(f"{PROG}: error: internal error ({type(exc).__name__}: {message}); "
              f"please report it with the traceback in {log}", file=sys.stderr)
        return EXIT_INTERNAL_ERROR


def _stopped(signum: int) -> None:
    """A SIGTERM or Ctrl-C, its children already killed: remove what was being written and
    say so. ``os.write``: the interrupted code may hold the lock of ``sys.stderr``."""
    remove_staged()
    what = "terminated" if signum == signal.SIGTERM else "interrupted"
    os.write(2, f"{PROG}: {what}; nothing was left half-written\n".encode())


def _run(args) -> int:
    commands = {"make-scenario": _make_scenario, "evaluate": _evaluate, "train": _train,
                "data": _data_prepare, "make-suite": _make_suite, "check-suite": _check_suite,
                "render": _render, "validate": _validate, "drive": drive_command,
                "drive-suite": drive_suite_command}  # fmt: skip
    return commands[args.command](args)


def _crash_log(argv: list[str] | None) -> Path:
    """Write the traceback being handled to a new log file (in the user's cache folder, else
    the temporary folder) and return its path."""
    stamp = datetime.datetime.now().strftime("%Y%m%d-%H%M%S")
    text = (f"{PROG} {__version__}, Python {sys.version.split()[0]}\n"
            f"arguments: {sys.argv[1:] if argv is None else argv}\n\n{traceback.format_exc()}")
    cache = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / PROG
    for folder in (cache, Path(tempfile.gettempdir())):
        path = folder / f"crash-{stamp}-{os.getpid()}.log"
        try:
            folder.mkdir(parents=True, exist_ok=True)
            path.write_text(text, encoding="utf-8")
            return path
        except OSError:
            continue
    return Path("(no writable folder for the log)")


def _rule_and_demand_fields(args) -> dict:
    """The spec fields of the options a scenario and every scenario of a suite share
    (``cli_parser._add_rule_and_demand_options``)."""
    return {"rules": args.rules, "one_way_share": args.one_way_share,
            "sidewalks": args.sidewalks, "bus_lines": args.bus_lines,
            "persons": args.persons if args.persons is not None
            else DEFAULT_PERSONS if args.sidewalks else 0,
            "vehicle_mix": parse_vehicle_mix(args.vehicle_mix), "departures": args.departures,
            "fringe_factor": args.fringe_factor, "roundabouts": args.roundabouts,
            "speeds": parse_speeds(args.speed) if args.speed is not None else {},
            "junction_mix": parse_junction_mix(args.junction_mix)
            if args.junction_mix is not None else {},
            "lanes": parse_lanes(args.lanes) if args.lanes is not None else {}}


def _make_scenario(args) -> int:
    width, height = parse_size(args.size)
    if args.density is None and args.like is None:
        raise RoadweaverError("make-scenario needs --density (road nodes per km²), or --like "
                              "FILE to take that network's")
    log = (lambda msg: None) if args.json else (lambda msg: print(f"  {msg}", file=sys.stderr))
    like = None
    if args.like is not None:
        from .like import measure_city

        like = measure_city(args.like)
        where = f"median of {like['tiles']} 2 km tiles" if like["tiles"] else "measured whole"
        log(f"like {args.like}: {like['density']:g} road nodes/km² ({where})")
    spec = ScenarioSpec(
        density=args.density if args.density is not None else like["density"],
        vehicles=args.vehicles if args.vehicles is not None else
        max(1, round(args.insertion_rate * args.duration / 3600.0)),
        width=width,
        height=height,
        seed=args.seed,
        style=args.style,
        skeleton=args.skeleton,
        boundary=args.boundary,
        **_rule_and_demand_fields(args),
        geo_origin=parse_geo_origin(args.geo_origin),
        duration=args.duration,
        like=like,
        ego_routes=args.ego_routes,
        ego_length=args.ego_length,
        **{name: getattr(args, name) for name in PRIOR_RANGES},
    )
    out = args.out if args.out is not None else Path("scenarios") / spec.name
    from .pipeline import make_scenario

    result = make_scenario(spec, out, force=args.force, validate=not args.no_validate, log=log)
    return _finish(result.out_dir, result.report, args.json, "wrote")


def _data_prepare(args) -> int:
    from .data.prepare import prepare_dataset
    from .staging import staged_folder

    for path in args.osm:
        if not path.is_file():
            raise RoadweaverError(f"OSM file {path} not found")
    if args.size % 8:
        raise RoadweaverError(f"--size must be a multiple of 8 cells, got {args.size}")
    with staged_folder(args.out, args.force) as tmp:
        manifest = prepare_dataset(args.osm, tmp, tile_m=args.tile, size=args.size,
                                   seed=args.seed, log=lambda msg: print(f"  {msg}", file=sys.stderr))
    print(f"wrote {args.out}: {manifest['tiles']} tiles")
    return 0


def _evaluate(args) -> int:
    from .validate.evaluate import evaluate_net, summary_lines

    result = evaluate_net(args.net, args.area_km2)
    if args.json:
        print(json.dumps(result, indent=2, sort_keys=True))
    else:
        print("\n".join(summary_lines(result)))
    return 0


def _validate(args) -> int:
    folder: Path = args.dir
    if not (folder / "scenario.sumocfg").is_file():
        raise RoadweaverError(f"{folder} is not a scenario folder (no scenario.sumocfg)")
    previous = _read_report(folder)  # a damaged report fails before the validation runs
    from .staging import scratch_beside
    from .validate.report import validate_scenario, write_report

    with scratch_beside(folder):
        report, _ = validate_scenario(folder)
    if previous is not None and "generation" in previous:
        report["generation"] = previous["generation"]
    write_report(folder, report)
    return _finish(folder, _read_report(folder), args.json, "validated")


def _read_report(folder: Path) -> dict | None:
    """``folder/report.json`` as a dict, None if there is none; a one-line error if it is
    damaged."""
    path = folder / "report.json"
    if not path.exists():
        return None
    try:
        report = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise RoadweaverError(f"cannot read {path} ({exc}); delete it to validate afresh") from None
    if not isinstance(report, dict):
        raise RoadweaverError(f"{path} is not a report (not a JSON object); delete it to "
                              "validate afresh")
    return report


def _finish(folder: Path, report: dict | None, as_json: bool, verb: str) -> int:
    from .validate.report import check_thresholds, summary_lines

    if report is None or report.get("validated") is False:
        print(f"wrote {folder} (not validated)")
        return 0
    if as_json:
        print(json.dumps(report, indent=2, sort_keys=True))
    else:
        print(f"{verb} {folder}")
        for line in summary_lines(report):
            print(f"  {line}")
    failures = check_thresholds(report)
    if failures:
        print(f"{PROG}: error: scenario fails {len(failures)} check(s): " + "; ".join(failures),
              file=sys.stderr)
        return EXIT_FAILED_CHECKS
    return 0


def _make_suite(args) -> int:
    from .suite import MANIFEST_FILE, Progress, SuiteSpec, make_suite
    from .suite.coverage import parse_min_coverage
    from .suite.grid import parse_densities, parse_seeds, parse_styles

    width, height = parse_size(args.size)
    minimum = parse_min_coverage(args.min_coverage) if args.min_coverage is not None else {}
    suite = SuiteSpec(densities=parse_densities(args.densities), styles=parse_styles(args.styles),
                      seeds=parse_seeds(args.seeds), width=width, height=height,
                      vehicles=args.vehicles, duration=args.duration, skeleton=args.skeleton,
                      boundary=args.boundary, **_rule_and_demand_fields(args),
                      ego_routes=args.ego_routes, ego_length=args.ego_length,
                      min_coverage=minimum)  # fmt: skip
    total = len(suite.scenarios())
    progress = Progress(total, enabled=not (args.quiet or args.json))
    start = time.monotonic()
    result = make_suite(suite, args.out, force=args.force, engine=args.engine,
                        workers=args.workers, address=args.address, progress=progress)  # fmt: skip
    wall, failed = time.monotonic() - start, result.failed
    if args.json:
        print(json.dumps({"out": str(args.out), "manifest": str(args.out / MANIFEST_FILE),
                          "scenarios": total, "passed": total - len(failed), "failed": failed,
                          "wall_s": round(wall, 1)}, indent=2, sort_keys=True))  # fmt: skip
    else:
        print(f"wrote {args.out}: {total - len(failed)} of {total} scenarios pass "
              f"({wall:.0f} s); manifest {args.out / MANIFEST_FILE}")  # fmt: skip
    if failed:
        name, reasons = next(iter(failed.items()))
        print(f"{PROG}: error: {len(failed)} of {total} scenarios fail, first {name}: "
              f"{reasons[0] if reasons else 'failed'}", file=sys.stderr)  # fmt: skip
        return EXIT_FAILED_CHECKS
    return 0


def _check_suite(args) -> int:
    from .suite import Progress, check_suite, environment_note, read_manifest
    from .suite.engines import check_workers

    check_workers(args.workers)
    _, manifest = read_manifest(args.dir)  # a broken manifest fails before any work
    progress = Progress(len(manifest["scenarios"]), enabled=not (args.quiet or args.json))
    noise: dict[str, list[str]] = {}
    problems = check_suite(args.dir, regenerate=not args.no_regenerate, workers=args.workers,
                           progress=progress, notes=noise)  # fmt: skip
    drifted = {name: found for name, found in problems.items() if found}
    note = environment_note(args.dir) if drifted else None
    checked = len(manifest["scenarios"])
    if args.json:
        print(json.dumps({"suite": str(args.dir), "checked": checked, "passed": not drifted,
                          "regenerated": not args.no_regenerate, "drift": drifted,
                          "noise": noise, "note": note}, indent=2, sort_keys=True))  # fmt: skip
    else:
        for name, found in drifted.items():
            for problem in found:
                print(f"{name}: {problem}")
        for name, found in noise.items():
            for line in found:
                print(f"{name}: note: {line}")
        verdict = f"{len(drifted)} drifted" if drifted else "all match the manifest"
        print(f"checked {checked} scenarios of {args.dir}: {verdict}")
        if note:
            print(f"  note: {note}")
    if drifted:
        name, found = next(iter(drifted.items()))
        print(f"{PROG}: error: {args.dir} drifted from its manifest, first {name}: {found[0]}",
              file=sys.stderr)  # fmt: skip
        return EXIT_FAILED_CHECKS
    return 0


def _render(args) -> int:
    from .render import render_preview

    for folder in args.dirs:
        if not folder.is_dir():
            raise RoadweaverError(f"{folder} is not a folder")
        _read_report(folder)
    for folder in args.dirs:
        print(f"wrote {render_preview(folder)}")
    return 0

def _check_train_paths(args) -> None:
    """Every path of a ``train`` command, before the first step: a training run is long, and
    its checkpoint is written only at its end."""
    out: Path = args.out
    if out.is_dir():
        raise RoadweaverError(f"--out {out} is a folder; name the checkpoint file to write")
    if out.exists() and not args.force:
        raise RoadweaverError(f"{out} exists; pass --force to replace it")
    if not out.parent.is_dir():
        raise RoadweaverError(f"--out {out}: folder {out.parent} does not exist")
    manifest = args.data / "manifest.json"
    if not manifest.is_file():
        raise RoadweaverError(f"{args.data} is not a prepared dataset (no manifest.json)")
    try:
        json.loads(manifest.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise RoadweaverError(f"cannot read {manifest} ({exc})") from None
    for option in ("vqvae", "teacher"):
        path = getattr(args, option, None)
        if path is not None and not path.is_file():
            raise RoadweaverError(f"--{option} {path}: no such checkpoint file")


def _train(args) -> int:
    from dataclasses import replace

    if importlib.util.find_spec("torch") is None:  # first: no other answer helps without it
        raise RoadweaverError("training needs torch: pip install 'roadweaver-sumo[train]'")
    _check_train_paths(args)
    from .generative import settings as defaults
    from .generative import training

    base = {"vqvae": defaults.VQVAE_SETTINGS, "maskgit": defaults.MASKGIT_SETTINGS,
            "distil": defaults.DISTIL_SETTINGS}[args.model]
    settings = replace(base, steps=args.steps, batch=args.batch, lr=args.lr, seed=args.seed)
    log = (lambda msg: None) if args.quiet else (lambda msg: print(f"  {msg}", file=sys.stderr))
    if args.model == "vqvae":
        meta = training.train_vqvae(args.data, args.out, settings, defaults.VQVAE_CONFIG, log=log)
        print(f"wrote {args.out}: held-out road IoU {meta['heldout']['road_iou']:.3f}, "
              f"{meta['seconds'] / 60:.1f} min")
    elif args.model == "maskgit":
        meta = training.train_maskgit(args.data, args.vqvae, args.out, settings,
                                      defaults.MASKGIT_CONFIG, log=log)
        print(f"wrote {args.out}: held-out loss {meta['history'][-1]['heldout_loss']:.3f}, "
              f"{meta['seconds'] / 60:.1f} min")
    else:
        meta = training.distil_guidance(args.data, args.vqvae, args.teacher, args.out, settings,
                                        log=log)
        run = meta["distillation"]
        print(f"wrote {args.out}: held-out cross-entropy to the guided teacher "
              f"{run['history'][0]['heldout_loss']:.3f} -> {run['history'][-1]['heldout_loss']:.3f}"
              f", {run['seconds'] / 60:.1f} min")
    return 0


if __name__ == "__main__":
    sys.exit(main())
