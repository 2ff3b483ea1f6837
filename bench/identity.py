"""Byte-identity check for speed-only changes: generate fixed maps and compare every written
file's sha256 with hashes recorded on the version before the change.

Usage: python bench/identity.py record FILE   (on the old version: writes the hashes)
       python bench/identity.py check FILE    (on the new version: exit 1 if any file differs)
       [--cases L10k,P10k,...] [--broad]

The default cases are two 10 km maps (learned, procedural, density 30) and four 2-3 km maps
of every style; ``--broad`` adds 48 small specs (both skeletons, 4 styles, densities
10/30/60, a square and a rectangle). Each case runs skeleton -> expansion -> HD map ->
written files as ``make-scenario`` does (cyclic GC paused), and prints its stage times.
"""

from __future__ import annotations

import argparse
import hashlib
import itertools
import json
import sys
import tempfile
import time
from pathlib import Path

from roadweaver_sumo.errors import RoadweaverError
from roadweaver_sumo.expand import expand_skeleton
from roadweaver_sumo.export.map_files import write_map_files
from roadweaver_sumo.gc_pause import cyclic_gc_paused
from roadweaver_sumo.hdmap import build_hdmap
from roadweaver_sumo.skeleton import make_skeleton
from roadweaver_sumo.spec import ScenarioSpec


def _case(skeleton: str, width: float, height: float, density: float, seed: int,
          **style: str) -> dict:
    return {"skeleton": skeleton, "width": width, "height": height, "density": density,
            "seed": seed, **style}


CASES = {
    "L10k": _case("learned", 10000, 10000, 30, 0),
    "P10k": _case("procedural", 10000, 10000, 30, 0),
    "L2grid": _case("learned", 2000, 2000, 30, 1, style="grid"),
    "P2org": _case("procedural", 2000, 2000, 60, 2, style="organic"),
    "Lrect": _case("learned", 3000, 1500, 10, 3, style="mixed"),
    "Prad": _case("procedural", 2500, 2500, 20, 4, style="radial"),
}


def broad_cases() -> dict:
    cases = {}
    for skeleton in ("learned", "procedural"):
        for style in ("grid", "radial", "organic", "mixed"):
            for density in (10, 30, 60):
                for seed, (w, h) in enumerate([(2000, 2000), (3000, 1500)], start=7):
                    cases[f"{skeleton[0]}-{style}-{density}-{w}x{h}-{seed}"] = _case(
                        skeleton, w, h, density, seed, style=style)
    return cases


def file_hashes(options: dict) -> tuple[dict, list[float]]:
    """sha256 of every file written for the case, and the four stage times (s)."""
    spec = ScenarioSpec(vehicles=100, **options)
    with tempfile.TemporaryDirectory() as tmp, cyclic_gc_paused():
        marks = [time.perf_counter()]
        skeleton = make_skeleton(spec)
        marks.append(time.perf_counter())
        graph = expand_skeleton(spec, skeleton)
        marks.append(time.perf_counter())
        hd = build_hdmap(graph, spec.geo_origin, traffic_lights=spec.traffic_lights,
                         rules=spec.rules, one_way_share=spec.one_way_share)
        marks.append(time.perf_counter())
        write_map_files(hd, Path(tmp))
        marks.append(time.perf_counter())
        hashes = {str(p.relative_to(tmp)): hashlib.sha256(p.read_bytes()).hexdigest()
                  for p in sorted(Path(tmp).rglob("*")) if p.is_file()}
    return hashes, [b - a for a, b in itertools.pairwise(marks)]


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("mode", choices=("record", "check"))
    ap.add_argument("file", type=Path)
    ap.add_argument("--cases", help="comma-separated case names (default: all)")
    ap.add_argument("--broad", action="store_true", help="add the 48 small specs")
    args = ap.parse_args()
    cases = CASES | (broad_cases() if args.broad else {})
    names = args.cases.split(",") if args.cases else list(cases)
    unknown = [n for n in names if n not in cases]
    if unknown:
        sys.exit(f"error: unknown case(s) {', '.join(unknown)}; known: {', '.join(cases)}")
    stored = json.loads(args.file.read_text()) if args.mode == "check" else {}
    missing = [n for n in names if args.mode == "check" and n not in stored]
    if missing:
        sys.exit(f"error: {args.file} has no recorded hashes for {', '.join(missing)}")
    differ = 0
    for name in names:
        try:
            hashes, times = file_hashes(cases[name])
        except RoadweaverError as exc:  # a refused spec: its message is the output
            hashes, times = {"error": str(exc)}, []
        stage_text = " ".join(f"{t:.2f}" for t in times)
        if args.mode == "record":
            stored[name] = hashes
            print(f"{name}: recorded ({stage_text} s)", flush=True)
            continue
        changed = sorted(f for f in set(hashes) | set(stored[name])
                         if hashes.get(f) != stored[name].get(f))
        differ += bool(changed)
        verdict = "identical" if not changed else f"DIFFERS in {', '.join(changed)}"
        print(f"{name}: {verdict} (skeleton/expansion/hdmap/export {stage_text} s)", flush=True)
    if args.mode == "record":
        args.file.write_text(json.dumps(stored, indent=1, sort_keys=True) + "\n")
        return 0
    print(f"{len(names) - differ} of {len(names)} cases identical")
    return 1 if differ else 0


if __name__ == "__main__":
    sys.exit(main())
