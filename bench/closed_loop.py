"""Closed loop over many scenarios (issue 37): does SUMO's own driver finish every ego route
cleanly, is the naive controller caught, and what does the loop cost per step?

Usage: python bench/closed_loop.py [--scenarios 20] [--routes 3] [--length 5000]
           [--density 30] [--seed-base 950000] [--work DIR] [--esmini PATH] [--qc-python PY]

Scenarios are 2 km maps at ``--density``, styles in turn, seeds from ``--seed-base``, 500
vehicles over an hour, made with ``--ego-routes`` (not validated: ``make-scenario`` validates
the same maps elsewhere). On each route: ``sumo`` (the reference) and ``naive`` (ignores signals
and limits). Each route's OpenSCENARIO file is run headless by esmini (``--esmini``, default
``../shared/tools/esmini/esmini`` where it exists: did the ego reach the route's end?) and
checked by ASAM's OpenSCENARIO checker when ``--qc-python`` names a Python with PyPI
``asam-qc-openscenarioxml`` (its lxml pin clashes with ours: give it its own venv,
``python3 -m venv /work/oscqc && /work/oscqc/bin/pip install asam-qc-openscenarioxml``).
Prints one line per scenario and the totals.
"""

from __future__ import annotations

import argparse
import shutil
import subprocess
import tempfile
import time
from collections import Counter
from pathlib import Path

import numpy as np

import roadweaver_sumo as rw
from roadweaver_sumo.spec import STYLES

ESMINI = Path(__file__).resolve().parents[2] / "shared" / "tools" / "esmini" / "esmini"
QC_CONFIG = """<?xml version="1.0" encoding="UTF-8"?>
<Config><Param name="InputFile" value="{xosc}"/><CheckerBundle application="xoscBundle">
<Param name="resultFile" value="{result}"/></CheckerBundle></Config>"""


def esmini_arrives(esmini: Path, folder: Path, route: int, work: Path) -> bool:
    """Run ``ego_route_K.xosc`` headless in esmini: True if the ego reached the last
    waypoint (the story's ``arrived`` condition) with no error in the log."""
    work.mkdir(parents=True, exist_ok=True)
    for name in ("map.xodr", f"ego_route_{route}.xosc"):
        shutil.copy(folder / name, work / name)
    run = subprocess.run([str(esmini), "--headless", "--osc", f"ego_route_{route}.xosc",
                          "--fixed_timestep", "0.05", "--disable_stdout"], cwd=work,
                         capture_output=True, text=True, timeout=600, check=False)
    log = (work / "log.txt").read_text() if (work / "log.txt").exists() else ""
    errors = [ln for ln in log.splitlines() if "[error]" in ln and "geo reference" not in ln]
    return run.returncode == 0 and "arrived: true" in log and not errors


def asam_issues(qc_python: str, xosc: Path, work: Path) -> int:
    """Issues of every level ASAM's OpenSCENARIO checker bundle finds in ``xosc``."""
    from lxml import etree

    config, result = work / "qc_config.xml", work / "qc_result.xqar"
    config.write_text(QC_CONFIG.format(xosc=xosc.resolve(), result=result.resolve()))
    result.unlink(missing_ok=True)
    subprocess.run([qc_python, "-m", "qc_openscenario.main", "-c", str(config)], cwd=work,
                   capture_output=True, check=True)
    return sum(1 for _ in etree.parse(str(result)).getroot().iter("Issue"))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--scenarios", type=int, default=20)
    parser.add_argument("--routes", type=int, default=3)
    parser.add_argument("--length", type=float, default=5000.0)
    parser.add_argument("--density", type=float, default=30.0)
    parser.add_argument("--seed-base", type=int, default=950000)
    parser.add_argument("--work", type=Path)
    parser.add_argument("--esmini", type=Path, default=ESMINI if ESMINI.exists() else None)
    parser.add_argument("--qc-python")
    args = parser.parse_args()
    work = args.work or Path(tempfile.mkdtemp(prefix="closed-loop-"))
    totals = {name: Counter() for name in ("sumo", "naive", "esmini", "asam")}
    overhead, step = [], []
    for k in range(args.scenarios):
        spec = rw.ScenarioSpec(density=args.density, vehicles=500, seed=args.seed_base + k,
                               style=STYLES[k % len(STYLES)], ego_routes=args.routes,
                               ego_length=args.length)
        folder = work / spec.name
        began = time.perf_counter()
        rw.make_scenario(spec, folder, validate=False, force=True)
        line = []
        for name in ("sumo", "naive"):
            for route in range(args.routes):
                report = rw.closed_loop.run(folder, name, route=route)
                totals[name]["routes"] += 1
                totals[name]["completed"] += report["route_completion"] == 1.0
                totals[name]["clean"] += not report["infractions"]
                totals[name].update(report["infraction_counts"])
                totals[name]["score_sum_x1000"] += round(1000 * report["score"])
                overhead.append(report["loop_overhead_ms"])
                step.append(report["sumo_step_ms"])
                line.append(f"{name}{route} {report['score']:.2f}")
        for route in range(args.routes):
            if args.esmini:
                arrived = esmini_arrives(args.esmini, folder, route, folder / f"esmini{route}")
                totals["esmini"]["routes"] += 1
                totals["esmini"]["arrived"] += arrived
                line.append(f"esmini{route} {'end' if arrived else 'LOST'}")
            if args.qc_python:
                issues = asam_issues(args.qc_python, folder / f"ego_route_{route}.xosc", folder)
                totals["asam"]["files"] += 1
                totals["asam"]["issues"] += issues
        print(f"{spec.name:<40} {' '.join(line)} ({time.perf_counter() - began:.0f} s)",
              flush=True)
    esmini, asam = totals.pop("esmini"), totals.pop("asam")
    if esmini:
        print(f"esmini: {esmini['arrived']}/{esmini['routes']} OpenSCENARIO routes driven to "
              "their end")
    if asam:
        print(f"ASAM OpenSCENARIO checker: {asam['issues']} issues in {asam['files']} files")
    for name, t in totals.items():
        routes = t.pop("routes")
        score = t.pop("score_sum_x1000") / 1000 / routes
        print(f"{name}: {t.pop('completed')}/{routes} routes completed, {t.pop('clean')} "
              f"without infraction, mean score {score:.3f}; infractions {dict(t)}")
    print(f"loop overhead per step: mean {np.mean(overhead):.3f} ms, max {np.max(overhead):.3f}"
          f" ms (SUMO's own step: mean {np.mean(step):.3f} ms)")


if __name__ == "__main__":
    main()
