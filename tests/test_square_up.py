"""Squaring up the learned skeleton (issue 35): raster noise out, real curves kept."""

import math

import numpy as np

from roadweaver_sumo.roadgraph import add_road, new_road_graph
from roadweaver_sumo.skeleton.square_up import snap_tolerance_deg, square_up


def _jittered_grid(jitter: float, bulge: float = 0.0, seed: int = 0):
    """A 6 x 6 grid of 100 m blocks turned by 20°, junctions moved up to ``jitter`` metres,
    each road bowed sideways by ``bulge`` of its length at its middle."""
    rng = np.random.default_rng(seed)
    turn = np.array([[math.cos(0.35), -math.sin(0.35)], [math.sin(0.35), math.cos(0.35)]])
    G = new_road_graph(1000.0, 1000.0)
    for i in range(6):
        for j in range(6):
            xy = turn @ np.array([100.0 * i, 100.0 * j]) + 300 + rng.uniform(-jitter, jitter, 2)
            G.add_node((i, j), xy=tuple(xy))
    for i in range(6):
        for j in range(6):
            for di, dj in ((1, 0), (0, 1)):
                if i + di < 6 and j + dj < 6:
                    a, b = np.array(G.nodes[(i, j)]["xy"]), np.array(G.nodes[(i + di, j + dj)]["xy"])
                    side = np.array([-(b - a)[1], (b - a)[0]])
                    add_road(G, (i, j), (i + di, j + dj), [a, (a + b) / 2 + bulge * side, b],
                             "local")
    return G


def _off_axis_deg(G) -> np.ndarray:
    """Each road's chord angle from the grid's axes, in degrees."""
    out = []
    for u, v in G.edges:
        d = np.subtract(G.nodes[v]["xy"], G.nodes[u]["xy"])
        a = (math.degrees(math.atan2(d[1], d[0])) - 20.05) % 90
        out.append(min(a, 90 - a))
    return np.array(out)


def test_a_noisy_grid_is_squared_up_and_its_roads_straightened():
    G = _jittered_grid(jitter=8.0)
    before = {n: np.array(G.nodes[n]["xy"]) for n in G}
    assert _off_axis_deg(G).max() > 6
    assert square_up(G, gridness=0.67) == G.number_of_edges()
    assert _off_axis_deg(G).max() < 1.5
    moved = [np.hypot(*(np.array(G.nodes[n]["xy"]) - before[n])) for n in G]
    assert max(moved) < 15
    for u, v in G.edges:  # straight, ends on the nodes
        coords = G.edges[u, v]["coords"]
        assert len(coords) == 2
        assert {tuple(coords[0]), tuple(coords[-1])} == {tuple(G.nodes[u]["xy"]),
                                                        tuple(G.nodes[v]["xy"])}


def test_curved_roads_keep_their_shape_and_follow_their_ends():
    G = _jittered_grid(jitter=8.0, bulge=0.3)
    assert square_up(G, gridness=0.67) == 0
    for u, v in G.edges:
        coords = G.edges[u, v]["coords"]
        assert len(coords) == 3
        assert np.allclose(coords[[0, -1]], [G.nodes[G.edges[u, v]["start"]]["xy"],
                                              G.nodes[v if G.edges[u, v]["start"] == u else u]["xy"]])


def test_the_tolerance_follows_the_gridness_asked_for():
    """A grid is squared up harder than an organic town: a road 17° off its axis snaps in the
    grid preset (gridness 0.67) and not in the organic one (0.07)."""
    assert snap_tolerance_deg(0.07) < 17 < snap_tolerance_deg(0.67)
    assert snap_tolerance_deg(5.0) == snap_tolerance_deg(1.0)
