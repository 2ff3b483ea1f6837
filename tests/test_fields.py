"""Tensor fields, the streamline tracer and A* reconnection on hand-made inputs."""

import math

import numba.core.caching
import numpy as np
import pytest

from roadweaver_sumo.compiled import F8, compiled
from roadweaver_sumo.expand.planar import build_planar_graph
from roadweaver_sumo.expand.reconnect import reconnect_dangles
from roadweaver_sumo.streamlines import (
    GrowthParams,
    SegmentIndex,
    choose_axis,
    clamp_turn,
    follow_field,
    trace,
)
from roadweaver_sumo.tensor_field import TensorField, blend, from_angles, structure_tensor


def uniform_field(theta: float, shape=(50, 50), res=10.0) -> TensorField:
    return from_angles(np.full(shape, theta), np.ones(shape), res)


def test_structure_tensor_follows_skeleton_tangents():
    xs = np.linspace(50, 450, 41)
    points = np.column_stack([xs, np.full_like(xs, 250.0)])
    tangents = np.tile([1.0, 0.0], (len(xs), 1))
    field, support = structure_tensor(points, tangents, (50, 50), 10.0, sigma=60, radius=180)
    assert abs(field.major(250, 300)[1]) < 1e-6  # horizontal next to a horizontal road
    assert support[25, 25] > 0 and support[0, 0] == 0  # no support beyond the radius


def test_tangents_of_opposite_sign_do_not_cancel():
    points = np.array([[100.0, 100.0], [100.0, 100.0]])
    tangents = np.array([[0.0, 1.0], [0.0, -1.0]])
    field, _ = structure_tensor(points, tangents, (20, 20), 10.0, sigma=30, radius=90)
    assert np.allclose(np.abs(choose_axis(field, (100, 110), np.array([0.1, 1.0]))), [0, 1])
    assert math.isclose(field.anisotropy(100, 110), 1.0)


def test_streets_of_a_skewed_crossroads_average_to_their_own_axes_not_the_diagonal():
    """Two streets crossing at 88°: averaged as tensors (2θ) they nearly cancel to the
    diagonal between them (-44°), and a fill road in that block ran diagonally."""
    skew = math.radians(88.0)
    points = np.array([[100.0, 100.0], [100.0, 100.0]])
    tangents = np.array([[1.0, 0.0], [math.cos(skew), math.sin(skew)]])
    field, _ = structure_tensor(points, tangents, (20, 20), 10.0, sigma=30, radius=90)
    for wanted in ([1.0, 0.1], [0.1, 1.0]):
        axis = choose_axis(field, (100, 110), np.array(wanted))
        assert math.degrees(math.acos(abs(axis @ np.array(wanted) / np.hypot(*wanted)))) < 8.0
    assert field.anisotropy(100, 110) > 0.99


def test_blending_a_grid_with_its_own_turned_copy_keeps_the_grid():
    horizontal, vertical = uniform_field(0.0), uniform_field(math.pi / 2)
    mixed = blend(horizontal, np.full((50, 50), 0.5), vertical)
    assert math.isclose(mixed.anisotropy(250, 250), 1.0)
    assert np.allclose(np.abs(choose_axis(mixed, (250, 250), np.array([1.0, 0.2]))), [1, 0])


def test_clamp_limits_the_turn():
    d = clamp_turn(np.array([1.0, 0.0]), np.array([0.0, 1.0]), math.radians(15))
    assert math.isclose(math.degrees(math.atan2(d[1], d[0])), 15.0)


def test_compiled_field_steps_match_the_python_steps_bit_for_bit():
    """Fill roads follow the field through compiled steps; a different last bit anywhere
    would change every map made since, so they are checked against the Python operations."""
    rng = np.random.default_rng(1)
    field = from_angles(rng.uniform(0, np.pi, (40, 60)), np.ones((40, 60)), 10.0)
    start, d = (123.4, 201.7), np.array([0.6, 0.8])
    steps, last = follow_field(field, start, d, 50, math.radians(8.0), 20.0)
    x, y = start
    for k in range(50):
        d = clamp_turn(d, choose_axis(field, (x, y), d), math.radians(8.0))
        x, y = x + 20.0 * float(d[0]), y + 20.0 * float(d[1])
        assert (steps[k, 0], steps[k, 1]) == (x, y)
    assert tuple(last) == (d[0], d[1])


def test_front_snaps_onto_a_crossing_road_and_stops_at_the_border():
    index = SegmentIndex()
    index.add(np.array([[300.0, 0.0], [300.0, 500.0]]), road_id=0)
    params = GrowthParams(jitter=0.0)
    rng = np.random.default_rng(0)
    hit = trace(np.array([100.0, 250.0]), np.array([1.0, 0.0]), uniform_field(0.0), index,
                (500, 500), params, rng)
    assert hit.end == "snap" and np.allclose(hit.coords[-1], [300.0, 250.0])
    away = trace(np.array([200.0, 250.0]), np.array([-1.0, 0.0]), uniform_field(0.0), index,
                 (500, 500), params, rng)
    assert away.end == "boundary" and math.isclose(away.coords[-1][0], 0.0, abs_tol=1e-9)


def test_front_running_alongside_a_road_is_blocked():
    index = SegmentIndex()
    index.add(np.array([[0.0, 270.0], [500.0, 270.0]]), road_id=0)
    tr = trace(np.array([100.0, 250.0]), np.array([1.0, 0.0]), uniform_field(0.0), index,
               (500, 500), GrowthParams(jitter=0.0, parallel_gap=40.0), np.random.default_rng(0))
    assert tr.end == "blocked"


def test_front_ignores_its_own_road_only_for_the_first_metres():
    index = SegmentIndex()
    index.add(np.array([[0.0, 250.0], [500.0, 250.0]]), road_id=7)  # the road it starts on
    index.add(np.array([[400.0, 0.0], [400.0, 500.0]]), road_id=8)
    params = GrowthParams(jitter=0.0, parallel_gap=40.0)
    seeded = trace(np.array([100.0, 250.0]), np.array([1.0, 0.0]), uniform_field(0.0), index,
                   (500, 500), params, np.random.default_rng(0), frozenset([7]), 30.0)
    assert seeded.end == "blocked" and len(seeded.coords) == 4  # sees road 7 after 30 m
    blind = trace(np.array([100.0, 250.0]), np.array([1.0, 0.0]), uniform_field(0.0), index,
                  (500, 500), params, np.random.default_rng(0), frozenset([7]), 1000.0)
    assert blind.end == "snap" and np.allclose(blind.coords[-1], [400.0, 250.0])


def test_a_trace_draws_one_jitter_value_per_step():
    """The jitter is drawn ahead in a batch; the generator must still end where one draw per
    step leaves it, or every later road of the map would change with the batch size."""
    index = SegmentIndex()
    params = GrowthParams(jitter=2.0, max_length=300.0)
    rng = np.random.default_rng(3)
    tr = trace(np.array([20.0, 250.0]), np.array([1.0, 0.0]), uniform_field(0.0), index,
               (500, 500), params, rng)
    assert tr.end == "length" and len(tr.coords) == 31
    reference = np.random.default_rng(3)
    reference.normal(0.0, 2.0, size=30)
    assert rng.normal() == reference.normal()


def test_segment_index_grows_to_roads_outside_its_grid():
    index = SegmentIndex(cell=50.0)
    index.add(np.array([[10.0, 10.0], [40.0, 10.0]]), road_id=0)
    index.add(np.array([[-900.0, 5000.0], [-700.0, 5000.0]]), road_id=1)
    assert list(index.near(np.array([25.0, 10.0]), 5.0)) == [0]
    assert list(index.road[index.near(np.array([-800.0, 5010.0]), 20.0)]) == [1]
    assert len(index.near(np.array([2000.0, 2000.0]), 20.0)) == 0


def test_a_star_links_a_dangling_end_to_the_nearest_road():
    roads = [(np.array([[0.0, 100.0], [400.0, 100.0]]), "arterial"),
             (np.array([[200.0, 100.0], [200.0, 160.0]]), "local"),
             (np.array([[0.0, 260.0], [400.0, 260.0]]), "arterial")]
    G = build_planar_graph(roads, 400, 400)
    cost = np.ones((40, 40))
    links = reconnect_dangles(G, cost, 10.0, radius=200.0, margin=30.0)
    assert len(links) == 1
    start, end = links[0][0], links[0][-1]
    assert np.allclose(start, [200.0, 160.0])
    assert math.isclose(end[1], 260.0, abs_tol=1e-6)  # ends exactly on the other road


def test_components_joined_by_pending_links_get_no_second_link():
    """Dead-end links and component links are noded into the graph together: a component
    whose dead end already has a pending link onto the main component needs no link of its
    own, one without gets one (onto a main road or a pending link of the main one)."""
    from roadweaver_sumo.expand.reconnect import link_components
    from roadweaver_sumo.skeleton.model import perimeter

    square = np.array([[150.0, 150.0], [250.0, 150.0], [250.0, 250.0], [150.0, 250.0],
                       [150.0, 150.0]])
    tail = np.array([[250.0, 200.0], [300.0, 200.0]])  # its dead end at x 300
    roads = [(perimeter(400, 400), "collector"), (square, "local"), (tail, "local")]
    G = build_planar_graph(roads, 400, 400)
    cost = np.ones((40, 40))
    pending = [np.array([[300.0, 200.0], [385.0, 200.0]])]  # onto the ring's east side
    assert link_components(G, cost, 10.0, radius=200.0, pending=pending) == []
    assert len(link_components(G, cost, 10.0, radius=200.0)) == 1


def test_line_samples_lie_on_their_lines_evenly_spaced():
    """Growth seeds and raster cells come from points sampled along the roads: on the line,
    ``spacing`` apart along it from its start, with the unit tangent of the piece they lie on
    (zero-length pieces, which have none, skipped); every cell a line passes through is hit."""
    from shapely import LineString

    from roadweaver_sumo.expand.growth import _samples_each
    from roadweaver_sumo.raster import polyline_cells_each

    rng = np.random.default_rng(9)
    lines = [np.cumsum(rng.normal(size=(int(rng.integers(2, 9)), 2))
                       * rng.choice([0.0, 1e-10, 0.3, 30.0]), axis=0) + 500.0 for _ in range(300)]
    pts, tans, cuts = _samples_each(lines, 0.7)
    assert np.allclose(np.linalg.norm(tans, axis=1), 1.0)
    for line, a, b in zip(lines, cuts[:-1], cuts[1:], strict=True):
        shape = LineString(line)
        assert b - a == (len(np.arange(0.0, shape.length, 0.7)) if shape.length > 1e-8 else 0)
        along = [shape.project(shapely_point(p)) for p in pts[a:b]]
        assert np.allclose(along, 0.7 * np.arange(b - a), atol=1e-6)
        assert all(shape.distance(shapely_point(p)) < 1e-6 for p in pts[a:b])
    (i, j), = polyline_cells_each([np.array([[12.0, 31.0], [188.0, 31.0]])], (200, 200), 5.0)
    assert set(i) == {6} and set(j) == set(range(2, 38))


def shapely_point(xy):
    from shapely import Point

    return Point(*xy)


def test_junctions_placed_on_a_rectangular_field():
    """Junction placement reads a heat window clipped to the field's own rows and columns: a
    learned skeleton of a rectangular map has a field that is not square."""
    from roadweaver_sumo.data.vectorise import place_junctions, skeleton_graph

    res, rows, cols = 10.0, 40, 10
    mask = np.zeros((rows, cols), bool)
    mask[:, 8] = True  # a road near the right edge
    mask[30, :9] = True  # a side road meeting it
    G = skeleton_graph(mask, res, cols * res, "arterial")
    yy, xx = np.mgrid[0:rows, 0:cols]
    heat = np.exp(-0.5 * ((xx - 8) ** 2 + (yy - 30) ** 2))
    junctions = [n for n, d in G.degree() if d >= 3]
    assert junctions
    place_junctions(G, heat, res)
    for n in junctions:
        assert np.hypot(G.nodes[n]["xy"][0] - 85.0, G.nodes[n]["xy"][1] - 305.0) < res


def test_compiled_functions_work_where_no_cache_can_be_written(monkeypatch):
    """A read-only install with no writable cache directory must still import: numba then
    refuses to cache, and the function is compiled uncached instead."""
    monkeypatch.setattr(numba.core.caching.CacheImpl, "_locator_classes", [])

    def add_one(x):
        return x + 1.0

    with pytest.raises(RuntimeError, match="cannot cache"):
        numba.njit(F8(F8), cache=True)(add_one)
    assert compiled(F8(F8))(add_one)(1.5) == 2.5
