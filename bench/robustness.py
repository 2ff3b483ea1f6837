"""Robustness sweep (issue 5): random specs must give a valid scenario or a clear refusal.

Usage: python bench/robustness.py [--count 200] [--seed 0] [--skeleton procedural] [--boundary ring]
                                  [--specs A-B] [--json bench/results/robustness_<skeleton>.json]

Each spec (sizes 0.5-5 km, squares and rectangles; densities 5-120 log-uniform; every style;
random seeds) is built to its SUMO net and demand (no libsumo run) and measured on
``map.net.xml``. Verdicts: ``valid`` (LCC 100 %, no crossing without junction, no sharp
bend, lane-level reachability >= 99.5 %), ``refused`` (the spec itself is impossible: a
one-line RoadweaverError saying why), ``failed`` (a threshold missed), ``error`` (a
RoadweaverError after the spec was accepted) or ``crash`` (any other exception). Prints the
counts and every non-valid spec.
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
import traceback
from pathlib import Path

import numpy as np

from roadweaver_sumo.errors import RoadweaverError
from roadweaver_sumo.pipeline import build_scenario_files
from roadweaver_sumo.spec import STYLES, ScenarioSpec
from roadweaver_sumo.validate.net_metrics import net_metrics

VEHICLES = 100


def random_specs(count: int, seed: int) -> list[dict]:
    """``count`` spec dicts drawn from one seeded generator: half squares, half rectangles."""
    rng = np.random.default_rng(seed)
    specs = []
    for k in range(count):
        width = float(round(rng.uniform(500, 5000), -1))
        height = width if k % 2 == 0 else float(round(rng.uniform(500, 5000), -1))
        density = float(round(np.exp(rng.uniform(np.log(5), np.log(120))), 1))
        specs.append({"width": width, "height": height, "density": density,
                      "style": STYLES[k % len(STYLES)], "seed": int(rng.integers(0, 10_000))})
    return specs


def check(spec_args: dict, skeleton: str, boundary: str = "ring") -> dict:
    """Build one spec and judge it; never raises."""
    start = time.perf_counter()
    try:
        spec = ScenarioSpec(vehicles=VEHICLES, skeleton=skeleton, boundary=boundary, **spec_args)
    except RoadweaverError as exc:
        return {"verdict": "refused", "reason": str(exc), "seconds": 0.0}
    try:
        with tempfile.TemporaryDirectory() as tmp:
            build_scenario_files(spec, Path(tmp), {}, lambda msg: None)
            net = net_metrics(Path(tmp) / "map.net.xml", spec.area_km2)
    except RoadweaverError as exc:
        return {"verdict": "error", "reason": str(exc), "seconds": time.perf_counter() - start}
    except Exception as exc:  # noqa: BLE001 - a crash is what we are looking for
        tb = traceback.format_exception(exc)[-3:]
        return {"verdict": "crash", "reason": f"{type(exc).__name__}: {exc}",
                "traceback": "".join(tb), "seconds": time.perf_counter() - start}
    problems = []
    if net["lcc_ratio"] < 1.0:
        problems.append(f"LCC {net['lcc_ratio']:.4f}")
    if net["crossings_without_junction"] > 0:
        problems.append(f"{net['crossings_without_junction']} crossings without junction")
    if net["lane_reachability"] < 0.995:
        problems.append(f"lane reachability {net['lane_reachability']:.4f}")
    if net["sharp_bends"] > 0:
        problems.append(f"{net['sharp_bends']} sharp bends")
    figures = {k: net[k] for k in ("road_nodes", "density", "lcc_ratio", "lane_reachability",
                                   "crossings_without_junction", "sharp_bends")}
    return {"verdict": "failed" if problems else "valid", "reason": "; ".join(problems),
            "net": figures, "seconds": time.perf_counter() - start}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--count", type=int, default=200)
    ap.add_argument("--seed", type=int, default=0, help="seed of the spec generator")
    ap.add_argument("--skeleton", default="procedural")
    ap.add_argument("--boundary", default="open", help="open or ring")
    ap.add_argument("--specs", help="only specs A-B of the drawn list (to split a sweep over "
                    "processes; the specs are the same as in a whole run)")
    ap.add_argument("--json", type=Path)
    args = ap.parse_args()
    out = args.json or Path(f"bench/results/robustness_{args.skeleton}.json")
    first, last = 0, args.count - 1
    if args.specs:
        first, last = (int(x) for x in args.specs.split("-"))
    results = []
    for k, spec_args in enumerate(random_specs(args.count, args.seed)):
        if not first <= k <= last:
            continue
        result = {"spec": spec_args, **check(spec_args, args.skeleton, args.boundary)}
        results.append(result)
        print(f"{k:3d} {result['verdict']:8s} {result['seconds']:6.1f} s  {spec_args}"
              + (f"  {result['reason']}" if result["reason"] else ""), flush=True)
    counts = {v: sum(r["verdict"] == v for r in results)
              for v in ("valid", "refused", "failed", "error", "crash")}
    print(f"\n{len(results)} specs, skeleton {args.skeleton}: " +
          ", ".join(f"{n} {v}" for v, n in counts.items()))
    for r in results:
        if r["verdict"] not in ("valid", "refused"):
            print(f"  {r['verdict']}: {r['spec']}: {r['reason']}")
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps({"skeleton": args.skeleton, "count": args.count, "seed": args.seed,
                               "specs": [first, last], "counts": counts, "results": results},
                              indent=1) + "\n")


if __name__ == "__main__":
    main()
