"""One-way streets (hdmap/one_way.py): long straight local streets, neighbours in opposite
directions, never at the cost of a place that cannot be reached; and what SUMO makes of them."""

from __future__ import annotations

import itertools

import networkx as nx
import numpy as np
import pytest
from shapely.geometry import LineString, Point
from test_hdmap import _graph

from roadweaver_sumo.export.map_files import write_map_files
from roadweaver_sumo.hdmap import build_hdmap, hdmap_metrics
from roadweaver_sumo.validate.netgraph import load_net


def local_grid(n: int = 5, block: float = 100.0) -> nx.Graph:
    """``n`` x ``n`` nodes, ``block`` m apart: a collector frame around local streets."""
    nodes = {n * i + j: (block * (j + 1), block * (i + 1)) for i in range(n) for j in range(n)}
    roads = []
    for i in range(n):
        for j in range(n):
            a = n * i + j
            if j < n - 1:
                roads.append((a, a + 1, "collector" if i in (0, n - 1) else "local"))
            if i < n - 1:
                roads.append((a, a + n, "collector" if j in (0, n - 1) else "local"))
    return _graph(nodes, roads, size=block * (n + 1))


@pytest.fixture(scope="module")
def hd():
    return build_hdmap(local_grid(), (48.137, 11.575), one_way_share=1.0)


def test_one_way_streets_are_whole_streets_in_alternating_directions(hd):
    """Every local street of the grid (3 rows, 3 columns of 4 blocks) is one-way along its
    whole length, and neighbouring parallel streets run opposite ways (one-way pairs)."""
    streets: dict = {}
    for road in hd.roads.values():
        assert road.one_way == (road.road_class == "local")
        if road.one_way:
            ahead = road.centreline[-1] - road.centreline[0]
            horizontal = abs(ahead[0]) > abs(ahead[1])
            across = road.centreline[0][1] if horizontal else road.centreline[0][0]
            streets.setdefault((horizontal, round(float(across))), set()).add(
                tuple(np.sign(ahead).astype(int)))
    assert len(streets) == 6
    for horizontal in (True, False):
        ordered = [streets[k] for k in sorted(k for k in streets if k[0] == horizontal)]
        assert all(len(d) == 1 for d in ordered), "one direction along the whole street"
        ordered = [next(iter(d)) for d in ordered]
        assert all(np.dot(p, q) < 0 for p, q in itertools.pairwise(ordered)), ordered


def test_the_share_caps_the_one_way_length():
    hd = build_hdmap(local_grid(), (48.137, 11.575), one_way_share=0.4)
    local = [r for r in hd.roads.values() if r.road_class == "local"]
    assert sum(r.one_way for r in local) == 8  # two streets of four blocks: 33 % of 24 blocks


def test_one_way_roads_have_lanes_one_way_centred_and_everything_stays_reachable(hd):
    metrics = hdmap_metrics(hd)
    assert metrics["strongly_connected"] and metrics["lane_reachability"] == 1.0
    for road in (r for r in hd.roads.values() if r.one_way):
        assert road.lanes("b") == [] and len(road.lanes("f")) == 1
        lane = hd.lanes[road.lanes("f")[0]]
        assert np.allclose(lane.centre, road.reference[0], atol=1e-9), "centred"
        width = np.linalg.norm(lane.left - lane.right, axis=1)
        assert np.allclose(width, lane.width)


def test_sumo_builds_one_edge_per_one_way_road_where_the_hd_map_has_it(hd, tmp_path):
    files = write_map_files(hd, tmp_path)
    net = load_net(files["sumo"])
    for road in hd.roads.values():
        assert net.hasEdge(f"r{road.id}_f")
        assert net.hasEdge(f"r{road.id}_b") != road.one_way
        if road.one_way:
            shape = net.getEdge(f"r{road.id}_f").getLane(0).getShape()
            centre = LineString(hd.lanes[road.lanes("f")[0]].centre)
            assert max(centre.distance(Point(p)) for p in shape) < 0.05, "same lane, centred"


def test_no_one_way_share_keeps_every_road_two_way():
    hd = build_hdmap(local_grid(), (48.137, 11.575))
    assert not any(r.one_way for r in hd.roads.values())
