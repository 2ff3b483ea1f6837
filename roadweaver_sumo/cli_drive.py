"""The closed-loop commands (issue 37): ``drive`` one ego route and ``drive-suite`` every route
of a suite, against a baseline score table if given."""

from __future__ import annotations

import json
import sys

from .cli_parser import EXIT_FAILED_CHECKS, PROG
from .errors import RoadweaverError


def drive_command(args) -> int:
    """``drive DIR``: one ego route, one controller, the drive report."""
    from .closed_loop import run

    if not (args.dir / "scenario.sumocfg").is_file():
        raise RoadweaverError(f"{args.dir} is not a scenario folder (no scenario.sumocfg)")
    controller = args.controller or (None if args.remote_port else "sumo")
    report = run(args.dir, controller, route=args.route, remote_port=args.remote_port)
    out = args.out or args.dir / f"drive_report_{args.route}.json"
    out.write_text(json.dumps(report, indent=2, sort_keys=True) + "\n", encoding="utf-8")
    if args.json:
        print(json.dumps(report, indent=2, sort_keys=True))
        return 0
    kinds = ", ".join(f"{k} x{n}" for k, n in report["infraction_counts"].items()) or "none"
    print(f"{report['route']} ({report['route_length_m']:g} m), controller "
          f"{report['controller']}: score {report['score']:.3f} = completion "
          f"{report['route_completion']:.3f} x penalty {report['penalty']:.3f}; infractions: "
          f"{kinds}; wrote {out}")
    return 0


def drive_suite_command(args) -> int:
    """``drive-suite SUITE``: every ego route of a suite, a score table, its changes."""
    from .closed_loop.suite_drive import (
        SCORES_FILE,
        compare_scores,
        drive_suite,
        read_scores,
        table_lines,
    )
    from .suite import Progress, read_manifest

    suite, manifest = read_manifest(args.dir)  # a broken suite fails before any driving
    out = args.out or args.dir / SCORES_FILE
    if out.exists() and not args.force:
        raise RoadweaverError(f"{out} exists; use --force to replace it, or --out")
    baseline = read_scores(args.baseline) if args.baseline else None
    progress = Progress(len(manifest["scenarios"]) * suite.ego_routes, enabled=not args.json)
    table = drive_suite(args.dir, args.controller, progress=progress)
    out.write_text(json.dumps(table, indent=2, sort_keys=True) + "\n", encoding="utf-8")
    changes, regressed = compare_scores(baseline, table) if baseline else ([], False)
    if args.json:
        print(json.dumps(table | {"changes": changes, "regressed": regressed}, indent=2,
                         sort_keys=True))
    else:
        print("\n".join(table_lines(table)))
        if baseline:
            print(f"against {args.baseline}: {len(changes)} routes changed")
            for line in changes:
                print(f"  {line}")
        print(f"wrote {out}")
    if regressed:
        print(f"{PROG}: error: a route scores lower or has a new infraction kind than in "
              f"{args.baseline}", file=sys.stderr)
        return EXIT_FAILED_CHECKS
    return 0
