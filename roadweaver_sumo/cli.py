"""Command line: ``roadweaver-sumo make-scenario`` and ``roadweaver-sumo validate``.

Every user error ends in one line on stderr, ``roadweaver-sumo: error: ...``, and a non-zero exit
(2 for bad input, 1 for a scenario that fails its thresholds); never a traceback.
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import sys
import time
import warnings
from pathlib import Path

from . import __version__
from .allocator import keep_freed_memory
from .errors import RoadweaverError
from .spec import SKELETONS, STYLES, ScenarioSpec, parse_size

PROG = "roadweaver-sumo"
EXIT_FAILED_CHECKS = 1
EXIT_BAD_INPUT = 2


class _Parser(argparse.ArgumentParser):
    """argparse that reports a usage error in one line instead of usage text plus error."""

    def error(self, message: str):
        raise RoadweaverError(message)


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(prog=PROG, description="Lane-level road networks as SUMO scenarios.")
    parser.add_argument("--version", action="version", version=f"{PROG} {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)

    make = sub.add_parser("make-scenario", help="generate a map and a validated SUMO scenario")
    make.add_argument("--density", type=float, required=True, help="road nodes per km²")
    make.add_argument("--vehicles", type=int, required=True, help="number of vehicles")
    make.add_argument("--size", default="2000", help="map size in metres: 2000 or 3000x2000")
    make.add_argument("--seed", type=int, default=0)
    make.add_argument("--style", default="mixed", help=f"one of {', '.join(STYLES)}")
    make.add_argument("--skeleton", default="learned", help=f"one of {', '.join(SKELETONS)}")
    make.add_argument("--duration", type=float, default=3600.0, help="demand horizon, seconds")
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
    prep.add_argument("--tile", type=float, default=2000.0, help="tile side, metres")
    prep.add_argument("--size", type=int, default=128, help="raster cells per tile side")
    prep.add_argument("--seed", type=int, default=0)
    prep.add_argument("--force", action="store_true", help="replace an existing dataset folder")

    val = sub.add_parser("validate", help="re-run the validation of a scenario folder")
    val.add_argument("dir", type=Path)
    val.add_argument("--json", action="store_true", help="print the report as JSON")
    _add_suite_commands(sub, make)
    ev = sub.add_parser("evaluate", help="our metrics for any SUMO network")
    ev.add_argument("net", type=Path, metavar="NET.net.xml")
    ev.add_argument("--area-km2", type=float, help="map area (default: the net's convBoundary)")
    ev.add_argument("--json", action="store_true", help="print the metrics as JSON")
    _add_train_commands(sub)
    return parser


def _add_suite_commands(sub, make: argparse.ArgumentParser) -> None:
    """``make-suite``, ``check-suite`` and ``render`` (scenario suites and previews)."""
    suite = sub.add_parser("make-suite", help="build a grid of scenarios with a manifest")
    suite.add_argument("--densities", required=True, help="road nodes per km², e.g. 10,20,30")
    suite.add_argument("--styles", default="mixed", help=f"comma-separated: {', '.join(STYLES)}")
    suite.add_argument("--seeds", default="0", help="seeds and ranges, e.g. 0-9 or 0,3,7")
    suite.add_argument("--size", default="2000", help="map size in metres: 2000 or 3000x2000")
    suite.add_argument("--vehicles", type=int, default=500, help="vehicles per scenario")
    suite.add_argument("--duration", type=float, default=3600.0, help="demand horizon, seconds")
    suite.add_argument("--skeleton", default=make.get_default("skeleton"),
                       help=f"one of {', '.join(SKELETONS)}")  # same default as make-scenario
    suite.add_argument("--out", type=Path, required=True, help="suite folder")
    suite.add_argument("--force", action="store_true", help="replace an existing suite folder")
    suite.add_argument("--engine", default="local", help="local (process pool) or ray")
    suite.add_argument("--address", help="Ray cluster address (with --engine ray)")
    suite.add_argument("--workers", type=int, help="parallel scenarios (default: CPU count)")
    suite.add_argument("--quiet", action="store_true", help="no progress lines on stderr")
    suite.add_argument("--json", action="store_true", help="print the summary as JSON")

    check = sub.add_parser("check-suite", help="check a suite against its manifest")
    check.add_argument("dir", type=Path)
    check.add_argument("--no-regenerate", action="store_true",
                       help="only re-validate; do not rebuild every scenario to compare hashes")
    check.add_argument("--workers", type=int, help="parallel scenarios (default: CPU count)")
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
        args = build_parser().parse_args(argv)
        if args.command == "make-scenario":
            return _make_scenario(args)
        if args.command == "evaluate":
            return _evaluate(args)
        if args.command == "train":
            return _train(args)
        if args.command == "data":
            return _data_prepare(args)
        if args.command in ("make-suite", "check-suite", "render"):
            return {"make-suite": _make_suite, "check-suite": _check_suite,
                    "render": _render}[args.command](args)  # fmt: skip
        return _validate(args)
    except RoadweaverError as exc:
        print(f"{PROG}: error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except KeyboardInterrupt:
        print(f"{PROG}: interrupted; nothing was left half-written", file=sys.stderr)
        return 130


def _make_scenario(args) -> int:
    from .pipeline import make_scenario

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
    log = (lambda msg: None) if args.json else (lambda msg: print(f"  {msg}", file=sys.stderr))
    result = make_scenario(spec, out, force=args.force, validate=not args.no_validate, log=log)
    return _finish(result.out_dir, result.report, args.json, "wrote")


def _data_prepare(args) -> int:
    from .data.prepare import prepare_dataset
    from .staging import staged_folder

    for path in args.osm:
        if not path.is_file():
            raise RoadweaverError(f"OSM file {path} not found")
    if args.tile <= 0 or args.size < 8:
        raise RoadweaverError("--tile must be > 0 metres and --size at least 8 cells")
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
    report, _ = validate_scenario(folder)
    old = folder / "report.json"
    if old.is_file():
        previous = json.loads(old.read_text(encoding="utf-8"))
        if "generation" in previous:
            report["generation"] = previous["generation"]
    write_report(folder, report)
    report = json.loads(old.read_text(encoding="utf-8"))
    return _finish(folder, report, args.json, "validated")


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
        p.add_argument("--steps", type=int, default=defaults.steps)
        p.add_argument("--batch", type=int, default=defaults.batch)
        p.add_argument("--lr", type=float, default=defaults.lr)
        p.add_argument("--seed", type=int, default=defaults.seed)
        p.add_argument("--force", action="store_true", help="replace an existing checkpoint")
        p.add_argument("--quiet", action="store_true", help="no progress lines on stderr")


def _train(args) -> int:
    from dataclasses import replace

    if importlib.util.find_spec("torch") is None:
        raise RoadweaverError("training needs torch: pip install 'roadweaver-sumo[train]'")
    from .generative import settings as defaults
    from .generative import training

    if args.out.exists() and not args.force:
        raise RoadweaverError(f"{args.out} exists; pass --force to replace it")
    if not (args.data / "manifest.json").is_file():
        raise RoadweaverError(f"{args.data} is not a prepared dataset (no manifest.json)")
    if args.steps < 1 or args.batch < 1 or not args.lr > 0 or args.seed < 0:
        raise RoadweaverError("--steps and --batch must be >= 1, --lr > 0 and --seed >= 0")
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
