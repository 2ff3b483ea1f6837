"""A map like this city (issue 35, "Like this city"): a real network measured with the report's
own code, the generator conditioned on it, and the closest of a few candidate maps kept.

The city is measured as the learned model was trained (paper §III-B): on the 2 km tiles that
its roads mostly cover (``data.iter_tiles``), each measured by ``data.condition`` (the
structural priors of the condition vector c) and ``realism`` (the statistics of the report);
the city is the median tile. A network smaller than a tile is measured whole, on its bounding box.

The learned model is conditioned on the city's density and structural priors (gridness,
radialness, organicness, bearing entropy: as ``--gridness`` ... would), the style code staying
the ``--style`` preset's: conditioned on a tile's own style code as well, the maps' share of
junction arms running straight on fell from about 0.63 to 0.47 (held-out tiles of Heidelberg
and Cobb County, same seeds). The expansion takes the city's share of dead ends. But one
sampled map varies from seed to seed about as much as towns do, so the map is the closest of
:func:`candidate_count` candidates, made from seeds drawn from the spec's; closeness is the
mean over :data:`MATCHED` of each statistic's distance to the city divided by the spread of
real tiles. On ten held-out 2 km tiles (``bench/like.py``) that map was closer to its tile
than the `mixed` preset's on at least 5 of the 6 figures issue 35 names for 8 of the 10.
"""

from __future__ import annotations

import math
import re
from dataclasses import replace
from pathlib import Path

import networkx as nx
import numpy as np

from .errors import RoadweaverError
from .spec import MAX_SEED, PRIOR_RANGES, ScenarioSpec

#: The statistics a candidate is matched on, each with its yardstick: the p10-p90 spread of
#: 153 real 2 km tiles of 16 OpenStreetMap regions (bench/realism.py --real-only).
MATCHED = {
    "dead_end_share_inner": 0.281, "three_way_share_inner": 0.252,
    "four_way_share_inner": 0.366, "bearing_entropy": 1.338,
    "straight_through_share_inner": 0.288, "block_area_median_inner": 22_680.0,
    "edge_length_mean": 90.6,
}
TILE_M = 2000.0
STAGE_LIKE = 5  # the spec's random stream that draws the candidates' seeds
#: candidates for a 2 km map; a larger map averages over more town, varies less from seed
#: to seed and costs more, so it gets fewer (:func:`candidate_count`)
CANDIDATES, CANDIDATE_AREA_KM2 = 8, 4.0
NETWORK_SUFFIXES = (".net.xml", ".net.xml.gz", ".graphml")


def measure_city(path: Path) -> dict:
    """The ``like`` entry of a spec for the road network in ``path`` (an OSM extract, a SUMO
    ``.net.xml`` or an osmnx GraphML file): see :func:`measure_network`."""
    G, bbox = read_network(Path(path))
    return measure_network(G, bbox, _name(Path(path)))


def measure_network(G: nx.Graph, bbox: tuple[float, float, float, float], name: str) -> dict:
    """The ``like`` entry of a spec for road graph ``G`` on the map box ``bbox``: its name,
    density (road nodes/km²), structural priors (``data.condition``) and statistics (every one
    ``realism`` computes), the medians over its covered 2 km tiles, and how many tiles that was
    (0: the network was measured whole)."""
    from .data import iter_tiles
    from .data.condition import structural_priors
    from .realism import realism_statistics

    tiles = [t.base for t in iter_tiles(G, TILE_M, rotations=(0,), shifts=(0.0,))]
    parts = [(T, (0.0, 0.0, TILE_M, TILE_M)) for T in tiles] or [(G, bbox)]
    priors, statistics = [], []
    for part, (x0, y0, x1, y1) in parts:
        priors.append(structural_priors(part, (x1 - x0) * (y1 - y0) / 1e6))
        statistics.append(realism_statistics(part, (x0, y0, x1, y1)))
    median = {k: float(np.nanmedian([s[k] for s in statistics])) for k in statistics[0]
              if any(math.isfinite(s[k]) for s in statistics)}
    density, *rest = np.median(priors, axis=0).tolist()
    return {"name": name, "tiles": len(tiles), "density": _rounded(density),
            "priors": {k: _rounded(v) for k, v in zip(PRIOR_RANGES, rest, strict=True)},
            "statistics": {k: _rounded(v) for k, v in sorted(median.items())}}


def read_network(path: Path) -> tuple[nx.Graph, tuple[float, float, float, float]]:
    """The road graph (RoadGraph convention, starting at (0, 0)) and the map box of a network
    file; a one-line error for a file that is missing, of an unknown kind or without roads."""
    from .data.osm import OSM_SUFFIXES

    name = path.name.lower()
    if not path.is_file():
        raise RoadweaverError(f"--like: {path} not found")
    if name.endswith(OSM_SUFFIXES):
        from .data import read_osm

        G = read_osm(path)
    elif name.endswith(".graphml"):
        from .data.graphml import read_graphml

        G = read_graphml(path)
    elif name.endswith(NETWORK_SUFFIXES):
        G = _read_sumo_net(path)
    else:
        raise RoadweaverError(
            f"--like: {path} is not a road network this reads: an OpenStreetMap extract "
            f"({', '.join(OSM_SUFFIXES)}), a SUMO network (.net.xml) or an osmnx .graphml file")
    if not any(d != 2 for _, d in G.degree()):
        raise RoadweaverError(f"--like: {path} holds no roads")
    return G, (0.0, 0.0, float(G.graph["width"]), float(G.graph["height"]))


def _read_sumo_net(path: Path) -> nx.Graph:
    """A SUMO network's road graph, shifted so that its boundary starts at (0, 0)."""
    from .validate.evaluate import looks_like_net, net_bbox
    from .validate.netgraph import load_net, road_graph

    if not looks_like_net(path):
        raise RoadweaverError(f"--like: {path} is not a SUMO network (no <net> root element)")
    net = load_net(path)
    x0, y0, _, _ = net_bbox(net)
    G = road_graph(net)
    shift = np.array([x0, y0])
    for n in G:
        G.nodes[n]["xy"] = tuple(np.asarray(G.nodes[n]["xy"]) - shift)
    for _, _, data in G.edges(data=True):
        data["coords"] = data["coords"] - shift
    return G


def candidate_count(spec: ScenarioSpec) -> int:
    """:data:`CANDIDATES` for a map of :data:`CANDIDATE_AREA_KM2`, fewer in proportion to a
    larger area, at least one."""
    return int(np.clip(round(CANDIDATES * CANDIDATE_AREA_KM2 / spec.area_km2), 1, CANDIDATES))


def candidate_specs(spec: ScenarioSpec) -> list[ScenarioSpec]:
    """The spec itself, then specs whose seeds its own seed draws."""
    count = candidate_count(spec)
    seeds = spec.rng(STAGE_LIKE).integers(MAX_SEED, size=count - 1).tolist()
    return [spec] + [replace(spec, seed=int(s)) for s in seeds]


def distance(statistics: dict, city: dict) -> float:
    """Mean over the :data:`MATCHED` statistics both define of |map - city| / real spread."""
    gaps = [abs(statistics[k] - city[k]) / spread for k, spread in MATCHED.items()
            if k in city and math.isfinite(statistics.get(k, math.nan))]
    return float(np.mean(gaps)) if gaps else math.inf


def closest_map(spec: ScenarioSpec, log=lambda msg: None) -> tuple[dict, nx.Graph, dict]:
    """The road graph of the candidate closest to ``spec.like``: (the skeleton's provenance,
    the graph, the report's ``like`` section)."""
    from .expand import expand_skeleton
    from .realism import realism_statistics
    from .skeleton import make_skeleton

    city = spec.like["statistics"]
    best = None
    candidates = candidate_specs(spec)
    for k, candidate in enumerate(candidates):
        log(f"candidate {k + 1} of {len(candidates)} like {spec.like['name']} ...")
        skeleton = make_skeleton(candidate)
        graph = expand_skeleton(candidate, skeleton)
        statistics = realism_statistics(graph)
        gap = distance(statistics, city)
        if best is None or gap < best[0]:
            best = (gap, k, candidate.seed, skeleton.provenance, graph, statistics)
    gap, k, seed, provenance, graph, statistics = best
    report = {"name": spec.like["name"], "candidates": len(candidates), "chosen": k,
              "map_seed": seed, "distance": round(gap, 4),
              "statistics": {name: {"city": city[name], "map": _rounded(statistics[name])}
                             for name in MATCHED if name in city}}
    return provenance, graph, report


def _name(path: Path) -> str:
    """The file's name without its suffixes, safe in a folder name."""
    stem = path.name
    while (suffix := Path(stem).suffix).lower() in (".osm", ".gz", ".bz2", ".pbf", ".net",
                                                     ".xml", ".graphml"):
        stem = stem[:-len(suffix)]
    return re.sub(r"[^A-Za-z0-9_-]+", "-", stem).strip("-") or "city"


def _rounded(value: float) -> float:
    """Five significant digits: what a measurement means, the same on every machine."""
    return float(f"{value:.5g}")
