"""Build the v1 training set from the shared OSM extracts and print what it holds.

    python bench/prepare_data.py [--osm-dir DIR] [--out DIR] [--cgcc DIR] [--calibrate] [--reuse]

Prints tiles per region, time, size on disk, the condition-vector distribution, the round trip
graph -> F -> graph on real tiles (at 128 and 64 pixels), the grid/organic separation on the
labelled cgcc city centres, and the style presets measured on the tiles. ``--calibrate`` first
prints the style-feature means and standard deviations that style_code.py standardises with.
Writes everything also to ``<out>/report.json``. Development tool: reads ../shared, the package
never does.
"""

from __future__ import annotations

import argparse
import csv
import json
import time
from pathlib import Path

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from roadweaver_sumo import metrics
from roadweaver_sumo.data.condition import CONDITION_NAMES, gridness, organicness, radialness
from roadweaver_sumo.data.field import field_to_graph, road_field
from roadweaver_sumo.data.graphml import read_graphml
from roadweaver_sumo.data.osm import read_osm
from roadweaver_sumo.data.prepare import decode_field, encode_field, load_dataset, prepare_dataset
from roadweaver_sumo.data.style_code import STYLE_FEATURES, style_features
from roadweaver_sumo.data.tiles import iter_tiles
from roadweaver_sumo.roadgraph import total_length

SHARED = Path("/work/shared/data")
MATCH_M = 25.0  # a road node counts as recovered if the round trip has one this close


def base_crops(osm_files, shifts=(0.0,)):
    for path in osm_files:
        G = read_osm(path)
        for tile in iter_tiles(G, rotations=(0,), shifts=shifts):
            yield path.name, tile.base


def calibrate(osm_files) -> dict:
    X = np.array([style_features(g) for _, g in base_crops(osm_files, (0.0, 0.5))])
    out = {n: {"mean": float(m), "std": float(s)}
           for n, m, s in zip(STYLE_FEATURES, X.mean(0), X.std(0))}
    print(f"style features over {len(X)} crops:")
    for n, v in out.items():
        print(f"  {n:16s} mean {v['mean']:.4f} std {v['std']:.4f}")
    return out


def merged_count(G, tol: float) -> int:
    """Road nodes left when those closer than ``tol`` are merged (what a raster can resolve)."""
    xy = np.array([G.nodes[n]["xy"] for n, d in G.degree() if d != 2])
    if len(xy) < 2:
        return len(xy)
    pairs = cKDTree(xy).query_pairs(tol, output_type="ndarray")
    A = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(len(xy),) * 2)
    return int(connected_components(A, directed=False)[0])


def _recall(truth, rt) -> float:
    t = np.array([truth.nodes[n]["xy"] for n, d in truth.degree() if d != 2])
    r = np.array([rt.nodes[n]["xy"] for n, d in rt.degree() if d != 2])
    if len(t) == 0 or len(r) == 0:
        return 0.0
    return float((cKDTree(r).query(t)[0] < MATCH_M).mean())


def round_trip(osm_files, per_region: int) -> dict:
    out = {}
    for size in (128, 64):
        rows, seconds = [], 0.0
        for region, g in _limited(base_crops(osm_files), per_region):
            F = decode_field(encode_field(road_field(g, size)))
            t0 = time.perf_counter()
            h = field_to_graph(F, g.graph["width"])
            seconds += time.perf_counter() - t0
            n0, n1 = metrics.road_node_count(g), metrics.road_node_count(h)
            merged = merged_count(g, g.graph["width"] / size)
            rows.append([(n1 - n0) / n0, _recall(g, h), metrics.lcc_ratio(g), metrics.lcc_ratio(h),
                         total_length(h) / total_length(g), (n1 - merged) / merged])
        r = np.array(rows)
        out[size] = {"tiles": len(r), "node_error_mean": float(r[:, 0].mean()),
                     "node_error_abs_mean": float(np.abs(r[:, 0]).mean()),
                     "node_recall_25m": float(r[:, 1].mean()), "lcc_truth": float(r[:, 2].mean()),
                     "lcc_round_trip": float(r[:, 3].mean()), "length_ratio": float(r[:, 4].mean()),
                     "node_error_vs_merged_1px": float(r[:, 5].mean()),
                     "field_to_graph_s": seconds / len(r)}
        print(f"round trip {size}px: " + ", ".join(f"{k} {v:.3f}" for k, v in out[size].items()))
    return out


def _limited(items, per_region):
    seen: dict[str, int] = {}
    for region, g in items:
        seen[region] = seen.get(region, 0) + 1
        if seen[region] <= per_region:
            yield region, g


def auc(pos, neg) -> float:
    """Probability that a random positive scores above a random negative (ties count half)."""
    p, n = np.asarray(pos)[:, None], np.asarray(neg)[None, :]
    return float((p > n).mean() + 0.5 * (p == n).mean())


def cgcc_check(folder: Path) -> dict:
    with open(folder / "labels.csv", newline="") as f:
        labels = {r["file"]: r["layout"] for r in csv.DictReader(f)}
    by = {}
    for name, layout in labels.items():
        G = read_graphml(folder / name)
        by.setdefault(layout, []).append([gridness(G), organicness(G), radialness(G)])
    by = {k: np.array(v) for k, v in by.items()}
    g, o = by["grid"], by["organic"]
    out = {"auc_gridness": auc(g[:, 0], o[:, 0]), "auc_organicness": auc(o[:, 1], g[:, 1]),
           "auc_grid_minus_organic": auc(g[:, 0] - g[:, 1], o[:, 0] - o[:, 1]),
           "means": {k: {"gridness": float(v[:, 0].mean()), "organicness": float(v[:, 1].mean()),
                         "radialness": float(v[:, 2].mean()), "n": len(v)} for k, v in by.items()}}
    print("cgcc: " + json.dumps(out))
    return out


def presets(data: dict) -> dict:
    """Style presets: mean c of the real tiles most like each style (rotation 0 only)."""
    c = data["c"][data["angle"] == 0]
    idx = {n: i for i, n in enumerate(CONDITION_NAMES)}
    score = c[:, idx["gridness"]] - c[:, idx["organicness"]]
    rad = c[:, idx["radialness"]]
    pick = {"grid": score >= np.quantile(score, 0.9), "organic": score <= np.quantile(score, 0.1),
            "radial": rad >= np.quantile(rad, 0.9),
            "mixed": np.abs(score - np.median(score)) <= np.quantile(np.abs(score - np.median(score)), 0.2)}
    out = {k: np.round(c[m].mean(axis=0), 3).tolist() for k, m in pick.items()}
    for k, v in out.items():
        print(f"preset {k}: {v}")
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--osm-dir", type=Path, default=SHARED / "osm")
    ap.add_argument("--cgcc", type=Path, default=SHARED / "cgcc")
    ap.add_argument("--out", type=Path, default=Path("/work/datasets/v1"))
    ap.add_argument("--round-trip-tiles", type=int, default=6, help="per region")
    ap.add_argument("--calibrate", action="store_true")
    ap.add_argument("--reuse", action="store_true", help="measure an already prepared --out")
    args = ap.parse_args()
    osm_files = sorted(p for p in args.osm_dir.iterdir() if ".osm" in p.name)
    report = {"calibration": calibrate(osm_files)} if args.calibrate else {}
    if args.reuse:
        manifest = json.loads((args.out / "manifest.json").read_text())
    else:
        manifest = prepare_dataset(osm_files, args.out)
    size_mb = sum(f.stat().st_size for f in args.out.glob("shard-*.npz")) / 1e6
    print(f"{manifest['tiles']} tiles in {manifest['seconds']:.0f} s, {size_mb:.1f} MB on disk")
    for name, st in manifest["condition"]["stats"].items():
        print(f"  c {name:16s} mean {st['mean']:8.3f} std {st['std']:7.3f}")
    report.update({"tiles": manifest["tiles"], "seconds": manifest["seconds"], "size_mb": size_mb,
                   "per_region": {s["file"]: s["tiles"] for s in manifest["sources"]},
                   "condition_stats": manifest["condition"]["stats"],
                   "round_trip": round_trip(osm_files, args.round_trip_tiles),
                   "cgcc": cgcc_check(args.cgcc), "presets": presets(load_dataset(args.out))})
    (args.out / "report.json").write_text(json.dumps(report, indent=1))


if __name__ == "__main__":
    main()
