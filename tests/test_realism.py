"""Realism statistics (issue 35) on small graphs whose answers are known by hand."""

from __future__ import annotations

import math
from itertools import pairwise
from pathlib import Path

import pytest

from roadweaver_sumo.realism import COMPARED, realism_statistics, stroke_lengths
from roadweaver_sumo.roadgraph import add_road, new_road_graph

SIZE = 2000.0


def graph_of(roads, size: float = SIZE):
    """A RoadGraph from polylines; points closer than 1 mm are the same node."""
    G = new_road_graph(size, size)
    ids: dict = {}

    def node(p):
        key = (round(p[0], 3), round(p[1], 3))
        if key not in ids:
            ids[key] = len(ids)
            G.add_node(ids[key], xy=(float(p[0]), float(p[1])))
        return ids[key]

    for line in roads:
        for a, b in pairwise(line):  # one road per stretch between listed points
            add_road(G, node(a), node(b), [a, b], "local")
    return G


def cut_grid():
    """Four streets each way at 250, 750, 1250, 1750 m running off a 2 km map, as if cut out
    of a larger grid: 16 crossings, 16 dead ends on the border."""
    at = (250.0, 750.0, 1250.0, 1750.0)
    xs = (0.0,) + at + (SIZE,)
    return graph_of([[(x, y) for y in xs] for x in at] + [[(x, y) for x in xs] for y in at])


def test_cut_grid_is_all_crossings_away_from_the_border():
    s = realism_statistics(cut_grid())
    assert s["four_way_share"] == pytest.approx(0.5)  # 16 crossings, 16 cut ends
    assert s["dead_end_share"] == pytest.approx(0.5)
    assert s["four_way_share_inner"] == 1.0
    assert s["dead_end_share_inner"] == 0.0
    assert s["cycle_share_inner"] == 1.0
    assert s["bearing_entropy"] == pytest.approx(math.log(4))
    assert s["right_angle_share_inner"] == 1.0
    assert s["acute_angle_share_inner"] == 0.0
    assert s["straight_through_share_inner"] == 1.0
    assert s["stroke_length_median"] == pytest.approx(SIZE)  # every street crosses the map
    assert s["block_area_median_inner"] == pytest.approx(500.0**2)  # 9 closed blocks
    assert s["block_compactness_median_inner"] == pytest.approx(math.pi / 4)
    assert s["small_block_share_inner"] == 0.0
    assert s["circuity"] == pytest.approx(1.0)
    assert s["turning_per_km"] == pytest.approx(0.0)
    assert s["frame_share"] == 0.0
    assert s["length_cv"] == pytest.approx(0.0, abs=1e-9)  # one street each way per cell
    assert s["edge_length_p50"] == pytest.approx(500.0)
    assert s["density"] == pytest.approx(32 / 4.0)
    assert set(COMPARED) <= set(s)


def test_ring_road_along_the_border_is_all_frame():
    m = 10.0
    ring = [(m, m), (SIZE - m, m), (SIZE - m, SIZE - m), (m, SIZE - m), (m, m)]
    s = realism_statistics(graph_of([ring]))
    assert s["frame_share"] == pytest.approx(1.0)
    # the same ring 100 m inside is no frame road
    inset = [(x + 90 * (1 if x < SIZE / 2 else -1), y + 90 * (1 if y < SIZE / 2 else -1))
             for x, y in ring]
    assert realism_statistics(graph_of([inset]))["frame_share"] == 0.0


def test_cul_de_sac_counts_as_dead_end_only_inside():
    main = [(0.0, 1000.0), (1000.0, 1000.0), (SIZE, 1000.0)]
    side = [(1000.0, 1000.0), (1000.0, 1200.0)]
    s = realism_statistics(graph_of([main, side]))
    assert s["dead_end_share"] == pytest.approx(3 / 4)  # two cut ends and the cul-de-sac
    assert s["dead_end_share_inner"] == pytest.approx(1 / 2)  # the cul-de-sac and the T
    assert s["three_way_share_inner"] == pytest.approx(1 / 2)
    assert s["cycle_share"] == 0.0
    assert s["straight_through_share_inner"] == pytest.approx(2 / 3)  # the side street is not


def test_straight_road_through_three_junctions_is_one_stroke():
    junctions = [(500.0, 1000.0), (1000.0, 1000.0), (1500.0, 1000.0)]
    main = [(0.0, 1000.0), *junctions, (SIZE, 1000.0)]
    sides = [[p, (p[0], 1300.0)] for p in junctions]
    G = graph_of([main, *sides])
    assert sorted(stroke_lengths(G).round(6)) == [300.0, 300.0, 300.0, SIZE]
    assert realism_statistics(G)["stroke_length_median"] == pytest.approx(SIZE)


def test_a_road_that_turns_at_a_junction_ends_its_stroke():
    bend = (1000.0, 1000.0)
    main = [(0.0, 1000.0), bend, (SIZE, 1000.0 + 1000.0 * math.tan(math.radians(30)))]
    side = [bend, (1000.0, 1300.0)]
    lengths = sorted(stroke_lengths(graph_of([main, side])))
    assert len(lengths) == 3  # 30° off straight: west, east and side street apart


CGCC = Path(__file__).resolve().parents[2] / "shared" / "data" / "cgcc"


@pytest.mark.skipif(not (CGCC / "labels.csv").is_file(), reason="needs ../shared/data/cgcc")
def test_a_real_grid_city_has_more_crossings_than_an_organic_one():
    import csv

    from roadweaver_sumo.data.graphml import read_graphml

    with open(CGCC / "labels.csv", newline="") as f:
        rows = list(csv.DictReader(f))  # columns: file, layout
    pick = {lab: next(r["file"] for r in rows if r["layout"] == lab) for lab in ("grid", "organic")}
    stats = {lab: realism_statistics(read_graphml(CGCC / name)) for lab, name in pick.items()}
    assert stats["grid"]["four_way_share_inner"] > stats["organic"]["four_way_share_inner"]
