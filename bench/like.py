"""Does ``--like`` make a map like the city (issue 35, "Like this city")?

Usage: python bench/like.py [--regions heidelberg-de.osm.pbf,cobb-county-us.osm.pbf]
           [--networks 5] [--seeds 2] [--seed-base 930000] [--osm-dir ../shared/data/osm]
           [--json bench/results/like.json]

The networks are 2 km tiles (unrotated, unshifted, mostly covered: ``data.iter_tiles``) of the
regions the learned model never saw in training (Heidelberg and Cobb County,
``generative/weights/MODEL_CARD.md``), taken in turn from each region. For each network and
seed, the map made ``like`` it (``like.measure_network``, ``like.closest_map``) and the map of
the ``mixed`` preset at the network's density are measured by ``realism``; the six figures of
issue 35 are compared by their distance to the network's, averaged over the seeds:
degree mix (sum of the absolute differences of the dead-end, 3-way and 4-way shares), dead
ends, bearing entropy, straight-through share, median block area and mean edge length (the
``_inner`` figures where there are). Done when, for every network, the ``like`` map is closer
on at least 5 of the 6.

Development tool: reads ../shared, the package never does. Road data © OpenStreetMap
contributors (ODbL).
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

from roadweaver_sumo.data import iter_tiles, read_osm
from roadweaver_sumo.expand import expand_skeleton
from roadweaver_sumo.like import closest_map, measure_network
from roadweaver_sumo.realism import realism_statistics
from roadweaver_sumo.skeleton import make_skeleton
from roadweaver_sumo.spec import ScenarioSpec

SHARED = Path(__file__).resolve().parents[2] / "shared" / "data" / "osm"
TILE_M = 2000.0
DEGREES = ("dead_end_share_inner", "three_way_share_inner", "four_way_share_inner")
FIGURES = ("degree mix", "dead ends", "bearing entropy", "straight through", "block area",
           "edge length")
SINGLE = ("dead_end_share_inner", "bearing_entropy", "straight_through_share_inner",
          "block_area_median_inner", "edge_length_mean")


def gaps(ours: dict, city: dict) -> list[float]:
    """Distance to the city on each of the six figures."""
    mix = sum(abs(ours[k] - city[k]) for k in DEGREES)
    return [mix] + [abs(ours[k] - city[k]) for k in SINGLE]


def networks(args) -> list[tuple[str, dict]]:
    """(name, like entry) of ``--networks`` tiles, taken in turn from each region."""
    per_region = []
    for region in args.regions.split(","):
        G = read_osm(args.osm_dir / region)
        tiles = list(iter_tiles(G, TILE_M, rotations=(0,), shifts=(0.0,)))
        per_region.append([(f"{region.split('.')[0]}-{k}", t.base) for k, t in enumerate(tiles)])
    chosen = []
    while len(chosen) < args.networks and any(per_region):
        for tiles in per_region:
            if tiles and len(chosen) < args.networks:
                chosen.append(tiles.pop(0))
    return [(name, measure_network(T, (0.0, 0.0, TILE_M, TILE_M), name)) for name, T in chosen]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--regions", default="heidelberg-de.osm.pbf,cobb-county-us.osm.pbf")
    parser.add_argument("--networks", type=int, default=5)
    parser.add_argument("--seeds", type=int, default=2)
    parser.add_argument("--seed-base", type=int, default=930000)
    parser.add_argument("--osm-dir", type=Path, default=SHARED)
    parser.add_argument("--json", type=Path)
    args = parser.parse_args()
    results = []
    print(f"{'network':<22}{'density':>8}  " + "".join(f"{f:>18}" for f in FIGURES)
          + "   closer")
    for name, like in networks(args):
        began = time.perf_counter()
        ours, mixed = [], []
        for seed in range(args.seed_base, args.seed_base + args.seeds):
            spec = ScenarioSpec(density=like["density"], vehicles=1, seed=seed)
            ours.append(gaps(realism_statistics(closest_map(
                ScenarioSpec(density=like["density"], vehicles=1, seed=seed, like=like))[1]),
                like["statistics"]))
            mixed.append(gaps(realism_statistics(expand_skeleton(spec, make_skeleton(spec))),
                              like["statistics"]))
        ours_mean, mixed_mean = np.nanmean(ours, axis=0), np.nanmean(mixed, axis=0)
        closer = int(np.sum(ours_mean < mixed_mean))
        results.append({"network": name, "density": like["density"], "figures": FIGURES,
                        "like_gap": ours_mean.tolist(), "mixed_gap": mixed_mean.tolist(),
                        "closer": closer})
        print(f"{name:<22}{like['density']:>8.1f}  "
              + "".join(f"{a:>8.3g} / {b:<8.3g}" for a, b in zip(ours_mean, mixed_mean))
              + f"   {closer} of 6 ({time.perf_counter() - began:.0f} s)", flush=True)
    print("(each figure: distance to the network of the like map / of the mixed preset)")
    done = sum(r["closer"] >= 5 for r in results)
    print(f"like closer on >= 5 of 6 figures: {done} of {len(results)} networks")
    if args.json:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps(results, indent=2) + "\n")


if __name__ == "__main__":
    main()
