"""Would a person (or a classifier) take our maps for real towns? The realism instrument of
issue 35.

Usage: python bench/realism.py [--maps 1] [--styles grid,radial,organic,mixed]
           [--skeletons learned,procedural] [--density-range 20-200] [--densities 30]
           [--seed-base 900000] [--boundary ring] [--jobs 1] [--real-only] [--split-size 3] [--splits 200]
           [--osm-dir ../shared/data/osm] [--cgcc-dir ../shared/data/cgcc]
           [--cache bench/results/realism_real.json] [--json bench/results/realism.json]

The reference is every 2 km x 2 km tile (unrotated, unshifted crops mostly covered by roads,
``data.iter_tiles``) of the OSM extracts, car-drivable network, topologically simplified,
with its density in ``--density-range``. Our maps are ``--maps`` road graphs per style and
skeleton, 2 km, at the density of a randomly drawn reference tile (or ``--densities``), on
seeds from ``--seed-base`` (never used in training or tests). Both are measured by
``roadweaver_sumo.realism`` (the statistics of issue 35) and compared on its ``COMPARED`` set:

* per statistic the real p10/median/p90, ours, and the 1-Wasserstein distance divided by the
  real p10-p90 spread; their mean for ours, for two random sets of ``--split-size`` real
  tiles (issue 35: real vs real 0.28) and for as many real tiles as we have maps against the
  other real tiles (the floor at our sample size: W1 of a small set is larger);
* a classifier two-sample test: logistic regression on the standardised statistics, stratified
  5-fold cross-validated ROC AUC (0.5: indistinguishable, 1: told apart every time), also
  without the two statistics that separate the sets most;
* the labelled cgcc city centres: per label the p10-p90 range of bearing entropy,
  straight-through share and 4-way share, beside our maps per style.

Real statistics are cached in ``--cache`` (recomputed when roadweaver_sumo/realism.py changes).
Development tool: reads ../shared, the package never does. Road data © OpenStreetMap
contributors (ODbL).
"""

from __future__ import annotations

import argparse
import csv
import hashlib
import json
import math
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np
from scipy.stats import wasserstein_distance

from roadweaver_sumo import realism
from roadweaver_sumo.realism import COMPARED, realism_statistics

SHARED = Path(__file__).resolve().parents[2] / "shared" / "data"
TILE_M = 2000.0
CGCC_SHOWN = ("bearing_entropy", "straight_through_share_inner", "four_way_share_inner")


def definitions_key() -> str:
    """Changes whenever the statistics' code or the tiling does: the cache is then stale."""
    source = Path(realism.__file__).read_bytes() + f"tile {TILE_M}".encode()
    return hashlib.sha1(source).hexdigest()[:12]


def osm_tile_stats(path: Path) -> list[dict]:
    from roadweaver_sumo.data import iter_tiles, read_osm

    G = read_osm(path)
    return [{"region": path.name, "centre": list(t.centre), "coverage": t.coverage,
             "stats": realism_statistics(t.base, (0.0, 0.0, TILE_M, TILE_M))}
            for t in iter_tiles(G, TILE_M, rotations=(0,), shifts=(0.0,))]


def cgcc_stats(path: Path, label: str) -> dict:
    from roadweaver_sumo.data.graphml import read_graphml

    return {"city": path.stem, "label": label, "stats": realism_statistics(read_graphml(path))}


def reference(args) -> dict:
    """Real tile and cgcc statistics, from the cache when it is current."""
    key = definitions_key()
    if args.cache.is_file():
        cached = json.loads(args.cache.read_text())
        if cached.get("key") == key:
            return cached
    began = time.perf_counter()
    files = sorted(p for p in args.osm_dir.iterdir() if ".osm" in p.name or p.suffix == ".pbf")
    with open(args.cgcc_dir / "labels.csv", newline="") as f:
        labels = {row["file"]: row["layout"] for row in csv.DictReader(f)}
    tiles = [t for per_file in pool_map(osm_tile_stats, files, args.jobs) for t in per_file]
    cities = pool_map(cgcc_stats, [args.cgcc_dir / name for name in labels], args.jobs,
                      list(labels.values()))
    ref = {"key": key, "tiles": tiles, "cgcc": cities}
    args.cache.parent.mkdir(parents=True, exist_ok=True)
    args.cache.write_text(json.dumps(ref))
    print(f"reference: {len(tiles)} tiles of {len(files)} regions, {len(cities)} cgcc centres "
          f"({time.perf_counter() - began:.0f} s; cached in {args.cache})")
    return ref


def our_map(task: tuple) -> dict:
    from roadweaver_sumo.expand import expand_skeleton
    from roadweaver_sumo.skeleton import make_skeleton
    from roadweaver_sumo.spec import ScenarioSpec

    style, skeleton, seed, density, boundary = task
    record = {"style": style, "skeleton": skeleton, "seed": seed, "density": density}
    spec = ScenarioSpec(density=density, vehicles=1, width=TILE_M, height=TILE_M, seed=seed,
                        style=style, skeleton=skeleton, boundary=boundary)
    try:  # a failed map is a result too; the others still count
        record["stats"] = realism_statistics(expand_skeleton(spec, make_skeleton(spec)))
    except Exception as exc:  # noqa: BLE001
        record["error"] = f"{type(exc).__name__}: {exc}"
    return record


def pool_map(fn, items: list, jobs: int, *more) -> list:
    if jobs <= 1:
        return list(map(fn, items, *more))
    with ProcessPoolExecutor(jobs) as pool:
        return list(pool.map(fn, items, *more))


def matrix(records: list[dict]) -> np.ndarray:
    return np.array([[r["stats"][k] for k in COMPARED] for r in records], dtype=float)


def normalised_w1(ours: np.ndarray, real: np.ndarray, spread: np.ndarray) -> np.ndarray:
    """Per statistic: W1(ours, real) / (real p90 − p10); NaN values (undefined) are left out."""
    out = np.full(len(COMPARED), np.nan)
    for k in range(len(COMPARED)):
        a, b = ours[:, k][np.isfinite(ours[:, k])], real[:, k][np.isfinite(real[:, k])]
        if len(a) and len(b) and spread[k] > 0:
            out[k] = wasserstein_distance(a, b) / spread[k]
    return out


def split_half(real: np.ndarray, spread: np.ndarray, size: int, splits: int) -> float:
    """Mean over ``splits`` random draws of the mean normalised W1 between two disjoint sets
    of ``size`` real tiles: how far real maps are from each other."""
    rng = np.random.default_rng(0)
    values = []
    for _ in range(splits):
        pick = rng.permutation(len(real))[: 2 * size]
        values.append(np.nanmean(normalised_w1(real[pick[:size]], real[pick[size:]], spread)))
    return float(np.mean(values))


def holdout(real: np.ndarray, spread: np.ndarray, size: int, splits: int) -> float:
    """Mean normalised W1 of ``size`` random real tiles to all the others: what a generator
    as real as the reference would score with ``size`` maps."""
    rng = np.random.default_rng(1)
    values = []
    for _ in range(splits):
        pick = rng.permutation(len(real))
        values.append(np.nanmean(normalised_w1(real[pick[:size]], real[pick[size:]], spread)))
    return float(np.mean(values))


def classifier_auc(real: np.ndarray, ours: np.ndarray, drop: int = 0) -> tuple[float, list]:
    """Cross-validated ROC AUC of logistic regression telling ``ours`` from ``real``; with
    ``drop``, first leaving out the statistics whose medians differ most (in real spreads)."""
    from sklearn.impute import SimpleImputer
    from sklearn.linear_model import LogisticRegression
    from sklearn.model_selection import StratifiedKFold, cross_val_score
    from sklearn.pipeline import make_pipeline
    from sklearn.preprocessing import StandardScaler

    gap = np.abs(np.nanmedian(ours, 0) - np.nanmedian(real, 0)) / (np.nanstd(real, 0) + 1e-12)
    dropped = [int(k) for k in np.argsort(-np.nan_to_num(gap))[:drop]]
    keep = [k for k in range(len(COMPARED)) if k not in dropped]
    X = np.vstack([real, ours])[:, keep]
    y = np.r_[np.zeros(len(real)), np.ones(len(ours))]
    folds = min(5, len(real), len(ours))
    if folds < 2:
        return math.nan, dropped
    model = make_pipeline(SimpleImputer(strategy="median"), StandardScaler(),
                          LogisticRegression(max_iter=2000, class_weight="balanced"))
    cv = StratifiedKFold(folds, shuffle=True, random_state=0)
    auc = cross_val_score(model, X, y, cv=cv, scoring="roc_auc")
    return float(auc.mean()), [COMPARED[k] for k in dropped]


def our_tasks(args, real_densities: np.ndarray) -> list[tuple]:
    rng = np.random.default_rng(args.seed_base)
    tasks, seed = [], args.seed_base
    for skeleton in args.skeletons:
        for style in args.styles:
            for i in range(args.maps):
                if args.densities:
                    density = args.densities[i % len(args.densities)]
                else:
                    density = round(float(rng.choice(real_densities)), 1)
                tasks.append((style, skeleton, seed, density, args.boundary))
                seed += 1
    return tasks


def print_table(real: np.ndarray, ours: dict[str, np.ndarray], spread: np.ndarray) -> dict:
    names = list(ours)
    print(f"{'statistic':32s} {'real p10 / p50 / p90':>28s} {'ours p10 / p50 / p90':>28s}  "
          + "  ".join(f"W1n {n}" for n in names))
    w1 = {n: normalised_w1(m, real, spread) for n, m in ours.items()}
    pooled = np.vstack(list(ours.values()))
    for k, name in enumerate(COMPARED):
        r = np.nanpercentile(real[:, k], [10, 50, 90])
        o = np.nanpercentile(pooled[:, k], [10, 50, 90]) if np.isfinite(pooled[:, k]).any() \
            else [math.nan] * 3
        print(f"{name:32s} {_triple(r):>28s} {_triple(o):>28s}  "
              + "  ".join(f"{w1[n][k]:{4 + len(n)}.2f}" for n in names))
    return {n: float(np.nanmean(v)) for n, v in w1.items()}


def _triple(v) -> str:
    return " / ".join(f"{x:.3g}" for x in v)


def print_cgcc(cities: list[dict], maps: list[dict]) -> None:
    print("cgcc city centres per label (p10-p90 [median]) and our maps per style (median):")
    groups = {f"cgcc {lab}": [c for c in cities if c["label"] == lab]
              for lab in ("grid", "hybrid", "organic")}
    for m in maps:
        groups.setdefault(f"ours {m['skeleton']} {m['style']}", []).append(m)
    print(f"{'':28s}" + "".join(f"{n:>34s}" for n in CGCC_SHOWN))
    for name, members in groups.items():
        X = np.array([[g["stats"][k] for k in CGCC_SHOWN] for g in members], dtype=float)
        cells = []
        for k in range(len(CGCC_SHOWN)):
            lo, mid, hi = np.nanpercentile(X[:, k], [10, 50, 90])
            cells.append(f"{lo:.2f}-{hi:.2f} [{mid:.2f}]" if name.startswith("cgcc")
                         else f"{mid:.2f}")
        print(f"{name + f' ({len(members)})':28s}" + "".join(f"{c:>34s}" for c in cells))


def main(argv=None) -> int:
    args = parse_args(argv)
    ref = reference(args)
    lo, hi = args.density_range
    tiles = [t for t in ref["tiles"] if lo <= t["stats"]["density"] <= hi]
    real = matrix(tiles)
    densities = np.array([t["stats"]["density"] for t in tiles])
    spread = np.nanpercentile(real, 90, axis=0) - np.nanpercentile(real, 10, axis=0)
    regions = sorted({t["region"] for t in tiles})
    print(f"real tiles with density {lo:g}-{hi:g}: {len(tiles)} of {len(ref['tiles'])}, "
          f"{len(regions)} regions, density median {np.median(densities):.1f}")
    results: dict = {"real_tiles": len(tiles), "regions": regions}
    results["real_vs_real_w1n"] = split_half(real, spread, args.split_size, args.splits)
    print(f"real vs real: mean normalised W1 between two sets of {args.split_size} tiles "
          f"({args.splits} draws): {results['real_vs_real_w1n']:.3f}")
    if args.real_only:
        print_cgcc(ref["cgcc"], [])
        return 0
    began = time.perf_counter()
    maps = pool_map(our_map, our_tasks(args, densities), args.jobs)
    ok = [m for m in maps if "stats" in m]
    for m in maps:
        if "error" in m:
            print(f"FAILED {m['skeleton']} {m['style']} seed {m['seed']}: {m['error']}")
    print(f"our maps: {len(ok)} of {len(maps)}, density median "
          f"{np.median([m['stats']['density'] for m in ok] or [math.nan]):.1f} "
          f"({time.perf_counter() - began:.0f} s)")
    if not ok:
        return 1
    ours = {"all": matrix(ok)}
    for skeleton in args.skeletons:
        chosen = [m for m in ok if m["skeleton"] == skeleton]
        if chosen:
            ours[skeleton] = matrix(chosen)
    results["mean_w1n"] = print_table(real, ours, spread)
    print("mean normalised W1 to the real tiles: "
          + ", ".join(f"{n} {v:.3f}" for n, v in results["mean_w1n"].items())
          + f" (real vs real {results['real_vs_real_w1n']:.3f})")
    results["holdout_w1n"] = {}
    for name, X in ours.items():
        size = min(len(X), len(real) // 2)
        results["holdout_w1n"][name] = holdout(real, spread, size, args.splits)
        print(f"  {size} real tiles vs the other real tiles, as a floor for {name}: "
              f"{results['holdout_w1n'][name]:.3f}")
    results["auc"] = {}
    for name, X in ours.items():
        auc, _ = classifier_auc(real, X)
        auc2, dropped = classifier_auc(real, X, drop=2)
        results["auc"][name] = {"auc": auc, "auc_without_two": auc2, "dropped": dropped}
        print(f"classifier AUC real vs ours ({name}, {len(X)} maps): {auc:.3f}; "
              f"without {', '.join(dropped)}: {auc2:.3f}")
    print_cgcc(ref["cgcc"], ok)
    results["maps"] = maps
    args.json.parent.mkdir(parents=True, exist_ok=True)
    args.json.write_text(json.dumps(results, indent=1))
    return 0


def parse_args(argv=None):
    def floats(text: str) -> list[float]:
        return [float(x) for x in text.split(",") if x]

    def span(text: str) -> tuple[float, float]:
        lo, hi = text.split("-")
        return float(lo), float(hi)

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--osm-dir", type=Path, default=SHARED / "osm")
    ap.add_argument("--cgcc-dir", type=Path, default=SHARED / "cgcc")
    ap.add_argument("--maps", type=int, default=1, help="maps per style and skeleton")
    ap.add_argument("--styles", type=lambda s: s.split(","),
                    default=["grid", "radial", "organic", "mixed"])
    ap.add_argument("--skeletons", type=lambda s: s.split(","), default=["learned", "procedural"])
    ap.add_argument("--density-range", type=span, default=(0.0, math.inf),
                    help="real tiles in this road-node density range (per km²), e.g. 20-40")
    ap.add_argument("--densities", type=floats, default=None,
                    help="our maps' densities (default: those of random reference tiles)")
    ap.add_argument("--seed-base", type=int, default=900_000)
    ap.add_argument("--boundary", default="open", help="our maps' boundary: open or ring")
    ap.add_argument("--jobs", type=int, default=1)
    ap.add_argument("--real-only", action="store_true", help="only the real-vs-real check")
    ap.add_argument("--split-size", type=int, default=3)
    ap.add_argument("--splits", type=int, default=200)
    ap.add_argument("--cache", type=Path, default=Path("bench/results/realism_real.json"))
    ap.add_argument("--json", type=Path, default=Path("bench/results/realism.json"))
    return ap.parse_args(argv)


if __name__ == "__main__":
    raise SystemExit(main())
