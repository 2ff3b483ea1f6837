"""``preview.png``: a picture of a scenario folder that answers "what did I get?" at a glance.

Lanes at their true width, junction areas, traffic lights and dead ends from ``map.net.xml``
(read with sumolib), the vehicles per edge of the validation run (``report.json``,
``simulation.edge_flows``) as a heat overlay with a colour bar, a scale bar, and the spec and
verdict in the title.

Drawn with matplotlib's Agg canvas directly (no pyplot, so the caller's backend is untouched) and
saved without date or software metadata, so the same folder always gives the same PNG bytes.
"""

from __future__ import annotations

import functools
import json
import math
from pathlib import Path
from types import SimpleNamespace

import numpy as np

from .errors import RoadweaverError
from .gc_pause import cyclic_gc_paused

PREVIEW_FILE = "preview.png"
NET_FILE = "map.net.xml"
FIGURE_WIDTH_IN = 8.0
SIDE_IN, TOP_IN, BOTTOM_IN = 0.25, 0.8, 1.2  # margins around the map: titles, legend, colour bar
MAX_MAP_HEIGHT_IN = 10.0  # a tall map is drawn narrower rather than as a very long picture
DPI = 100
LANE_COLOUR = "#c4c4c4"
JUNCTION_COLOUR = "#dcdcdc"
TLS_COLOUR = "#1565c0"
DEAD_END_COLOUR = "#6a1b9a"
STOP_COLOUR = "#c62828"
RIGHT_BEFORE_LEFT_COLOUR = "#ef6c00"
LEGEND_COLUMNS = 4
OPTIONAL_MARKERS = ("stop sign", "right before left", "collision site")
COLLISION_COLOUR = "#00c853"  # stands out against the flow colours
FLOW_CMAP = "inferno_r"
FLOW_CMAP_RANGE = (0.12, 0.95)  # skip the near-white and near-black ends of the colour map
PNG_METADATA = {"Software": None}  # no matplotlib version in the file: bytes depend on pixels only


@functools.cache
def matplotlib_parts() -> SimpleNamespace:
    """The matplotlib classes the preview draws with, imported on first use, so that commands
    that draw nothing do not import matplotlib."""
    from matplotlib import colormaps
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.collections import LineCollection, PolyCollection
    from matplotlib.colors import ListedColormap, Normalize
    from matplotlib.figure import Figure
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    return SimpleNamespace(
        colormaps=colormaps, FigureCanvasAgg=FigureCanvasAgg, LineCollection=LineCollection,
        PolyCollection=PolyCollection, ListedColormap=ListedColormap, Normalize=Normalize,
        Figure=Figure, Line2D=Line2D, Patch=Patch,
    )


def render_preview(folder: Path, out: Path | None = None, net: dict | None = None) -> Path:
    """Draw the scenario in ``folder`` into ``out`` (default ``folder/preview.png``). ``net`` is
    :func:`net_drawing` of the folder's net when the caller has read it already (validation
    does, while its simulation runs); otherwise the net is read here."""
    folder = Path(folder)
    net_path = folder / NET_FILE
    if not net_path.is_file():
        raise RoadweaverError(f"{folder} is not a scenario folder (no {NET_FILE})")
    spec = _read_json(folder / "spec.json")
    report = _read_json(folder / "report.json")
    net = net if net is not None else _read_net(net_path)

    xmin, ymin, xmax, ymax = net["bounds"]
    pad = 0.02 * max(xmax - xmin, ymax - ymin, 1.0)  # the perimeter road sits on the bounds
    xmin, ymin, xmax, ymax = xmin - pad, ymin - pad, xmax + pad, ymax + pad
    width, height = xmax - xmin, ymax - ymin
    map_w = min(FIGURE_WIDTH_IN - 2 * SIDE_IN, MAX_MAP_HEIGHT_IN * width / height)
    map_h = map_w * height / width
    fig_h = TOP_IN + map_h + BOTTOM_IN
    mpl = matplotlib_parts()
    fig = mpl.Figure(figsize=(FIGURE_WIDTH_IN, fig_h), dpi=DPI)
    mpl.FigureCanvasAgg(fig)
    left = (FIGURE_WIDTH_IN - map_w) / 2  # a tall map stands centred
    ax = fig.add_axes((left / FIGURE_WIDTH_IN, BOTTOM_IN / fig_h, map_w / FIGURE_WIDTH_IN,
                       map_h / fig_h))  # fmt: skip
    pt_per_m = map_w * 72 / width  # draw lanes at their true width
    _draw_network(ax, net, report, pt_per_m, fig)
    ax.set_xlim(xmin, xmax)
    ax.set_ylim(ymin, ymax)
    ax.set_aspect("equal")
    ax.set_xticks([])
    ax.set_yticks([])
    for side in ax.spines.values():
        side.set_color("#999999")
    _scale_bar(ax, xmin, ymin, width, height)
    _titles(fig, spec, report)

    out = Path(out) if out is not None else folder / PREVIEW_FILE
    try:
        fig.savefig(out, dpi=DPI, metadata=PNG_METADATA, facecolor="white")
    except OSError as exc:
        raise RoadweaverError(f"cannot write {out}: {exc.strerror or exc}") from None
    return out


def _draw_network(ax, net: dict, report: dict, pt_per_m: float, fig) -> None:
    """Junction areas, lanes (grey, or coloured by flow), junction markers, collision sites,
    and one legend for all of them."""
    mpl = matplotlib_parts()
    ax.add_collection(mpl.PolyCollection(net["junctions"], facecolors=JUNCTION_COLOUR,
                                     edgecolors="none", zorder=1))  # fmt: skip
    handles = [mpl.Patch(color=JUNCTION_COLOUR, label=f"junction area ({len(net['junctions'])})")]
    sim = report.get("simulation") if isinstance(report.get("simulation"), dict) else {}
    handles += _draw_lanes(ax, net, sim.get("edge_flows") or {}, pt_per_m, fig)
    size = float(np.clip(9 * pt_per_m, 4.5, 9))
    sites = _collision_xy(net, sim.get("collision_sites") or [])
    stops = [xy for kind in ("priority_stop", "allway_stop")
             if (xy := net["nodes"].get(kind)) is not None]
    for xy, colour, marker, label in (
        (net["nodes"].get("traffic_light"), TLS_COLOUR, "o", "traffic light"),
        (np.vstack(stops) if stops else None, STOP_COLOUR, "8", "stop sign"),
        (net["nodes"].get("right_before_left"), RIGHT_BEFORE_LEFT_COLOUR, "^",
         "right before left"),
        (net["nodes"].get("dead_end"), DEAD_END_COLOUR, "X", "dead end"),
        (sites, COLLISION_COLOUR, "*", "collision site"),
    ):
        xy = np.empty((0, 2)) if xy is None else xy
        if label in OPTIONAL_MARKERS and not len(xy):
            continue  # only worth a legend entry when there is one
        big = 1.6 if label == "collision site" else 1.0
        ax.plot(xy[:, 0], xy[:, 1], ls="none", marker=marker, ms=size * big, mfc=colour,
                mec="white", mew=0.8, zorder=4)  # fmt: skip
        handles.append(mpl.Line2D([], [], ls="none", marker=marker, ms=7 * big, mfc=colour,
                              mec="white", label=f"{label} ({len(xy)})"))  # fmt: skip
    ax.legend(handles=handles, loc="upper center", bbox_to_anchor=(0.5, -0.01),
              ncol=min(len(handles), LEGEND_COLUMNS),
              fontsize=8, frameon=False, handlelength=1.6)  # fmt: skip


def _draw_lanes(ax, net: dict, flows: dict, pt_per_m: float, fig) -> list:
    """Lanes at their true width: unused ones grey, used ones coloured by their edge's flow
    (busiest on top), with a colour bar under the map. Returns the legend handle."""
    mpl = matplotlib_parts()
    lanes, widths = net["lanes"], net["lane_widths"]
    values = np.array([_count(flows.get(edge)) for edge in net["lane_edges"]], dtype=float)
    busy = values > 0
    ax.add_collection(mpl.LineCollection(
        [lane for lane, b in zip(lanes, busy) if not b], colors=LANE_COLOUR,
        linewidths=np.maximum(widths[~busy] * pt_per_m, 0.4), capstyle="butt", zorder=2))
    label = f"lane ({len(lanes)})" if not busy.any() else f"lane without traffic ({(~busy).sum()})"
    if busy.any():
        lo, hi = FLOW_CMAP_RANGE
        cmap = mpl.ListedColormap(mpl.colormaps[FLOW_CMAP](np.linspace(lo, hi, 256)),
                                  name="flow")
        order = np.argsort(values[busy], kind="stable")
        coll = mpl.LineCollection([lanes[i] for i in np.flatnonzero(busy)[order]], cmap=cmap,
                                  norm=mpl.Normalize(vmin=0, vmax=values.max()),
                                  capstyle="butt",
                                  linewidths=np.maximum(widths[busy][order] * pt_per_m, 0.8),
                                  zorder=3)  # fmt: skip
        coll.set_array(values[busy][order])
        ax.add_collection(coll)
        fig_h = fig.get_figheight()
        bar = fig.colorbar(coll, cax=fig.add_axes((0.2, 0.5 / fig_h, 0.6, 0.15 / fig_h)),
                           orientation="horizontal")  # fmt: skip
        bar.set_label("vehicles that drove on the edge in the validation run", fontsize=9)
        bar.ax.tick_params(labelsize=8)
    return [mpl.Line2D([], [], color=LANE_COLOUR, lw=3, label=label)]


def _collision_xy(net: dict, sites: list) -> np.ndarray:
    """Positions of the report's collision sites (``["junction n12", 3]``, ``["lane e4_0", 1]``):
    the junction, or the middle of the lane."""
    points = []
    for site in sites:
        kind, _, name = str(site[0] if isinstance(site, list) and site else "").partition(" ")
        if kind == "junction" and name in net["node_xy"]:
            points.append(net["node_xy"][name])
        elif kind == "lane" and name in net["lane_ids"]:
            shape = net["lanes"][net["lane_ids"][name]]
            points.append(shape[len(shape) // 2])
    return np.asarray(points, dtype=float).reshape(-1, 2)


def _count(value) -> float:
    return float(value) if isinstance(value, (int, float)) and not isinstance(value, bool) else 0.0


def _scale_bar(ax, xmin: float, ymin: float, width: float, height: float) -> None:
    """A bar of a round length (1, 2 or 5 x 10^k m) about a fifth of the map wide."""
    target = width / 5
    base = 10 ** math.floor(math.log10(target))
    length = max(m * base for m in (1, 2, 5) if m * base <= target)
    x0, y0 = xmin + 0.04 * width, ymin + 0.04 * height
    ax.plot([x0, x0 + length], [y0, y0], color="black", lw=3, solid_capstyle="butt", zorder=5)
    label = f"{length / 1000:g} km" if length >= 1000 else f"{length:g} m"
    ax.text(x0 + length / 2, y0 + 0.012 * height, label, ha="center", va="bottom", fontsize=9,
            zorder=5, bbox={"facecolor": "white", "alpha": 0.8, "edgecolor": "none", "pad": 1})


def _titles(fig, spec: dict, report: dict) -> None:
    """Line 1: the spec; line 2: the verdict and key figures of the validation."""
    title = "  ·  ".join([
        str(spec.get("style", "?")),
        f"{_num(spec.get('density'))} road nodes/km²",
        f"{_length(spec.get('width'))} × {_length(spec.get('height'))}",
        f"seed {spec.get('seed', '?')}",
        f"{spec.get('vehicles', '?')} vehicles in {_duration(spec.get('duration'))}",
    ])  # fmt: skip
    fig.text(0.5, 1 - 0.15 / fig.get_figheight(), title, ha="center", va="top", fontsize=12,
             weight="bold")  # fmt: skip
    sim, net = report.get("simulation"), report.get("net") or {}
    if isinstance(sim, dict):
        line = "  ·  ".join([
            "PASSED" if report.get("passed") else "FAILED",
            f"{sim.get('arrived', '?')}/{spec.get('vehicles', '?')} arrived",
            f"{sim.get('teleports_total', '?')} teleports",
            f"{sim.get('collisions', '?')} collisions",
            f"{net.get('road_nodes', '?')} road nodes ({_num(net.get('density'), '.1f')}/km²)",
        ])  # fmt: skip
        colour = "#1b5e20" if report.get("passed") else "#b71c1c"
    else:
        line, colour = "not validated: lanes shown without traffic", "#555555"
    fig.text(0.5, 1 - 0.45 / fig.get_figheight(), line, ha="center", va="top", fontsize=10,
             color=colour)  # fmt: skip


def _num(value, fmt: str = "g") -> str:
    return format(value, fmt) if isinstance(value, (int, float)) else "?"


def _length(metres) -> str:
    if not isinstance(metres, (int, float)):
        return "?"
    return f"{metres / 1000:g} km" if metres >= 1000 else f"{metres:g} m"


def _duration(seconds) -> str:
    if not isinstance(seconds, (int, float)):
        return "?"
    for unit, size in (("h", 3600), ("min", 60)):
        if seconds >= size and seconds % size == 0:
            return f"{seconds / size:g} {unit}"
    return f"{seconds:g} s"


def _read_net(path: Path) -> dict:
    """:func:`net_drawing` of the net at ``path``, read without internal lanes."""
    import sumolib

    try:
        with cyclic_gc_paused():
            net = sumolib.net.readNet(str(path), withInternal=False)
    except Exception as exc:  # noqa: BLE001 - sumolib raises bare SAX errors on a damaged net
        raise RoadweaverError(f"cannot read {path}: {exc}") from None
    return net_drawing(net)


def net_drawing(net) -> dict:
    """What the preview draws of a sumolib net (read with or without internal lanes): lane
    polylines and widths (with their edge ids), junction polygons and node positions by
    junction type, and the net's bounds, in the net's own metric frame."""
    lanes, widths, lane_edges, lane_ids = [], [], [], {}
    for edge in sorted(net.getEdges(withInternal=False), key=lambda e: e.getID()):
        for lane in edge.getLanes():
            lane_ids[lane.getID()] = len(lanes)
            lanes.append(np.asarray(lane.getShape(), dtype=float)[:, :2])
            widths.append(lane.getWidth())
            lane_edges.append(edge.getID())
    junctions, nodes, node_xy = [], {}, {}
    road_nodes = (n for n in net.getNodes() if n.getType() != "internal")
    for node in sorted(road_nodes, key=lambda n: n.getID()):
        node_xy[node.getID()] = node.getCoord()[:2]
        shape = node.getShape()
        if len(shape) >= 3:
            junctions.append(np.asarray(shape, dtype=float)[:, :2])
        nodes.setdefault(_kind(node), []).append(node.getCoord()[:2])
    xmin, ymin, xmax, ymax = net.getBoundary()
    return {
        "lanes": lanes,
        "lane_widths": np.asarray(widths, dtype=float),
        "lane_edges": lane_edges,
        "lane_ids": lane_ids,
        "node_xy": node_xy,
        "junctions": junctions,
        "nodes": {kind: np.asarray(xy, dtype=float) for kind, xy in nodes.items()},
        "bounds": (xmin, ymin, xmax, ymax),
    }


def _kind(node) -> str:
    """The node's SUMO junction type, except that a node with roads to one other node only is a
    ``dead_end`` (the road graph's definition, as in the report): netconvert types our dead
    ends ``priority``, since cars can turn around there."""
    others = {n.getID() for n in node.getNeighboringNodes()} - {node.getID()}
    return "dead_end" if len(others) == 1 else node.getType()


def _read_json(path: Path) -> dict:
    """A JSON file as a dict; missing or damaged files give an empty dict (the preview then
    says what it could not show rather than failing)."""
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return {}
    return data if isinstance(data, dict) else {}
