"""Roads crossing or overlapping without a junction, over many maps of unseen seeds (issue 33).

For every map: the report's own figures (``generation.hdmap.lane_overlaps`` and
``net.crossings_without_junction``, measured by ``roadweaver_sumo.validate.overlaps``) and the
independent check of ``tests/crossing_check.py`` (centrelines and lane outlines of
``map.net.xml`` read with sumolib). Prints one line per map and the totals.

  python bench/crossings.py [--maps 200] [--big] [--work DIR] [--jobs 2] [--boundary ring]
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from crossing_check import crossings

from roadweaver_sumo.validate.net_metrics import net_metrics

STYLES = ("grid", "organic", "radial", "mixed")
SKELETONS = ("learned", "procedural")
FIRST_SEED = 5000  # seeds the tests and examples never use


def specs(count: int, big: bool) -> list[dict]:
    """``count`` specs spread over sizes 1-3 km, densities 10-120, styles and skeletons."""
    rng = np.random.default_rng(33)
    out = []
    for k in range(count):
        out.append({"size": int(rng.choice([1000, 1500, 2000, 2500, 3000])),
                    "density": int(rng.integers(10, 121)),
                    "style": STYLES[k % 4], "skeleton": SKELETONS[(k // 4) % 2],
                    "seed": FIRST_SEED + k})
    if big:
        out.append({"size": 10000, "density": 30, "style": "mixed", "skeleton": "learned",
                    "seed": FIRST_SEED + count})
    return out


def one_map(spec: dict, work: Path) -> dict:
    out = work / f"{spec['skeleton'][0]}-{spec['style']}-{spec['size']}-d{spec['density']}-s{spec['seed']}"
    cmd = ["roadweaver-sumo", "make-scenario", "--density", str(spec["density"]),
           "--vehicles", "10", "--size", str(spec["size"]), "--style", spec["style"],
           "--skeleton", spec["skeleton"], "--seed", str(spec["seed"]), "--out", str(out),
           "--force", "--no-validate", "--boundary", spec.get("boundary", "ring")]
    proc = subprocess.run(cmd, capture_output=True, text=True, check=False)
    if proc.returncode != 0:
        return {"name": out.name, "error": proc.stderr.strip().splitlines()[-1:]}
    report = json.loads((out / "report.json").read_text())
    net = out / "map.net.xml"
    area = spec["size"] ** 2 / 1e6
    return {"name": out.name,
            "hdmap": report["generation"]["hdmap"]["lane_overlaps"],
            "report_net": net_metrics(net, area)["crossings_without_junction"],
            "indep_centre": len(crossings(net)), "indep_lanes": len(crossings(net, lanes=True))}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--maps", type=int, default=200)
    parser.add_argument("--big", action="store_true", help="one 10 km map as well")
    parser.add_argument("--work", type=Path)
    parser.add_argument("--jobs", type=int, default=1, help="maps made at once")
    parser.add_argument("--boundary", default="open", help="the maps' boundary: open or ring")
    parser.add_argument("--skip", type=int, default=0,
                        help="leave out the first N specs (made by an earlier run)")
    args = parser.parse_args()
    work = args.work or Path(tempfile.mkdtemp(prefix="crossings-"))
    rows = []
    with ThreadPoolExecutor(args.jobs) as pool:  # each map is a make-scenario process
        for row in pool.map(lambda spec: one_map(spec | {"boundary": args.boundary}, work),
                            specs(args.maps, args.big)[args.skip:]):
            rows.append(row)
            print(json.dumps(row), flush=True)
    ok = [r for r in rows if "error" not in r]
    print(f"maps {len(rows)}, generated {len(ok)}, errors {len(rows) - len(ok)}")
    for key in ("hdmap", "report_net", "indep_centre", "indep_lanes"):
        print(f"{key}: maps with any {sum(r[key] > 0 for r in ok)}, pairs {sum(r[key] for r in ok)}")


if __name__ == "__main__":
    main()
