"""Closed loop over many scenarios (issue 37): does SUMO's own driver finish every ego route
cleanly, is the naive controller caught, and what does the loop cost per step?

Usage: python bench/closed_loop.py [--scenarios 20] [--routes 3] [--length 5000]
           [--density 30] [--seed-base 950000] [--work DIR]

Scenarios are 2 km maps at ``--density``, styles in turn, seeds from ``--seed-base``, 500
vehicles over an hour, made with ``--ego-routes`` (not validated: ``make-scenario`` validates
the same maps elsewhere). On each route: ``sumo`` (the reference) and ``naive`` (ignores signals
and limits). Prints one line per scenario and the totals.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from collections import Counter
from pathlib import Path

import numpy as np

import roadweaver_sumo as rw
from roadweaver_sumo.spec import STYLES


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--scenarios", type=int, default=20)
    parser.add_argument("--routes", type=int, default=3)
    parser.add_argument("--length", type=float, default=5000.0)
    parser.add_argument("--density", type=float, default=30.0)
    parser.add_argument("--seed-base", type=int, default=950000)
    parser.add_argument("--work", type=Path)
    args = parser.parse_args()
    work = args.work or Path(tempfile.mkdtemp(prefix="closed-loop-"))
    totals = {name: Counter() for name in ("sumo", "naive")}
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
        print(f"{spec.name:<40} {' '.join(line)} ({time.perf_counter() - began:.0f} s)",
              flush=True)
    for name, t in totals.items():
        routes = t.pop("routes")
        score = t.pop("score_sum_x1000") / 1000 / routes
        print(f"{name}: {t.pop('completed')}/{routes} routes completed, {t.pop('clean')} "
              f"without infraction, mean score {score:.3f}; infractions {dict(t)}")
    print(f"loop overhead per step: mean {np.mean(overhead):.3f} ms, max {np.max(overhead):.3f}"
          f" ms (SUMO's own step: mean {np.mean(step):.3f} ms)")


if __name__ == "__main__":
    main()
