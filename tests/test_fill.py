"""The density fill's block splitting: faster formulations must give the same blocks."""

import numpy as np
import shapely
from shapely.geometry import LineString, Polygon

from roadweaver_sumo.expand import MIN_EDGE
from roadweaver_sumo.expand.block_split import _joined_roads, _off_ring, split_face
from roadweaver_sumo.expand.chord_insert import insert_chord
from roadweaver_sumo.expand.edge_index import EdgeIndex
from roadweaver_sumo.expand.fill import faces
from roadweaver_sumo.expand.node_points import NodePoints
from roadweaver_sumo.expand.planar import build_planar_graph
from roadweaver_sumo.roadgraph import new_road_graph


def test_off_ring_drops_only_the_roads_made_of_ring_segments():
    """A road along the ring on its vertices (either way round) adds nothing to node; one with
    a vertex of its own on the ring, one that leaves it, or one inside must stay."""
    ring = Polygon([(0, 0), (0, 400), (800, 400), (800, 0)]).exterior
    along = LineString([(0, 0), (0, 400), (800, 400)])
    backwards = LineString([(800, 0), (800, 400)])
    new_vertex = LineString([(0, 0), (0, 200), (0, 400)])
    leaving = LineString([(0, 400), (800, 400), (900, 400)])
    inside = LineString([(400, 0), (400, 300)])
    lines = [along, new_vertex, backwards, leaving, inside]
    assert _off_ring(ring, lines) == [new_vertex, leaving, inside]


def test_split_face_with_a_dead_end_matches_noding_every_road():
    """A chord ending on a dead end inside the block: the two blocks come out exactly (same
    vertices, order and start) as when every road in the block is noded too: its own edge
    roads and the dead ends the chord is not joined to (two trees, one from each side)."""
    ring = np.array([[0, 0], [800, 0], [800, 400], [0, 400], [0, 0]], float)
    dead_end = np.array([[0, 150], [600, 150]], float)
    others = [np.array([[800, 300], [500, 300], [500, 220]], float),
              np.array([[500, 300], [450, 350]], float),
              np.array([[100, 0], [100, 100]], float)]
    G = build_planar_graph([(ring, "collector"), (dead_end, "local")]
                           + [(road, "local") for road in others], 1000, 1000)
    (block,) = faces(G)
    index = EdgeIndex(G)
    chord = np.array([[300.0, 150.0], [300.0, 275.0], [300.0, 400.0]])
    ends = insert_chord(G, chord, MIN_EDGE, index)
    assert ends is not None
    parts = split_face(block, chord, ends, index)
    assert len(parts) == 2
    everything = [index.lines[key] for key in index.near(block, 0.0)]
    noded = shapely.union_all([block.exterior, *block.interiors, *everything])
    found = shapely.get_parts(shapely.polygonize(shapely.get_parts(noded)))
    expected = [p for p in found if p.area > 1.0 and block.contains(p.representative_point())]
    assert [shapely.to_wkb(p) for p in parts] == [shapely.to_wkb(p) for p in expected]


def test_joined_roads_are_those_reachable_from_the_chord_ends():
    """Two trees and a road of their own: only the roads reachable from the ends count, in
    the order given."""
    roads = [(7, 8), (1, 2), (4, 5), (2, 3), (5, 6), (3, 9)]
    assert _joined_roads(roads, (1, 6)) == [(1, 2), (4, 5), (2, 3), (5, 6), (3, 9)]
    assert _joined_roads(roads, (9,)) == [(1, 2), (2, 3), (3, 9)]
    assert _joined_roads(roads, (10,)) == []


def test_nodes_near_a_long_ring_are_found_as_by_measuring_every_one():
    """A long block boundary with many nodes near it: the prepared ring only picks candidates;
    the nodes found must be those whose distance to the ring is within the tolerance, also
    those near it, and nodes added since the tree was built."""
    angle = np.linspace(0.0, 2 * np.pi, 2001)
    face = Polygon(np.column_stack([1000 * np.cos(angle), 700 * np.sin(angle)]))
    coords = shapely.get_coordinates(face.exterior)
    rng = np.random.default_rng(0)
    on_ring = coords[rng.integers(0, len(coords) - 1, 300)]
    offsets = rng.choice([0.0, 0.005, 0.0099, 0.0101, 0.02, 5.0], (300, 1))
    pts = np.vstack([on_ring + offsets * rng.normal(size=(300, 2)) / np.sqrt(2),
                     rng.uniform(-1000, 1000, (300, 2))])
    G = new_road_graph(3000, 3000)
    for n, xy in enumerate(pts[:500]):
        G.add_node(n, xy=(float(xy[0]), float(xy[1])))
    nodes = NodePoints(G)
    for n, xy in enumerate(pts[500:], start=500):
        G.add_node(n, xy=(float(xy[0]), float(xy[1])))
    nodes.update()
    direct = np.flatnonzero(shapely.distance(face.exterior, shapely.points(pts)) <= 0.01)
    assert 0 < len(direct) < len(pts)
    assert [n for n, _ in nodes.on_boundary(face)] == sorted(direct)


def test_a_large_fill_reaches_its_density_without_crossings():
    """A fill of a few hundred road nodes (a 3 x 2.5 km map at density 40) meets its target
    within 2.5 % and leaves every crossing a junction."""
    from roadweaver_sumo import metrics
    from roadweaver_sumo.expand import expand_skeleton
    from roadweaver_sumo.skeleton import make_skeleton
    from roadweaver_sumo.spec import ScenarioSpec

    spec = ScenarioSpec(density=40, vehicles=10, width=3000, height=2500, seed=4,
                        skeleton="procedural")
    G = expand_skeleton(spec, make_skeleton(spec))
    target = spec.target_road_nodes
    assert abs(metrics.road_node_count(G) - target) <= 0.025 * target
    assert metrics.crossings_without_junction(G) == 0
