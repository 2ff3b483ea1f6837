"""Does the learned skeleton do what issue 4 asks? Four measurements, one command.

Usage: python bench/evaluate_learned.py [--osm-dir ../shared/data/osm] [--seeds 0-9]
           [--parts condition,density,realism,seams] [--json bench/results/learned.json]

* condition: --style grid vs organic at density 30, 2 km, per seed: orientation order φ and
  bearing entropy H of the generated road graph (learned skeleton + expansion).
* density: relative error of the road-node density for targets 10..60 (style mixed).
* realism: distance to real 2 km tiles (unrotated crops of the OSM extracts, road-node density
  40..80) of learned and procedural maps at density 60: degree mix (L1 between mean shares of
  degree 1/3/4/5+ road nodes), dead-end share, bearing entropy (difference of means) and edge
  length distribution (1-D Wasserstein distance, metres). The degree figures twice: over all
  road nodes, and over those at least 100 m inside the map (a real tile's roads end where it
  was cut, a generated map's end on its frame road).
* seams: 6 km x 6 km learned maps at density 30, one per seed; road length and road-node
  density per band along x and y (bands half the window stride: 540 m, since density 30 is
  sampled over windows stretched 1.08 times), and the mean jump between neighbouring bands at
  sampling-window borders vs elsewhere, over all seeds.
"""

from __future__ import annotations

import argparse
import json
import statistics
import time
from pathlib import Path

import numpy as np
from scipy.stats import wasserstein_distance

from roadweaver_sumo import metrics
from roadweaver_sumo.errors import RoadweaverError
from roadweaver_sumo.expand import expand_skeleton
from roadweaver_sumo.roadgraph import edge_length
from roadweaver_sumo.skeleton import make_skeleton
from roadweaver_sumo.spec import ScenarioSpec

DEGREE_BINS = ((1, 1), (3, 3), (4, 4), (5, 99))


def seeds_arg(text: str) -> list[int]:
    if "-" in text:
        lo, hi = text.split("-")
        return list(range(int(lo), int(hi) + 1))
    return [int(s) for s in text.split(",")]


def road_graph(spec: ScenarioSpec):
    return expand_skeleton(spec, make_skeleton(spec))


def skeleton_only(spec: ScenarioSpec):
    """The skeleton's own polylines as a graph (for φ and H before any expansion)."""
    from roadweaver_sumo.roadgraph import add_road, new_road_graph

    sk = make_skeleton(spec)
    G = new_road_graph(spec.width, spec.height)
    for k, line in enumerate(sk.polylines):
        G.add_node(2 * k, xy=tuple(line[0]))
        G.add_node(2 * k + 1, xy=tuple(line[-1]))
        add_road(G, 2 * k, 2 * k + 1, line, "arterial")
    return G


def shape_figures(G, margin: float = 0.0) -> dict:
    """Degree mix, dead-end share, bearing entropy, φ and edge lengths. With ``margin``, the
    degree figures count only road nodes at least that far inside the map: a real tile's roads
    end where the tile was cut and a generated map's run into its frame road, and neither is a
    junction or dead end of the street network."""
    w, h = G.graph["width"], G.graph["height"]
    inside = [n for n in G.nodes if margin <= G.nodes[n]["xy"][0] <= w - margin
              and margin <= G.nodes[n]["xy"][1] <= h - margin]
    deg = [d for _, d in G.degree(inside) if d != 2]
    n = max(len(deg), 1)
    return {
        "degree_mix": [sum(lo <= d <= hi for d in deg) / n for lo, hi in DEGREE_BINS],
        "dead_end": sum(d == 1 for d in deg) / n,
        "H": metrics.bearing_entropy(G),
        "phi": metrics.orientation_order(G),
        "edge_lengths": [edge_length(G, u, v) for u, v in G.edges],
    }


def part_condition(seeds):
    out = {}
    for style in ("grid", "organic"):
        rows = []
        for seed in seeds:
            spec = ScenarioSpec(density=30, vehicles=10, seed=seed, style=style, skeleton="learned")
            try:
                G, S = road_graph(spec), skeleton_only(spec)
            except RoadweaverError as exc:  # a failed map is a result too
                rows.append({"seed": seed, "error": str(exc)})
                print(f"condition {style} seed {seed}: ERROR {exc}", flush=True)
                continue
            rows.append({"seed": seed, "phi": metrics.orientation_order(G),
                         "H": metrics.bearing_entropy(G),
                         "skeleton_phi": metrics.orientation_order(S),
                         "skeleton_H": metrics.bearing_entropy(S)})
            print(f"condition {style} seed {seed}: map phi {rows[-1]['phi']:.3f} "
                  f"H {rows[-1]['H']:.3f}; skeleton alone phi {rows[-1]['skeleton_phi']:.3f} "
                  f"H {rows[-1]['skeleton_H']:.3f}", flush=True)
        out[style] = rows
    for style, rows in out.items():
        ok = [r for r in rows if "error" not in r]
        print(f"{style}: {len(rows) - len(ok)} of {len(rows)} seeds failed")
        for prefix in ("", "skeleton_"):
            phis, hs = [r[prefix + "phi"] for r in ok], [r[prefix + "H"] for r in ok]
            print(f"{style:8s} {prefix or 'map_'}phi mean {statistics.mean(phis):.3f} "
                  f"[{min(phis):.3f}, {max(phis):.3f}]  H mean {statistics.mean(hs):.3f} "
                  f"[{min(hs):.3f}, {max(hs):.3f}]")
    return out


def part_density(seeds):
    rows = []
    for density in (10, 20, 30, 40, 60):
        for seed in seeds[:3]:
            spec = ScenarioSpec(density=density, vehicles=10, seed=seed, skeleton="learned")
            try:
                G = road_graph(spec)
            except RoadweaverError as exc:
                rows.append({"density": density, "seed": seed, "error": str(exc)})
                print(f"density {density} seed {seed}: ERROR {exc}", flush=True)
                continue
            measured = metrics.density(G, spec.area_km2)
            rows.append({"density": density, "seed": seed, "measured": measured,
                         "error": abs(measured - density) / density})
            print(f"density {density} seed {seed}: {measured:.2f} "
                  f"({100 * rows[-1]['error']:.1f} %)", flush=True)
    ok = [r for r in rows if isinstance(r["error"], float)]
    print(f"density: {len(rows) - len(ok)} of {len(rows)} failed; error max "
          f"{max((r['error'] for r in ok), default=float('nan')):.3f}")
    return rows


def real_tiles(osm_dir: Path, lo: float = 40.0, hi: float = 80.0):
    from roadweaver_sumo.data import iter_tiles, read_osm

    graphs = []
    for path in sorted(osm_dir.iterdir()):
        G = read_osm(path)
        for tile in iter_tiles(G, 2000.0, rotations=(0,), shifts=(0.0,)):
            d = metrics.density(tile.base, 4.0)
            if lo <= d <= hi:
                graphs.append(tile.base)
    return graphs


def summarise(figs: list[dict]) -> dict:
    return {"degree_mix": np.mean([f["degree_mix"] for f in figs], axis=0).tolist(),
            "dead_end": statistics.mean(f["dead_end"] for f in figs),
            "H": statistics.mean(f["H"] for f in figs),
            "edge_lengths": [x for f in figs for x in f["edge_lengths"]]}


def distance(a: dict, b: dict) -> dict:
    return {"degree_mix_l1": float(np.abs(np.subtract(a["degree_mix"], b["degree_mix"])).sum()),
            "dead_end": abs(a["dead_end"] - b["dead_end"]), "H": abs(a["H"] - b["H"]),
            "edge_length_w1_m": wasserstein_distance(a["edge_lengths"], b["edge_lengths"])}


MARGINS = (0.0, 100.0)  # whole map, and road nodes at least 100 m inside it


def real_summary(osm_dir: Path, cache: Path) -> dict:
    """Figures of the real tiles per margin (cached: reading and cutting every extract takes
    minutes)."""
    if cache.is_file():
        return json.loads(cache.read_text())
    tiles = real_tiles(osm_dir)
    real = {}
    for margin in MARGINS:
        real[str(margin)] = summarise([shape_figures(G, margin) for G in tiles])
        real[str(margin)]["tiles"] = len(tiles)
    cache.parent.mkdir(parents=True, exist_ok=True)
    cache.write_text(json.dumps(real))
    return real


def part_realism(seeds, osm_dir: Path, cache: Path = Path("bench/results/real_tiles_v2.json")):
    real = real_summary(osm_dir, cache)
    out = {}
    graphs = {}
    for skeleton in ("learned", "procedural"):
        graphs[skeleton], failed = [], 0
        for s in seeds:
            try:
                spec = ScenarioSpec(density=60, vehicles=10, seed=s, skeleton=skeleton)
                graphs[skeleton].append(road_graph(spec))
            except RoadweaverError:
                failed += 1
        print(f"{skeleton}: {len(graphs[skeleton])} maps, {failed} failed")
    for margin in MARGINS:
        ref = real[str(margin)]
        part = out[f"margin {margin:g} m"] = {
            "real": {k: v for k, v in ref.items() if k != "edge_lengths"}}
        print(f"-- road nodes at least {margin:g} m inside the map --")
        for skeleton, maps in graphs.items():
            mine = summarise([shape_figures(G, margin) for G in maps])
            part[skeleton] = {"figures": {k: v for k, v in mine.items() if k != "edge_lengths"},
                              "maps": len(maps), "distance_to_real": distance(mine, ref)}
            print(f"{skeleton:10s} figures {part[skeleton]['figures']}")
            print(f"{skeleton:10s} distance to real tiles: {part[skeleton]['distance_to_real']}")
        print(f"real tiles: {part['real']}")
    return out


def band_profile(G, size: float, band: float, axis: int):
    """Road length (km per km²) and road nodes per km² in each band along ``axis``."""
    n = int(size // band)
    length, nodes = np.zeros(n), np.zeros(n)
    for u, v, data in G.edges(data=True):
        c = np.asarray(data["coords"])
        mids, seg = 0.5 * (c[1:] + c[:-1]), np.hypot(*np.diff(c, axis=0).T)
        k = (mids[:, axis] // band).astype(int)
        inside = (k >= 0) & (k < n)  # a partial last band is left out
        np.add.at(length, k[inside], seg[inside])
    for node, d in G.degree():
        k = int(G.nodes[node]["xy"][axis] // band)
        if d != 2 and 0 <= k < n:
            nodes[k] += 1
    area = band * size / 1e6
    return length / 1000 / area, nodes / area


def part_seams(seeds, size: float = 6000.0):
    """Per seed, the band profiles; then the mean jump between neighbouring bands at window
    borders and elsewhere, over all seeds (one map's large-scale gradient is not a seam)."""
    from roadweaver_sumo.skeleton.learned import condition_for

    out, jumps = {"maps": []}, {}
    for seed in seeds:
        spec = ScenarioSpec(density=30, vehicles=10, width=size, height=size, seed=seed,
                            skeleton="learned")
        try:
            G = expand_skeleton(spec, make_skeleton(spec))
        except RoadweaverError as exc:  # a failed map is a result too; the others still count
            print(f"seams seed {seed}: FAILED: {exc}")
            out["maps"].append({"seed": seed, "error": str(exc)})
            continue
        # Sampling windows start every half window: 1 km times the window scale (1.08 at
        # density 30, which the model samples at 35 over stretched windows). Bands of half that
        # put a window border on every second band edge.
        window_m = 1000.0 * condition_for(spec)[1]
        band = window_m / 2
        record = {"seed": seed, "window_stride_m": window_m, "band_m": band}
        for axis, name in ((0, "x"), (1, "y")):
            length, nodes = band_profile(G, size, band, axis)
            edges = np.arange(1, len(length)) * band  # boundaries between neighbouring bands
            at_border = np.isclose(edges % window_m, 0.0) | np.isclose(edges % window_m, window_m)
            record[name] = {"road_km_per_km2": length.round(2).tolist(),
                            "nodes_per_km2": nodes.round(1).tolist()}
            for figure, values in (("length", length), ("nodes", nodes)):
                step = np.abs(np.diff(values))
                for where, sel in (("border", at_border), ("elsewhere", ~at_border)):
                    jumps.setdefault((name, figure, where), []).extend(step[sel].tolist())
            print(f"seams seed {seed} {name}: road km/km² per band "
                  f"{record[name]['road_km_per_km2']}; nodes/km² {record[name]['nodes_per_km2']}")
        out["maps"].append(record)
    for name in ("x", "y"):
        out[name] = {f"{figure} {where}": float(np.mean(jumps[(name, figure, where)]))
                     for figure in ("length", "nodes") for where in ("border", "elsewhere")}
        print(f"seams {name}: mean jump between bands (road km/km², nodes/km²) at window borders "
              f"{out[name]['length border']:.2f}, {out[name]['nodes border']:.2f}; elsewhere "
              f"{out[name]['length elsewhere']:.2f}, {out[name]['nodes elsewhere']:.2f}")
    return out


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--osm-dir", type=Path, default=Path("../shared/data/osm"))
    ap.add_argument("--seeds", default="0-9")
    ap.add_argument("--parts", default="condition,density,realism,seams")
    ap.add_argument("--json", type=Path, default=Path("bench/results/learned.json"))
    args = ap.parse_args()
    seeds = seeds_arg(args.seeds)
    results = {}
    for part in args.parts.split(","):
        start = time.perf_counter()
        if part == "condition":
            results[part] = part_condition(seeds)
        elif part == "density":
            results[part] = part_density(seeds)
        elif part == "realism":
            results[part] = part_realism(seeds, args.osm_dir)
        elif part == "seams":
            results[part] = part_seams(seeds)
        print(f"[{part}: {time.perf_counter() - start:.0f} s]", flush=True)
    # Parts run separately (condition over 10 seeds, the rest over 5) land in one file.
    args.json.parent.mkdir(parents=True, exist_ok=True)
    earlier = json.loads(args.json.read_text()) if args.json.is_file() else {}
    args.json.write_text(json.dumps(earlier | results, indent=1))


if __name__ == "__main__":
    main()
