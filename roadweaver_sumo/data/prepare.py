"""OSM extracts -> training tiles: road fields F and condition vectors c, one shard per file.

``out_dir/shard-NNN-<name>.npz`` holds, per tile, F quantised to uint8 (``decode_field`` turns it
back into float32), c as float32 and where the tile came from; ``out_dir/manifest.json`` lists
the sources with their sha256, the settings, the counts and the ODbL attribution that anything
derived from OpenStreetMap must carry.
"""

from __future__ import annotations

import hashlib
import json
import time
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np

from ..errors import RoadweaverError
from .condition import CONDITION_NAMES, condition_vector
from .field import CHANNELS, DIST_CLIP_M, FIELD_SIZE, road_field, rotate_field
from .osm import read_osm
from .style_code import STYLE_FEATURES, STYLE_MEAN, STYLE_STD
from .tiles import MIN_COVERAGE, iter_tiles

ATTRIBUTION = "Road data © OpenStreetMap contributors (ODbL)"
FORMAT_VERSION = 1
#: F = q / 255 * scale + offset per channel (orientation channels span [-1, 1]).
FIELD_OFFSET = np.array([0.0, -1.0, -1.0, 0.0, 0.0, 0.0], dtype=np.float32)
FIELD_SCALE = np.array([1.0, 2.0, 2.0, 1.0, 1.0, 1.0], dtype=np.float32)


def encode_field(F: np.ndarray) -> np.ndarray:
    """Float field(s) (..., 6) -> uint8, 1/255 of each channel's range per step."""
    q = np.rint((F - FIELD_OFFSET) / FIELD_SCALE * 255.0)
    return np.clip(q, 0, 255).astype(np.uint8)


def decode_field(Fq: np.ndarray) -> np.ndarray:
    """uint8 field(s) (..., 6) from a shard -> float32 F."""
    return Fq.astype(np.float32) / 255.0 * FIELD_SCALE + FIELD_OFFSET


def sha256(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def _region_tiles(G, tile_m, size, *, seed, rotations, shifts, random_rotations, min_coverage,
                  classes) -> dict[str, np.ndarray]:
    """F, c and provenance of every covered tile of one region. F and c are computed once per
    crop; its 90° rotations turn the raster (c does not change under them: all measures are
    invariant to quarter turns)."""
    area_km2 = tile_m * tile_m / 1e6
    cached = None
    rows: dict[str, list] = {k: [] for k in ("F", "c", "centre", "angle", "shift", "coverage",
                                             "road_nodes")}
    for tile in iter_tiles(G, tile_m, rotations=rotations, shifts=shifts,
                           random_rotations=random_rotations, min_coverage=min_coverage,
                           seed=seed):
        if tile.base is not cached:  # a new crop: rasterise and measure it once
            cached = tile.base
            F0 = road_field(tile.base, size, classes=classes)
            c = condition_vector(tile.base, area_km2)
            nodes = sum(1 for _, d in tile.base.degree() if d != 2)
        F = rotate_field(F0, tile.quarter_turns)
        for name, value in (("F", encode_field(F)), ("c", c), ("centre", tile.centre),
                            ("angle", tile.angle_deg), ("shift", tile.shift),
                            ("coverage", tile.coverage), ("road_nodes", nodes)):
            rows[name].append(value)
    empty = {"F": (0, size, size, len(CHANNELS)), "c": (0, len(CONDITION_NAMES)),
             "centre": (0, 2), "shift": (0, 2)}
    return {k: np.asarray(v) if v else np.zeros(empty.get(k, (0,))) for k, v in rows.items()}


def _check_inputs(osm_files: Sequence[Path]) -> list[Path]:
    paths = [Path(p) for p in osm_files]
    if not paths:
        raise RoadweaverError("no OSM files given")
    for p in paths:
        if not p.is_file():
            raise RoadweaverError(f"{p}: no such OSM file")
    return paths


def _stats(cs: list[np.ndarray]) -> dict:
    c = np.concatenate(cs) if cs else np.zeros((0, len(CONDITION_NAMES)))
    if len(c) == 0:
        return {}
    return {name: {"mean": float(c[:, i].mean()), "std": float(c[:, i].std())}
            for i, name in enumerate(CONDITION_NAMES)}


def prepare_dataset(osm_files: Sequence[Path], out_dir: Path, *, tile_m: float = 2000.0,
                    size: int = FIELD_SIZE, seed: int = 0,
                    rotations: Sequence[float] = (0, 90, 180, 270),
                    shifts: Sequence[float] = (0.0, 0.5), random_rotations: int = 0,
                    min_coverage: float = MIN_COVERAGE,
                    classes: tuple[str, ...] | None = None,
                    log: Callable[[str], None] = print) -> dict:
    """Cut every OSM file into tiles and write their road fields and condition vectors.

    Returns the manifest (also written to ``out_dir/manifest.json``). Bad input (a missing or
    unreadable file, a file without drivable roads, no covered tile at all) raises
    RoadweaverError with a one-line message.
    """
    paths = _check_inputs(osm_files)
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    sources, cs, start = [], [], time.perf_counter()
    for i, path in enumerate(paths):
        t0 = time.perf_counter()
        G = read_osm(path)
        arrays = _region_tiles(G, tile_m, size, seed=[seed, i], rotations=rotations,
                               shifts=shifts, random_rotations=random_rotations,
                               min_coverage=min_coverage, classes=classes)
        shard = f"shard-{i:03d}-{path.name.split('.')[0]}.npz"
        np.savez_compressed(out_dir / shard, **arrays)
        cs.append(arrays["c"])
        sources.append({
            "file": path.name, "sha256": sha256(path), "bytes": path.stat().st_size,
            "shard": shard, "tiles": len(arrays["c"]),
            "road_nodes": sum(1 for _, d in G.degree() if d != 2),
            "extent_m": [G.graph["width"], G.graph["height"]],
            "projection": G.graph["projection"], "seconds": time.perf_counter() - t0,
        })
        log(f"{path.name}: {len(arrays['c'])} tiles in {sources[-1]['seconds']:.1f} s")
    total = sum(s["tiles"] for s in sources)
    if total == 0:
        raise RoadweaverError(
            f"no tile of {tile_m:g} m is covered by roads (min coverage {min_coverage:g})")
    manifest = {
        "format_version": FORMAT_VERSION, "attribution": ATTRIBUTION, "sources": sources,
        "tiles": total, "seconds": time.perf_counter() - start,
        "settings": {"tile_m": tile_m, "size": size, "seed": seed, "rotations": list(rotations),
                     "shifts": list(shifts), "random_rotations": random_rotations,
                     "min_coverage": min_coverage, "classes": list(classes) if classes else None,
                     "dist_clip_m": DIST_CLIP_M},
        "field": {"channels": list(CHANNELS), "dtype": "uint8",
                  "offset": FIELD_OFFSET.tolist(), "scale": FIELD_SCALE.tolist()},
        "condition": {"names": list(CONDITION_NAMES), "stats": _stats(cs),
                      "style_features": list(STYLE_FEATURES),
                      "style_mean": STYLE_MEAN.tolist(), "style_std": STYLE_STD.tolist()},
    }
    (out_dir / "manifest.json").write_text(json.dumps(manifest, indent=1, ensure_ascii=False))
    return manifest


def load_dataset(out_dir: Path) -> dict[str, np.ndarray]:
    """All shards of a prepared dataset concatenated; ``F`` stays uint8 (see decode_field) and
    ``source`` is each tile's index into the manifest's ``sources``."""
    out_dir = Path(out_dir)
    try:
        manifest = json.loads((out_dir / "manifest.json").read_text())
    except (OSError, ValueError) as exc:
        raise RoadweaverError(f"{out_dir}: not a prepared dataset ({exc})") from exc
    parts: dict[str, list] = {}
    for i, src in enumerate(manifest["sources"]):
        with np.load(out_dir / src["shard"]) as shard:
            for k in shard.files:
                parts.setdefault(k, []).append(shard[k])
            parts.setdefault("source", []).append(np.full(len(shard["c"]), i))
    return {k: np.concatenate(v) for k, v in parts.items()}
