"""``roadweaver-sumo evaluate``: our metrics (DESIGN.md "Metrics") for any SUMO ``.net.xml``.

So that users can put our maps side by side with ``netgenerate`` output or their own OSM imports,
measured by the very code that judges our scenarios (:mod:`.net_metrics`). Only the map area is
not known from a foreign net: it is the net's ``convBoundary`` unless the caller gives it.
"""

from __future__ import annotations

import math
from pathlib import Path

import sumolib
from lxml import etree

from ..errors import RoadweaverError
from ..realism import realism_statistics
from .net_metrics import loaded_net_metrics
from .netgraph import load_net, road_edges, road_graph
from .rule_coverage import rule_lines


def evaluate_net(net_path: Path, area_km2: float | None = None) -> dict:
    """Net metrics of the SUMO network at ``net_path`` plus the area used and where it came from.

    Raises :class:`RoadweaverError` (one line) for a missing file, a file that is not a SUMO
    network, a network without roads, or an area that is not a positive number.
    """
    net_path = Path(net_path)
    if not net_path.is_file():
        raise RoadweaverError(f"network {net_path} not found")
    if area_km2 is not None and not area_km2 > 0:
        raise RoadweaverError(f"--area-km2 must be > 0, got {area_km2:g}")
    if not looks_like_net(net_path):
        raise RoadweaverError(f"{net_path} is not a SUMO network (no <net> root element)")
    net = load_net(net_path)
    if not road_edges(net):
        raise RoadweaverError(f"{net_path} holds no roads (no normal edges)")
    source = "given"
    if area_km2 is None:
        area_km2, source = boundary_area_km2(net), "convBoundary"
        if not area_km2 > 0:
            raise RoadweaverError(f"{net_path} has an empty convBoundary; pass --area-km2")
    result = loaded_net_metrics(net, area_km2)
    result.update(net=str(net_path), area_km2=area_km2, area_source=source,
                  realism=_json_ready(realism_statistics(road_graph(net), net_bbox(net))))
    return result


def boundary_area_km2(net: sumolib.net.Net) -> float:
    """Area (km²) of the net's ``convBoundary``, or of its junctions' bounding box when the net
    declares no location."""
    x0, y0, x1, y1 = net_bbox(net)
    return (x1 - x0) * (y1 - y0) / 1e6


def net_bbox(net: sumolib.net.Net) -> tuple[float, float, float, float]:
    """The net's ``convBoundary`` (x0, y0, x1, y1), or its junctions' bounding box when the net
    declares no location: the map border that the realism statistics measure from."""
    try:
        x0, y0, x1, y1 = net.getBoundary()
    except (KeyError, ValueError):
        xs, ys = zip(*(n.getCoord()[:2] for n in net.getNodes()), strict=True)
        x0, y0, x1, y1 = min(xs), min(ys), max(xs), max(ys)
    return float(x0), float(y0), float(x1), float(y1)


def summary_lines(result: dict) -> list[str]:
    """A short human summary of :func:`evaluate_net`'s result."""
    al = result["alignment"]
    return [
        f"{result['net']}: {result['area_km2']:.3f} km² ({result['area_source']})",
        (f"road nodes {result['road_nodes']} ({result['density']:.1f}/km²), edges"
         f" {result['edges']}, lanes {result['lanes']}"),
        (f"LCC {result['lcc_ratio']:.3f}, dead ends {result['dead_end_ratio']:.3f}, cycles"
         f" {result['cycle_ratio']:.3f}, crossings without junction"
         f" {result['crossings_without_junction']}, sharp bends {result['sharp_bends']}"),
        (f"bearing entropy {result['bearing_entropy']:.3f} nats, orientation order"
         f" {result['orientation_order']:.3f}"),
        (f"reachability: junctions {result['junction_reachability']:.4f}, lanes"
         f" {result['lane_reachability']:.4f}; lane-end gaps mean {al['mean']:.3f} m,"
         f" p95 {al['p95']:.3f} m, max {al['max']:.3f} m"),
        *rule_lines(result["rules"]),
        "realism (issue 35; _inner: away from the border):",
        *_columns([f"{k} {'-' if v is None else f'{v:.4g}'}"
                   for k, v in sorted(result["realism"].items())]),
    ]


def _json_ready(stats: dict) -> dict:
    """NaN (a figure the net does not define, e.g. no blocks) as null, so --json is JSON."""
    return {k: None if math.isnan(v) else v for k, v in stats.items()}


def _columns(items: list[str], per_line: int = 3) -> list[str]:
    return ["  " + ", ".join(items[i : i + per_line]) for i in range(0, len(items), per_line)]


def looks_like_net(path: Path) -> bool:
    """Whether the root element of the (possibly gzipped) XML file is ``<net>``: sumolib reads
    any XML without complaint and returns an empty net."""
    try:
        _, root = next(etree.iterparse(str(path), events=("start",)))
    except (etree.XMLSyntaxError, StopIteration, OSError):
        return False
    return root.tag == "net"
