"""Square up the learned skeleton: roads run straight between junctions along the local street
axes (issue 35, "hierarchy and continuity"; paper §III-B, graph reconstruction).

The sampled road field is a raster of about 16 m per pixel at 2 km, and its centrelines carry
that raster's noise: a junction may sit a pixel off, so a street between two junctions 100 m
apart leans by up to 9°, and the next one past the junction leans the other way. A grid then
reads as cracked mud: on learned `grid` maps at density 60 the bearing entropy was 3.1 nats and
0.45 of junction arms ran straight on (cgcc grid-labelled city centres: 1.7-2.9 nats and
0.72-0.86), and every style turned more per km than real towns.

The local street axes are the dominant pair of perpendicular directions of the skeleton's own
roads around each point (their length-weighted angles 4θ averaged with a Gaussian of
:data:`AXIS_SIGMA_M`, as ``tensor_field`` averages crosses). A road whose chord lies within the
snapping tolerance of an axis, and which bulges from its chord by at most :data:`MAX_BULGE` of its
length, is snapped: the junctions move so that the chord runs along the axis (least squares,
each junction held to where the model put it by :data:`ANCHOR`), and the road becomes its chord.
The tolerance grows with the condition's gridness prior (:func:`snap_tolerance_deg`), so a grid
asked for is squared up harder than an organic town, whose curving streets mostly keep their
shape. Other roads keep their shape and follow their ends.
"""

from __future__ import annotations

import math

import networkx as nx
import numpy as np
import shapely
from scipy.ndimage import gaussian_filter
from scipy.sparse import coo_matrix, identity
from scipy.sparse.linalg import spsolve

from ..portable import portable

AXIS_SIGMA_M = 300.0
AXIS_CELL_M = 50.0
#: a road's misalignment is weighed as the sideways offset it makes over this many metres, so a
#: long road is not forced round by the same angle as a short one (a 500 m road 10° off would
#: move its junctions by 87 m)
ANGLE_WEIGHT_M = 50.0
#: weight of a junction staying where the model put it, per metre, against ANGLE_WEIGHT_M
ANCHOR = 0.2
MAX_BULGE = 0.25  # of the road's length: a road bulging more is a curve, not a leaning street
#: snapping tolerance (degrees) at gridness 0 and its growth per unit of gridness: the style
#: presets' gridness 0.07 (organic), 0.31 (mixed, radial), 0.67 (grid) give 14°, 20°, 30°
TOLERANCE_DEG, TOLERANCE_PER_GRIDNESS = 12.0, 27.0
POSITION_DECIMALS = 6  # of a metre: far below anything that matters, far above last bits


def snap_tolerance_deg(gridness: float) -> float:
    return TOLERANCE_DEG + TOLERANCE_PER_GRIDNESS * min(max(gridness, 0.0), 1.0)


def square_up(G: nx.Graph, gridness: float) -> int:
    """Snap the roads of skeleton graph ``G`` (RoadGraph convention, changed in place) to the
    local street axes; returns how many roads were snapped."""
    edges = sorted((u, v) for u, v in G.edges if u != v)
    if not edges:
        return 0
    nodes = sorted(G.nodes)
    index = {n: i for i, n in enumerate(nodes)}
    before = np.array([G.nodes[n]["xy"] for n in nodes], dtype=float)
    ends = np.array([[index[u], index[v]] for u, v in edges])
    chord = before[ends[:, 1]] - before[ends[:, 0]]
    length = np.hypot(*chord.T)
    # rounded (``portable``): which roads snap must not depend on the CPU's last bits
    angle = portable(np.arctan2(chord[:, 1], chord[:, 0]))
    axis = portable(_local_axes(before[ends].mean(axis=1), length, angle))
    off_axis = (angle - axis + math.pi / 4) % (math.pi / 2) - math.pi / 4
    bulge = np.array([shapely.hausdorff_distance(shapely.LineString(G.edges[e]["coords"]),
                                                 shapely.LineString(before[ends[k]]))
                      for k, e in enumerate(edges)])
    snap = ((np.abs(off_axis) < math.radians(snap_tolerance_deg(gridness))) & (length > 1.0)
            & (bulge <= MAX_BULGE * length))
    after = portable(_aligned_positions(before, ends[snap], angle[snap] - off_axis[snap],
                                        ANGLE_WEIGHT_M / length[snap]), POSITION_DECIMALS)
    for n, xy in zip(nodes, after, strict=True):
        G.nodes[n]["xy"] = xy
    for k, (u, v) in enumerate(edges):
        data = G.edges[u, v]
        a, b = (u, v) if data["start"] == u else (v, u)
        if snap[k]:
            data["coords"] = np.array([after[index[a]], after[index[b]]])
        else:
            coords = np.asarray(data["coords"], dtype=float)
            step = np.hypot(*np.diff(coords, axis=0).T)
            t = np.concatenate([[0.0], np.cumsum(step)]) / max(step.sum(), 1e-9)
            moved_a, moved_b = (after - before)[[index[a], index[b]]]
            data["coords"] = coords + np.outer(1 - t, moved_a) + np.outer(t, moved_b)
    return int(snap.sum())


def _local_axes(points: np.ndarray, length: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """The dominant axis angle (mod 90°) around each point: the roads' length-weighted
    exp(4iθ) summed on a grid of AXIS_CELL_M cells, Gaussian-smoothed, read at the point."""
    lo = points.min(axis=0)
    cells = np.floor((points - lo) / AXIS_CELL_M).astype(int)
    shape = tuple(cells.max(axis=0)[::-1] + 1)
    z = length * np.exp(4j * angle)
    sigma = AXIS_SIGMA_M / AXIS_CELL_M
    parts = []
    for part in (z.real, z.imag):
        grid = np.zeros(shape)
        np.add.at(grid, (cells[:, 1], cells[:, 0]), part)
        parts.append(gaussian_filter(grid, sigma, mode="constant")[cells[:, 1], cells[:, 0]])
    return np.arctan2(parts[1], parts[0]) / 4


def _aligned_positions(xy: np.ndarray, ends: np.ndarray, axis: np.ndarray,
                       weight: np.ndarray) -> np.ndarray:
    """Node positions that make each road ``ends[k]`` run along ``axis[k]`` (its offset across
    the axis, times ``weight[k]``, near 0) while every node stays near ``xy`` (ANCHOR): the
    normal equations of that linear least-squares problem, solved directly."""
    n, m = len(xy), len(ends)
    normal = np.column_stack([-np.sin(axis), np.cos(axis)]) * weight[:, None]
    rows = np.repeat(np.arange(m), 4)
    cols = np.column_stack([2 * ends[:, 1], 2 * ends[:, 1] + 1,
                            2 * ends[:, 0], 2 * ends[:, 0] + 1]).ravel()
    vals = np.column_stack([normal, -normal]).ravel()
    A = coo_matrix((vals, (rows, cols)), shape=(m, 2 * n)).tocsc()
    lhs = (A.T @ A + ANCHOR**2 * identity(2 * n)).tocsc()
    return spsolve(lhs, ANCHOR**2 * xy.ravel()).reshape(n, 2)

