"""Per-stage wall times of make-scenario (without validation) at density 30 for growing maps.

Usage: python bench/stage_times.py [--sizes 2000,4000,8000] [--repeats 5] [--vehicles 500]
Prints a table (median over repeats, seeds 0..repeats-1) and per-km² ratios; writes JSON.
"""

from __future__ import annotations

import argparse
import json
import statistics
import tempfile
from pathlib import Path

from roadweaver_sumo.pipeline import build_scenario_files
from roadweaver_sumo.spec import ScenarioSpec

STAGES = ("skeleton", "expansion", "hdmap", "export", "netconvert", "demand")
GENERATION = ("skeleton", "expansion", "hdmap", "export")


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--sizes", default="2000,4000,8000")
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--density", type=float, default=30.0)
    ap.add_argument("--vehicles", type=int, default=500)
    ap.add_argument("--json", type=Path, default=Path("bench/results/stage_times.json"))
    args = ap.parse_args()
    results = {}
    header = "size_m  " + " ".join(f"{s:>10s}" for s in STAGES) + "  generation  total  per_km2"
    print(header)
    for size in [float(s) for s in args.sizes.split(",")]:
        runs = []
        for seed in range(args.repeats):
            spec = ScenarioSpec(density=args.density, vehicles=args.vehicles, seed=seed,
                                width=size, height=size)
            stages: dict[str, float] = {}
            with tempfile.TemporaryDirectory() as tmp:
                build_scenario_files(spec, Path(tmp), stages, lambda msg: None)
            runs.append(stages)
        med = {s: statistics.median(r[s] for r in runs) for s in STAGES}
        gen = statistics.median(sum(r[s] for s in GENERATION) for r in runs)
        total = statistics.median(sum(r.values()) for r in runs)
        area = size * size / 1e6
        results[size] = {"median_s": med, "generation_s": gen, "total_s": total,
                         "total_per_km2_s": total / area, "runs": runs}
        print(f"{size:6.0f}  " + " ".join(f"{med[s]:10.3f}" for s in STAGES)
              + f"  {gen:10.3f} {total:6.2f}  {total / area:7.3f}", flush=True)
    sizes = sorted(results)
    base = results[sizes[0]]["total_per_km2_s"]
    for size in sizes[1:]:
        print(f"time per km² at {size:.0f} m / at {sizes[0]:.0f} m: "
              f"{results[size]['total_per_km2_s'] / base:.2f}x")
    args.json.parent.mkdir(parents=True, exist_ok=True)
    args.json.write_text(json.dumps(results, indent=2))


if __name__ == "__main__":
    main()
