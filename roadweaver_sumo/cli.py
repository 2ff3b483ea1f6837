"""Command line: ``roadweaver-sumo make-scenario``, ``validate``, ``evaluate``, ``data prepare``,
``train``, ``make-suite``, ``check-suite`` and ``render``.

Every argument is checked before any work starts, and ``--help`` states its range and default.
Every run ends in one of four ways, never with a traceback: 0; 1 and one line on stderr for a
scenario or suite that fails its checks; 2 and one line ``roadweaver-sumo: error: ...`` for bad
input (or a failed external tool); 3 and one line naming a log file with the traceback, for a
bug. SIGTERM is handled like Ctrl-C: every child process is killed and nothing half-written
is left (``children``, ``staging``).
"""

from __future__ import annotations

import argparse
import datetime
import importlib.util
import json
import math
import os
import signal
import sys
import tempfile
import time
import traceback
import warnings
from pathlib import Path

from . import __version__, children
from .allocator import keep_freed_memory
from .errors import RoadweaverError
from .spec import (
    MAX_DENSITY,
    MAX_DURATION_S,
    MAX_SEED,
    MAX_SIDE_M,
    MAX_VEHICLES,
    MIN_DURATION_S,
    MIN_ROAD_NODES,
    MIN_SIDE_M,
    SKELETONS,
    STYLES,
    ScenarioSpec,
    parse_size,
)

PROG = "roadweaver-sumo"
EXIT_FAILED_CHECKS = 1
EXIT_BAD_INPUT = 2
EXIT_INTERNAL_ERROR = 3
# data prepare: a tile is cut from one town, and its raster is what the models train on
MIN_TILE_M, MAX_TILE_M = 200.0, 20_000.0
MIN_CELLS, MAX_CELLS = 8, 512  # the VQ-VAE downsamples by 8
# train
MAX_STEPS, MAX_BATCH, MAX_LR = 10_000_000, 4096, 1.0
MAX_WORKERS = 256  # suite.engines.MAX_WORKERS, stated here for --help


class _Parser(argparse.ArgumentParser):
    """argparse that reports a usage error in one line instead of usage text plus error, and
    shows defaults in ``--help``."""

    def __init__(self, *args, **kwargs) -> None:
        kwargs.setdefault("formatter_class", _HelpFormatter)
        super().__init__(*args, **kwargs)

    def error(self, message: str):
        raise RoadweaverError(message)


class _HelpFormatter(argparse.ArgumentDefaultsHelpFormatter):
    """``(default: X)`` after every option with a default worth stating (not None or False)."""

    def _get_help_string(self, action: argparse.Action) -> str:
        if action.default is None or action.default is False or not action.help:
            return action.help or ""
        return super()._get_help_string(action)


def _number(kind: type, low: float, high: float, *, above: bool = False):
    """An argparse type: a finite ``kind`` (int or float) from ``low`` (excluded with
    ``above``) to ``high``; anything else is a one-line error that states the range."""
    what = "a whole number" if kind is int else "a number"
    if math.isinf(high):
        span = f"{'>' if above else '>='} {low:g} and finite"
    else:
        span = f"> {low:g} and <= {high:g}" if above else f"{low:g}..{high:g}"

    def parse(text: str):
        try:
            value = kind(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not {what} ({span})") from None
        if not math.isfinite(value) or value < low or value > high or (above and value == low):
            raise argparse.ArgumentTypeError(f"must be {span}, got {text}")
        return value

    return parse


def _choices(names) -> str:
    return "{" + ",".join(names) + "}"


SEED = _number(int, 0, MAX_SEED)
SEED_HELP = f"random seed, 0..{MAX_SEED}"
SIZE_HELP = (f"map size in metres, 2000 or 3000x2000; each side {MIN_SIDE_M:g}..{MAX_SIDE_M:g}")
VEHICLES_HELP = f"vehicles, 1..{MAX_VEHICLES}"
DURATION_HELP = (f"demand horizon in seconds, {MIN_DURATION_S:g}..{MAX_DURATION_S:g} (a week)")


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(prog=PROG, description="Lane-level road networks as SUMO scenarios.")
    parser.add_argument("--version", action="version", version=f"{PROG} {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)

    make = sub.add_parser("make-scenario", help="generate a map and a validated SUMO scenario")
    make.add_argument("--density", type=float, required=True,
                      help=f"road nodes per km², > 0 and <= {MAX_DENSITY:g}; the map must hold "
                           f"at least {MIN_ROAD_NODES} road nodes")
    make.add_argument("--vehicles", type=int, required=True, help=VEHICLES_HELP)
    make.add_argument("--size", default="2000", help=SIZE_HELP)
    make.add_argument("--seed", type=int, default=0,
                      help=f"{SEED_HELP} (SUMO's tools take 32-bit seeds)")
    make.add_argument("--style", default="mixed", metavar=_choices(STYLES), help="road style")
    make.add_argument("--skeleton", default="learned", metavar=_choices(SKELETONS),
                      help="how the arterial roads are made")
    make.add_argument("--duration", type=float, default=3600.0, help=DURATION_HELP)
    make.add_argument("--out", type=Path, help="output folder (default ./scenarios/<name>)")
    make.add_argument("--force", action="store_true", help="replace an existing output folder")
    make.add_argument("--no-validate", action="store_true", help="skip the libsumo validation")
    make.add_argument("--json", action="store_true", help="print the report as JSON")

    data = sub.add_parser("data", help="training data for the learned skeleton")
    data_sub = data.add_subparsers(dest="data_command", required=True, parser_class=_Parser)
    prep = data_sub.add_parser("prepare", help="cut OSM files into road-field tiles")
    prep.add_argument("--osm", type=Path, nargs="+", required=True,
                      help=".osm, .osm.gz, .osm.bz2 or .osm.pbf files")
    prep.add_argument("--out", type=Path, required=True, help="dataset folder")
    prep.add_argument("--tile", type=_number(float, MIN_TILE_M, MAX_TILE_M), default=2000.0,
                      help=f"tile side in metres, {MIN_TILE_M:g}..{MAX_TILE_M:g}")
    prep.add_argument("--size", type=_number(int, MIN_CELLS, MAX_CELLS), default=128,
                      help=f"raster cells per tile side, {MIN_CELLS}..{MAX_CELLS}, a multiple "
                           "of 8")
    prep.add_argument("--seed", type=SEED, default=0, help=SEED_HELP)
    prep.add_argument("--force", action="store_true", help="replace an existing dataset folder")

    val = sub.add_parser("validate", help="re-run the validation of a scenario folder")
    val.add_argument("dir", type=Path)
    val.add_argument("--json", action="store_true", help="print the report as JSON")
    _add_suite_commands(sub, make)
    ev = sub.add_parser("evaluate", help="our metrics for any SUMO network")
    ev.add_argument("net", type=Path, metavar="NET.net.xml")
    ev.add_argument("--area-km2", type=_number(float, 0, math.inf, above=True),
                    help="map area in km², > 0 (default: the net's convBoundary)")
    ev.add_argument("--json", action="store_true", help="print the metrics as JSON")
    _add_train_commands(sub)
    return parser


def _add_suite_commands(sub, make: argparse.ArgumentParser) -> None:
    """``make-suite``, ``check-suite`` and ``render`` (scenario suites and previews)."""
    suite = sub.add_parser("make-suite", help="build a grid of scenarios with a manifest")
    suite.add_argument("--densities", required=True,
                       help=f"road nodes per km², each > 0 and <= {MAX_DENSITY:g}, e.g. 10,20,30")
    suite.add_argument("--styles", default="mixed",
                       help=f"comma-separated, from {_choices(STYLES)}")
    suite.add_argument("--seeds", default="0",
                       help=f"seeds and ranges, e.g. 0-9 or 0,3,7; each 0..{MAX_SEED}")
    suite.add_argument("--size", default="2000", help=SIZE_HELP)
    suite.add_argument("--vehicles", type=int, default=500, help=f"{VEHICLES_HELP} per scenario")
    suite.add_argument("--duration", type=float, default=3600.0, help=DURATION_HELP)
    suite.add_argument("--skeleton", default=make.get_default("skeleton"),
                       metavar=_choices(SKELETONS),
                       help="how the arterial roads are made")  # same default as make-scenario
    suite.add_argument("--out", type=Path, required=True, help="suite folder")
    suite.add_argument("--force", action="store_true", help="replace an existing suite folder")
    suite.add_argument("--engine", default="local", metavar="{local,ray}",
                       help="local (process pool) or ray")
    suite.add_argument("--address", help="Ray cluster address (with --engine ray)")
    suite.add_argument("--workers", type=int,
                       help=f"parallel scenarios, 1..{MAX_WORKERS} (default: CPU count)")
    suite.add_argument("--quiet", action="store_true", help="no progress lines on stderr")
    suite.add_argument("--json", action="store_true", help="print the summary as JSON")

    check = sub.add_parser("check-suite", help="check a suite against its manifest")
    check.add_argument("dir", type=Path)
    check.add_argument("--no-regenerate", action="store_true",
                       help="only re-validate; do not rebuild every scenario to compare hashes")
    check.add_argument("--workers", type=int,
                       help=f"parallel scenarios, 1..{MAX_WORKERS} (default: CPU count)")
    check.add_argument("--quiet", action="store_true", help="no progress lines on stderr")
    check.add_argument("--json", action="store_true", help="print the result as JSON")

    render = sub.add_parser("render", help="redraw preview.png of scenario folders")
    render.add_argument("dirs", type=Path, nargs="+", metavar="DIR")


def _one_line_warning(message, category, filename, lineno, file=None, line=None):
    print(f"{PROG}: warning: {message}", file=sys.stderr)


def main(argv: list[str] | None = None) -> int:
    warnings.showwarning = _one_line_warning
    keep_freed_memory()
    try:
        with children.handle_termination():
            return _run(build_parser().parse_args(argv))
    except RoadweaverError as exc:
        print(f"{PROG}: error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except children.Stopped as exc:
        what = "terminated" if exc.signum == signal.SIGTERM else "interrupted"
        print(f"{PROG}: {what}; nothing was left half-written", file=sys.stderr)
        return 128 + exc.signum
    except KeyboardInterrupt:
        print(f"{PROG}: interrupted; nothing was left half-written", file=sys.stderr)
        return 130
    except Exception as exc:  # noqa: BLE001 - a bug: one line here, the traceback in a log
        log = _crash_log(argv)
        message = " ".join(str(exc).split())[:200]
        print(f"{PROG}: error: internal error ({type(exc).__name__}: {message}); "
              f"please report it with the traceback in {log}", file=sys.stderr)
        return EXIT_INTERNAL_ERROR


def _run(args) -> int:
    commands = {"make-scenario": _make_scenario, "evaluate": _evaluate, "train": _train,
                "data": _data_prepare, "make-suite": _make_suite, "check-suite": _check_suite,
                "render": _render, "validate": _validate}  # fmt: skip
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


def _make_scenario(args) -> int:
    width, height = parse_size(args.size)
    spec = ScenarioSpec(
        density=args.density,
        vehicles=args.vehicles,
        width=width,
        height=height,
        seed=args.seed,
        style=args.style,
        skeleton=args.skeleton,
        duration=args.duration,
    )
    out = args.out if args.out is not None else Path("scenarios") / spec.name
    from .pipeline import make_scenario  # after the checks: its imports take a while

    log = (lambda msg: None) if args.json else (lambda msg: print(f"  {msg}", file=sys.stderr))
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
    from .validate.report import validate_scenario, write_report

    folder: Path = args.dir
    if not (folder / "scenario.sumocfg").is_file():
        raise RoadweaverError(f"{folder} is not a scenario folder (no scenario.sumocfg)")
    previous = _read_report(folder)  # a damaged report fails before the validation runs
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
    from .suite.grid import parse_densities, parse_seeds, parse_styles

    width, height = parse_size(args.size)
    suite = SuiteSpec(densities=parse_densities(args.densities), styles=parse_styles(args.styles),
                      seeds=parse_seeds(args.seeds), width=width, height=height,
                      vehicles=args.vehicles, duration=args.duration, skeleton=args.skeleton)  # fmt: skip
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
    problems = check_suite(args.dir, regenerate=not args.no_regenerate, workers=args.workers,
                           progress=progress)  # fmt: skip
    drifted = {name: found for name, found in problems.items() if found}
    note = environment_note(args.dir) if drifted else None
    checked = len(manifest["scenarios"])
    if args.json:
        print(json.dumps({"suite": str(args.dir), "checked": checked, "passed": not drifted,
                          "regenerated": not args.no_regenerate, "drift": drifted,
                          "note": note}, indent=2, sort_keys=True))  # fmt: skip
    else:
        for name, found in drifted.items():
            for problem in found:
                print(f"{name}: {problem}")
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


def _add_train_commands(sub) -> None:
    """``train vqvae``, ``train maskgit`` and ``train distil`` (the learned skeleton, paper
    §III-B; distil: the transformer's guidance, so sampling needs one pass per step)."""
    from .generative.settings import DISTIL_SETTINGS, MASKGIT_SETTINGS, VQVAE_SETTINGS

    train = sub.add_parser("train", help="train the learned skeleton's models")
    kinds = train.add_subparsers(dest="model", required=True, parser_class=_Parser)
    for name, defaults, what in (
            ("vqvae", VQVAE_SETTINGS, "train the VQ-VAE"),
            ("maskgit", MASKGIT_SETTINGS, "train the masked transformer"),
            ("distil", DISTIL_SETTINGS, "distil a trained transformer's guidance into a copy")):
        p = kinds.add_parser(name, help=f"{what} on a prepared dataset")
        p.add_argument("--data", type=Path, required=True, help="folder from 'data prepare'")
        if name != "vqvae":
            p.add_argument("--vqvae", type=Path, required=True, help="trained VQ-VAE checkpoint")
        if name == "distil":
            p.add_argument("--teacher", type=Path, required=True,
                           help="trained transformer checkpoint (from 'train maskgit')")
        p.add_argument("--out", type=Path, required=True, help="checkpoint file to write")
        p.add_argument("--steps", type=_number(int, 1, MAX_STEPS), default=defaults.steps,
                       help=f"training steps, 1..{MAX_STEPS}")
        p.add_argument("--batch", type=_number(int, 1, MAX_BATCH), default=defaults.batch,
                       help=f"tiles per step, 1..{MAX_BATCH}")
        p.add_argument("--lr", type=_number(float, 0, MAX_LR, above=True), default=defaults.lr,
                       help=f"learning rate, > 0 and <= {MAX_LR:g}")
        p.add_argument("--seed", type=SEED, default=defaults.seed, help=SEED_HELP)
        p.add_argument("--force", action="store_true", help="replace an existing checkpoint")
        p.add_argument("--quiet", action="store_true", help="no progress lines on stderr")


def _check_train_paths(args) -> None:
    """Every path of a ``train`` command, before the first step: a training run is long, and
    its checkpoint is written only at its end."""
    out: Path = args.out
    if out.is_dir():
        raise RoadweaverError(f"--out {out} is a folder; name the checkpoint file to write")
    if out.exists() and not args.force:
        raise RoadweaverError(f"{out} exists; pass --force to replace it")
    parent = out.parent if str(out.parent) else Path(".")
    if not parent.is_dir():
        raise RoadweaverError(f"--out {out}: folder {parent} does not exist")
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

    _check_train_paths(args)
    if importlib.util.find_spec("torch") is None:
        raise RoadweaverError("training needs torch: pip install 'roadweaver-sumo[train]'")
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
