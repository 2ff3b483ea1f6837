"""Quality sweep of issue 2: densities x seeds at 2 km, 500 vehicles over 1 h, full validation.

Usage: python bench/quality_sweep.py [--densities 10,20,30,40,60] [--seeds 0-4] [--styles mixed]
       [--skeleton learned|procedural] [--boundary open|ring] [--rules de|us|priority]
       [--persons 100] [--keep DIR]
Prints one row per scenario and a summary against the issue's thresholds; writes JSON next to it.
"""

from __future__ import annotations

import argparse
import json
import statistics
import tempfile
import time
from pathlib import Path

from roadweaver_sumo.errors import RoadweaverError
from roadweaver_sumo.pipeline import make_scenario
from roadweaver_sumo.spec import DEFAULT_PERSONS, ScenarioSpec


def seeds_arg(text: str) -> list[int]:
    if "-" in text:
        lo, hi = text.split("-")
        return list(range(int(lo), int(hi) + 1))
    return [int(s) for s in text.split(",")]


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--densities", default="10,20,30,40,60")
    ap.add_argument("--seeds", default="0-4")
    ap.add_argument("--styles", default="mixed")
    ap.add_argument("--size", type=float, default=2000.0)
    ap.add_argument("--skeleton", default="learned", help="learned or procedural")
    ap.add_argument("--boundary", default="open", help="open or ring")
    ap.add_argument("--rules", default="de", help="de, us or priority")
    ap.add_argument("--vehicles", type=int, default=500)
    ap.add_argument("--persons", type=int, default=DEFAULT_PERSONS,
                    help="pedestrians per scenario, on sidewalks (0: no sidewalks)")
    ap.add_argument("--json", type=Path, default=Path("bench/results/quality_sweep.json"))
    ap.add_argument("--keep", type=Path, default=None,
                    help="keep each scenario folder under this folder (default: a temporary one)")
    args = ap.parse_args()
    rows: list[dict] = []
    errors: list[dict] = []
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp) if args.keep is None else args.keep
        for style in args.styles.split(","):
            for density in [float(d) for d in args.densities.split(",")]:
                for seed in seeds_arg(args.seeds):
                    spec = ScenarioSpec(density=density, vehicles=args.vehicles, seed=seed,
                                        style=style, width=args.size, height=args.size,
                                        skeleton=args.skeleton, boundary=args.boundary,
                                        rules=args.rules, sidewalks=args.persons > 0,
                                        persons=args.persons)
                    start = time.perf_counter()
                    try:
                        res = make_scenario(spec, folder / spec.name)
                    except RoadweaverError as exc:  # an error is a result of the sweep too
                        errors.append({"spec": spec.name, "error": str(exc)})
                        print(f"{spec.name}: ERROR {exc}", flush=True)
                        continue
                    rows.append(row(spec, res.report, res.failures, time.perf_counter() - start))
                    print(format_row(rows[-1]), flush=True)
    print(summary(rows) + f"; {len(errors)} errors")
    args.json.parent.mkdir(parents=True, exist_ok=True)
    args.json.write_text(json.dumps({"rows": rows, "errors": errors}, indent=2))


def row(spec: ScenarioSpec, report: dict, failures: list[str], wall: float) -> dict:
    net, sim = report["net"], report["simulation"]
    return {
        "style": spec.style, "density": spec.density, "seed": spec.seed,
        "measured_density": net["density"], "lcc": net["lcc_ratio"],
        "lane_reach": net["lane_reachability"], "crossings": net["crossings_without_junction"],
        "align_mean": net["alignment"]["mean"], "dead_end": net["dead_end_ratio"],
        "cycle": net["cycle_ratio"], "H": net["bearing_entropy"], "phi": net["orientation_order"],
        "arrived": sim["arrived_ratio"], "teleports": sim["teleports_total"],
        "collisions": sim["collisions"], "routing": sim["routing_success_rate"],
        "failures": failures, "wall_s": wall,
    }


def format_row(r: dict) -> str:
    return (f"{r['style']:8s} d={r['density']:4.0f} s={r['seed']} dens={r['measured_density']:6.2f} "
            f"lcc={r['lcc']:.3f} reach={r['lane_reach']:.4f} X={r['crossings']} "
            f"align={r['align_mean']:.3f} de={r['dead_end']:.3f} cyc={r['cycle']:.3f} "
            f"H={r['H']:.2f} phi={r['phi']:.2f} arr={r['arrived']:.3f} tp={r['teleports']} "
            f"col={r['collisions']} route={r['routing']:.4f} {r['wall_s']:.1f}s "
            f"{'FAIL ' + '; '.join(r['failures']) if r['failures'] else 'ok'}")


def summary(rows: list[dict]) -> str:
    err = [abs(r["measured_density"] - r["density"]) / r["density"] for r in rows]
    failed = [r for r in rows if r["failures"]]
    return (f"{len(rows)} scenarios, {len(failed)} failing thresholds; density error "
            f"max {max(err):.3f} mean {statistics.mean(err):.3f}; "
            f"min arrived {min(r['arrived'] for r in rows):.3f}; "
            f"max teleports {max(r['teleports'] for r in rows)}; "
            f"min lane reachability {min(r['lane_reach'] for r in rows):.4f}")


if __name__ == "__main__":
    main()
