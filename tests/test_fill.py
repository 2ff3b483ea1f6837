"""The density fill's block splitting: faster formulations must give the same blocks."""

import networkx as nx
import numpy as np
import shapely
from shapely.geometry import LineString, Polygon

from roadweaver_sumo.expand import MIN_EDGE
from roadweaver_sumo.expand.edge_index import EdgeIndex, edge_key
from roadweaver_sumo.expand.fill import (
    _joined_roads,
    _NodePoints,
    _off_ring,
    _split_face,
    faces,
    insert_chord,
)
from roadweaver_sumo.expand.planar import build_planar_graph
from roadweaver_sumo.roadgraph import add_road, new_road_graph


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
    parts = _split_face(block, chord, ends, index)
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
    nodes = _NodePoints(G)
    for n, xy in enumerate(pts[500:], start=500):
        G.add_node(n, xy=(float(xy[0]), float(xy[1])))
    nodes.update()
    direct = np.flatnonzero(shapely.distance(face.exterior, shapely.points(pts)) <= 0.01)
    assert 0 < len(direct) < len(pts)
    assert [n for n, _ in nodes.on_boundary(face)] == sorted(direct)


def test_substring_matches_shapely_bit_for_bit():
    """The fill's own substring gives shapely.ops.substring's coordinates exactly, for pieces
    from the start, in the middle, to the end, empty ones and ones past the end."""
    from roadweaver_sumo.expand.fill import _substring

    rng = np.random.default_rng(1)
    line = LineString(np.cumsum(rng.normal(size=(40, 2)) * 7.3, axis=0))
    length = line.length
    vertex = float(line.project(shapely.Point(line.coords[5])))
    cases = [(0.0, 13.7), (2.0, length), (vertex, length), (0.0, vertex), (5.5, 5.5),
             (0.0, 0.0), (length, length), (length + 1.0, length + 2.0), (length + 1.0, length + 1.0),
             (3.0, 1.0)]
    cases += [tuple(sorted(rng.uniform(0, length, 2))) for _ in range(50)]
    for start, end in cases:
        expected = np.asarray(shapely.ops.substring(line, start, end).coords)
        got = _substring(line, start, end)
        assert got.shape == expected.shape and got.tobytes() == expected.tobytes(), (start, end)


def test_pieces_of_a_line_are_its_substrings():
    """Cutting a road in two at once gives exactly the two substrings (split_edge_at)."""
    from roadweaver_sumo.expand.fill import _pieces

    rng = np.random.default_rng(2)
    line = LineString(np.cumsum(rng.normal(size=(60, 2)) * 9.1, axis=0))
    vertex = float(line.project(shapely.Point(line.coords[7])))
    for s in [vertex, 12.0, line.length / 2, *rng.uniform(1.0, line.length - 1.0, 30)]:
        pieces = _pieces(line, [0, s, line.length])
        for piece, (a, b) in zip(pieces, [(0, s), (s, line.length)], strict=True):
            expected = np.asarray(shapely.ops.substring(line, a, b).coords)
            assert piece.shape == expected.shape and piece.tobytes() == expected.tobytes()


def test_fill_in_two_groups_is_planar_and_the_same_with_or_without_a_child(monkeypatch):
    """A map filled in two groups of blocks side by side (here from 100 road nodes on, as a
    10 km map is) reaches its density, has no crossing without a junction, and is the same
    graph whether the second group ran in a forked child or in this process on a copy."""
    import hashlib

    from roadweaver_sumo import forked, metrics
    from roadweaver_sumo.expand import expand_skeleton, fill
    from roadweaver_sumo.skeleton import make_skeleton
    from roadweaver_sumo.spec import ScenarioSpec

    def digest(G):
        h = hashlib.sha256()
        for u, v, d in sorted(G.edges(data=True), key=lambda t: t[:2]):
            h.update(f"{u} {v} {d['start']} {d['road_class']}".encode() + d["coords"].tobytes())
        return h.hexdigest()

    spec = ScenarioSpec(density=40, vehicles=10, width=3000, height=2500, seed=4,
                        skeleton="procedural")
    skeleton = make_skeleton(spec)
    groups, original = [], fill._two_groups

    def recording(blocks):
        groups.append(original(blocks))
        return groups[-1]

    monkeypatch.setattr(fill, "HALVES_MIN_NODES", 100)
    monkeypatch.setattr(fill, "_two_groups", recording)
    G = expand_skeleton(spec, skeleton)
    assert groups and all(first and second for first, second in groups)
    areas = [sum(b.area for b in group) for group in groups[0]]
    assert min(areas) > 0.4 * sum(areas)
    target = spec.target_road_nodes
    assert abs(metrics.road_node_count(G) - target) <= 0.025 * target
    assert metrics.crossings_without_junction(G) == 0
    monkeypatch.setattr(forked, "can_fork", lambda: False)
    assert digest(expand_skeleton(spec, skeleton)) == digest(G)


def test_merged_fills_keep_both_junctions_on_a_road_both_split():
    """Two fills that each made a junction on the same road, one here and one on a copy:
    merged, the road runs through both junctions, and the copy's side street hangs from its
    own junction."""
    from roadweaver_sumo.expand.fill import _fill_changes, _merge_fill, split_edge_at

    G = nx.Graph(width=200.0, height=200.0)
    G.add_node(0, xy=(0.0, 0.0))
    G.add_node(1, xy=(100.0, 0.0))
    add_road(G, 0, 1, [(0.0, 0.0), (50.0, 0.0), (100.0, 0.0)], "collector")
    H = G.copy()
    before = {edge_key(u, v): d for u, v, d in H.edges(data=True)}
    index_g, index_h = EdgeIndex(G), EdgeIndex(H)
    split_edge_at(G, (0, 1), (30.0, 0.0), 12.0, index_g)
    there = split_edge_at(H, (0, 1), (70.0, 0.0), 12.0, index_h)
    H.add_node(there + 1, xy=(70.0, 40.0))
    add_road(H, there, there + 1, [(70.0, 0.0), (70.0, 40.0)], "local")
    index_h.add(there, there + 1)
    _merge_fill(G, index_g, 12.0, *_fill_changes(H, 1, before, index_h))
    by_xy = {G.nodes[n]["xy"]: n for n in G}
    a, b, street_end = by_xy[(30.0, 0.0)], by_xy[(70.0, 0.0)], by_xy[(70.0, 40.0)]
    assert sorted(map(sorted, G.edges)) == sorted(map(sorted, [(0, a), (a, b), (b, 1),
                                                                (b, street_end)]))
    assert G.edges[a, b]["road_class"] == "collector" and G.edges[b, street_end]["road_class"] == "local"
