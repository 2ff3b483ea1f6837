"""Data pipeline: OSM reading, tiles, road field F and back, condition vector, dataset files.

Every input is made here: a little OSM town written as XML (and gz / bz2 / pbf), and synthetic
road graphs (a grid, a curvy town, a radial town).
"""

import bz2
import gzip
import json

import networkx as nx
import numpy as np
import pytest

from roadweaver_sumo import metrics
from roadweaver_sumo.data.condition import (
    CONDITION_NAMES,
    condition_vector,
    gridness,
    organicness,
    radialness,
    style_preset,
)
from roadweaver_sumo.data.field import CHANNELS, field_to_graph, road_field, rotate_field
from roadweaver_sumo.data.graphml import read_graphml
from roadweaver_sumo.data.prepare import (
    ATTRIBUTION,
    decode_field,
    encode_field,
    load_dataset,
    prepare_dataset,
)
from roadweaver_sumo.data.projection import LocalProjection
from roadweaver_sumo.data.tiles import coverage, cut_tile, iter_tiles, rotate_tile
from roadweaver_sumo.errors import RoadweaverError
from roadweaver_sumo.projection import local_to_latlon
from roadweaver_sumo.roadgraph import add_road, new_road_graph

LAT0, LON0 = 48.0, 11.0


def _lonlat(x: float, y: float) -> tuple[float, float]:
    """The WGS84 degrees of local metres around (LAT0, LON0), by pyproj's transverse Mercator."""
    lat, lon = local_to_latlon(x, y, (LAT0, LON0))
    return float(lon), float(lat)


def town_xml(extra_ways: str = "") -> str:
    """A 4 x 4 grid of residential streets, 100 m apart, with a primary road along the south
    side, a tertiary street, a dead-end stub south of (0, 0), and roads cars may not use."""
    nodes = {10 * i + j + 1: (100.0 * i, 100.0 * j) for i in range(4) for j in range(4)}
    nodes.update({100: (0.0, -100.0), 101: (150.0, 150.0), 102: (250.0, 350.0),
                  103: (350.0, 250.0)})
    xml = ['<?xml version="1.0"?>', '<osm version="0.6" generator="test">']
    for nid, (x, y) in nodes.items():
        lon, lat = _lonlat(x, y)
        xml.append(f'<node id="{nid}" lat="{lat:.8f}" lon="{lon:.8f}" version="1"/>')
    ways = {1: ([1, 11, 21, 31], "primary")}
    ways.update({1 + j: ([10 * i + j + 1 for i in range(4)], "residential") for j in (1, 2)})
    ways[4] = ([4, 14, 24, 34], "tertiary")
    ways.update({5 + i: ([10 * i + j + 1 for j in range(4)], "residential") for i in range(4)})
    ways[9] = ([1, 100], "residential")  # the dead end
    ways[20] = ([12, 101, 23], "service")
    ways[21] = ([22, 101], "footway")
    ways[22] = ([33, 103, 102], "cycleway")
    for wid, (refs, highway) in ways.items():
        nds = "".join(f'<nd ref="{r}"/>' for r in refs)
        xml.append(f'<way id="{wid}" version="1">{nds}<tag k="highway" v="{highway}"/></way>')
    xml.append(extra_ways)
    xml.append("</osm>")
    return "\n".join(xml)


CLOSED_WAYS = (
    '<way id="30" version="1"><nd ref="12"/><nd ref="101"/><nd ref="34"/>'
    '<tag k="highway" v="residential"/><tag k="access" v="private"/></way>'
    '<way id="31" version="1"><nd ref="13"/><nd ref="101"/>'
    '<tag k="highway" v="residential"/><tag k="area" v="yes"/></way>'
)


@pytest.fixture(scope="module")
def town_files(tmp_path_factory):
    d = tmp_path_factory.mktemp("osm")
    text = town_xml(CLOSED_WAYS)
    (d / "town.osm").write_text(text)
    (d / "town.osm.gz").write_bytes(gzip.compress(text.encode()))
    (d / "town.osm.bz2").write_bytes(bz2.compress(text.encode()))
    import osmium

    with osmium.SimpleWriter(str(d / "town.osm.pbf")) as writer:
        for obj in osmium.FileProcessor(str(d / "town.osm")):
            writer.add(obj)
    return d


@pytest.mark.parametrize("name", ["town.osm", "town.osm.gz", "town.osm.bz2", "town.osm.pbf"])
def test_every_format_gives_the_same_drivable_network(town_files, name):
    from roadweaver_sumo.data.osm import read_osm

    G = read_osm(town_files / name)
    # 8 border nodes of degree 3, 4 crossings, the stubbed corner and the dead end
    assert metrics.road_node_count(G) == 14
    assert sorted(d for _, d in G.degree() if d != 2) == [1] + [3] * 9 + [4] * 4
    assert not {101, 102, 103} & set(G.nodes)  # only on service, footway, cycleway, private
    assert G.number_of_edges() == 12 + 12 + 1  # row and column links, and the stub


def test_osm_graph_is_in_metres_with_classes(town_files):
    from roadweaver_sumo.data.osm import read_osm

    G = read_osm(town_files / "town.osm")
    assert G.graph["width"] == pytest.approx(300.0, abs=0.5)
    assert G.graph["height"] == pytest.approx(400.0, abs=0.5)
    assert metrics.density(G, 0.3 * 0.4) == pytest.approx(14 / 0.12)
    classes = {tuple(sorted((u, v))): c for u, v, c in G.edges(data="road_class")}
    assert classes[(1, 11)] == "arterial" and classes[(4, 14)] == "collector"
    assert classes[(1, 100)] == "local"
    p = G.graph["projection"]
    back = LocalProjection(p["lon0"], p["lat0"], p["x0"], p["y0"]).inverse(G.nodes[1]["xy"])
    assert np.allclose(back[0], _lonlat(0.0, 0.0), atol=1e-8)


def test_bad_osm_inputs_are_one_line_errors(tmp_path):
    pytest.importorskip("osmium")
    from roadweaver_sumo.data.osm import read_osm

    (tmp_path / "roads.txt").write_text("x")
    (tmp_path / "broken.osm").write_text("<osm><node id=")
    (tmp_path / "paths.osm").write_text(town_xml().replace('v="residential"', 'v="path"')
                                        .replace('v="primary"', 'v="track"')
                                        .replace('v="tertiary"', 'v="footway"'))
    for name in ("missing.osm.pbf", "roads.txt", "broken.osm", "paths.osm"):
        with pytest.raises(RoadweaverError) as err:
            read_osm(tmp_path / name)
        assert "\n" not in str(err.value)


def grid_graph(size: float, spacing: float, margin: float = 0.0, curve: float = 0.0,
               jitter: float = 0.0, seed: int = 0) -> nx.Graph:
    """A square grid of streets; ``curve`` bends every street into an arc of that height (m)
    and ``jitter`` moves the crossings (m), for an organic-looking network."""
    rng = np.random.default_rng(seed)
    G = new_road_graph(size, size)
    ticks = np.arange(margin, size - margin + 1e-9, spacing)
    n = len(ticks)
    for i in range(n):
        for j in range(n):
            G.add_node((i, j), xy=tuple(np.array([ticks[i], ticks[j]]) + rng.normal(0, jitter, 2)))
    t = np.linspace(0, 1, 9)[:, None]
    for i in range(n):
        for j in range(n):
            for a, b in (((i, j), (i + 1, j)), ((i, j), (i, j + 1))):
                if b[0] >= n or b[1] >= n:
                    continue
                p, q = np.array(G.nodes[a]["xy"]), np.array(G.nodes[b]["xy"])
                normal = np.array([-(q - p)[1], (q - p)[0]]) / np.linalg.norm(q - p)
                bend = curve * (1 if (i + j) % 2 else -1) * np.sin(np.pi * t)
                add_road(G, a, b, p + (q - p) * t + bend * normal, "local")
    return G


def radial_graph(size: float = 2000.0, spokes: int = 12, rings=(300.0, 550.0, 800.0)) -> nx.Graph:
    G = new_road_graph(size, size)
    c = np.array([size / 2, size / 2])
    ang = np.linspace(0, 2 * np.pi, spokes, endpoint=False)
    G.add_node("c", xy=tuple(c))
    for k, a in enumerate(ang):
        for r_i, r in enumerate(rings):
            G.add_node((k, r_i), xy=tuple(c + r * np.array([np.cos(a), np.sin(a)])))
        add_road(G, "c", (k, 0), [c, G.nodes[(k, 0)]["xy"]], "arterial")
        for r_i in range(1, len(rings)):
            add_road(G, (k, r_i - 1), (k, r_i),
                     [G.nodes[(k, r_i - 1)]["xy"], G.nodes[(k, r_i)]["xy"]], "arterial")
    for r_i, r in enumerate(rings):
        for k in range(spokes):
            arc = np.linspace(ang[k], ang[k] + 2 * np.pi / spokes, 12)
            pts = c + r * np.column_stack([np.cos(arc), np.sin(arc)])
            add_road(G, (k, r_i), ((k + 1) % spokes, r_i), pts, "collector")
    return G


def test_tiles_clip_roads_into_dead_ends_and_skip_empty_ones():
    G = grid_graph(1000.0, 100.0)
    G.graph["width"] = 2000.0  # the east half of the map has no roads
    T = cut_tile(G, (260.0, 260.0), 500.0)
    # the window [10, 510]²: each of the five streets at 100..500 m in each direction is cut
    # at both ends
    assert sum(1 for _, d in T.degree() if d == 1) == 20
    assert metrics.road_node_count(T) == 20 + 25
    assert coverage(T) == pytest.approx(1.0)
    tiles = list(iter_tiles(G, 500.0, rotations=(0,), shifts=(0.0, 0.5)))
    # shift (0, 0): x = 250, 750; (0.5, 0): x = 500 and 1000 (60 % covered); the y shift keeps
    # one row of those; tiles east of x = 1000 have no roads
    assert len(tiles) == 4 + 4 + 2 + 2
    assert max(t.centre[0] for t in tiles) == 1000.0


def test_tile_rotations_are_exact_and_random_angles_are_seeded():
    G = grid_graph(1000.0, 100.0, curve=10.0, jitter=5.0)
    T = cut_tile(G, (500.0, 500.0), 600.0)
    back = rotate_tile(rotate_tile(T, 1), 3)
    assert all(np.allclose(back.nodes[n]["xy"], T.nodes[n]["xy"]) for n in T)
    def angles(seed):
        return [t.angle_deg for t in iter_tiles(G, 600.0, rotations=(), shifts=(0.0,),
                                                random_rotations=2, min_coverage=0.0, seed=seed)]
    assert angles(3) == angles(3) and angles(3) != angles(4)


def test_road_field_channels():
    G = grid_graph(2000.0, 250.0, margin=125.0)
    F = road_field(G, 128)
    assert F.shape == (128, 128, len(CHANNELS)) and F.dtype == np.float32
    assert F[..., 0].min() >= 0 and F[..., 0].max() <= 1
    assert np.all(np.abs(F[..., 1:3]) <= F[..., :1] + 1e-6)  # orientation zero off-road
    assert 0 <= F[..., 5].min() and F[..., 5].max() <= 1
    res = 2000.0 / 128
    for n, d in G.degree():
        x, y = G.nodes[n]["xy"]
        iy, ix = int(y / res), int(x / res)
        channel = 3 if d >= 3 else 4 if d == 1 else None
        if channel is not None:  # nodes sit on pixel corners: 0.78 at the four pixels
            assert F[iy - 1 : iy + 2, ix - 1 : ix + 2, channel].max() > 0.7
    corner = G.nodes[(0, 0)]["xy"]
    assert F[int(corner[1] / res), int(corner[0] / res), 3] < 0.2  # degree 2: no junction
    assert F[0, 0, 5] > 0.3 and F[int(1125 / res), int(1000 / res), 5] < 0.05
    horizontal = F[int(1125 / res), int(1060 / res), 1:3]
    assert horizontal[0] > 0.5 and abs(horizontal[1]) < 0.05  # cos 2θ = 1 along x


def test_rotating_the_field_equals_rasterising_the_rotated_tile():
    G = grid_graph(1000.0, 100.0, curve=15.0, jitter=8.0, seed=2)
    T = cut_tile(G, (500.0, 500.0), 640.0)
    F = road_field(T, 64)
    for k in (1, 2, 3):
        R = road_field(rotate_tile(T, k), 64)
        turned = rotate_field(F, k)
        assert np.allclose(turned[..., [0, 3, 4, 5]], R[..., [0, 3, 4, 5]], atol=1e-5)
        # orientation may differ only where two roads are equally near (ties in the k-d tree):
        # 5-7 % of this small tile, where the road band (2.4 px) overlaps junction corners;
        # turning the raster without flipping the orientation pair changes nearly every pixel
        assert np.mean(np.abs(turned[..., 1:3] - R[..., 1:3]) > 1e-3) < 0.1


def test_field_to_graph_round_trip_keeps_road_nodes():
    G = grid_graph(2000.0, 200.0, margin=100.0, jitter=6.0, seed=1)
    H = field_to_graph(road_field(G, 128), 2000.0)
    n0, n1 = metrics.road_node_count(G), metrics.road_node_count(H)
    assert abs(n1 - n0) <= 0.1 * n0
    assert metrics.lcc_ratio(H) == 1.0
    assert H.graph["width"] == 2000.0
    assert all(np.allclose(H.edges[e]["coords"][0], H.nodes[H.edges[e]["start"]]["xy"])
               for e in H.edges)


def _skeleton_graph_path_by_path(mask: np.ndarray, res: float, tile_m: float) -> nx.Graph:
    """``vectorise.skeleton_graph`` as it was first written: each path walked on the sparse
    matrix, smoothed and simplified on its own (the reference for the batched version)."""
    import shapely
    from skimage.morphology import skeletonize

    from roadweaver_sumo.data.build import add_segment, node_counter
    from roadweaver_sumo.data.vectorise import _key_clusters, pixel_graph

    pix, A = pixel_graph(skeletonize(mask))
    degree = np.asarray(A.sum(axis=1)).ravel().astype(int)
    node = _key_clusters(A, degree)
    xy = (pix[:, ::-1] + 0.5) * res
    G = new_road_graph(tile_m, tile_m * mask.shape[0] / mask.shape[1])
    ids, cluster = np.unique(node[node >= 0], return_inverse=True)
    size = np.bincount(cluster)
    centre = np.column_stack([np.bincount(cluster, weights=xy[node >= 0, k]) / size
                              for k in (0, 1)])
    for n, (x, y) in zip(ids.tolist(), centre.tolist(), strict=True):
        G.add_node(n, xy=(x, y))
    fresh = node_counter(G, start=len(pix) + 1)

    def neighbours(k):
        return A.indices[A.indptr[k]:A.indptr[k + 1]]

    def traces():
        covered, done = node >= 0, set()
        for k in np.flatnonzero(node >= 0):
            for nb in neighbours(k):
                if node[nb] == node[k] or (k, nb) in done:
                    continue
                path = [k, nb]
                while node[path[-1]] < 0:
                    path.append(next(p for p in neighbours(path[-1]) if p != path[-2]))
                done.add((path[-1], path[-2]))
                covered[path] = True
                yield node[k], node[path[-1]], path
        for start in np.flatnonzero(~covered):
            if covered[start]:
                continue
            path = [start]
            while True:
                nbrs = [p for p in neighbours(path[-1]) if len(path) < 2 or p != path[-2]]
                if not nbrs or nbrs[0] == start:
                    break
                path.append(nbrs[0])
            covered[path] = True
            yield -1 - start, -1 - start, path + [start]

    for a, b, path in traces():
        for n, p in ((a, path[0]), (b, path[-1])):
            if n not in G:
                G.add_node(int(n), xy=(float(xy[p, 0]), float(xy[p, 1])))
        c = xy[path].copy()
        c[0], c[-1] = G.nodes[a]["xy"], G.nodes[b]["xy"]
        for _ in range(2):
            if len(c) >= 3:
                c[1:-1] = 0.25 * c[:-2] + 0.5 * c[1:-1] + 0.25 * c[2:]
        line = shapely.simplify(shapely.LineString(c), 0.5 * res)
        add_segment(G, int(a), int(b), np.asarray(line.coords), "arterial", fresh)
    return G


def _same_graph(G: nx.Graph, H: nx.Graph) -> bool:
    """Same nodes, edges, attributes and insertion order, coordinates to the bit."""
    return (list(G.nodes(data=True)) == list(H.nodes(data=True))
            and [(u, v, d["start"], d["road_class"], d["coords"].tobytes())
                 for u, v, d in G.edges(data=True)]
            == [(u, v, d["start"], d["road_class"], d["coords"].tobytes())
                for u, v, d in H.edges(data=True)])


def test_skeleton_graph_equals_tracing_path_by_path():
    """The batched tracing, smoothing and simplification give the graph, bit for bit, that
    handling each path on its own gave: on a rasterised town, and on a mask with a ring, a
    loop back to its junction, two roads between the same junctions and a lone speck."""
    from roadweaver_sumo.data.vectorise import skeleton_graph

    mask = np.zeros((60, 90), bool)
    mask[10:12, 5:85] = mask[40:42, 5:85] = True
    mask[10:42, 20:22] = mask[10:42, 60:62] = True
    yy, xx = np.mgrid[0:60, 0:90]
    mask |= np.abs(np.hypot(yy - 25, xx - 40) - 8) < 1.0  # a ring touching nothing
    mask |= np.abs(np.hypot(yy - 48, xx - 75) - 6) < 1.0  # a loop off the lower road
    mask[55, 10] = True
    fields = [(mask, 13.7)]
    for G in (grid_graph(2000.0, 200.0, margin=100.0, jitter=6.0, seed=1), radial_graph()):
        fields.append((road_field(G, 96)[..., 0] >= 0.5, 2000.0 / 96))
    for m, res in fields:
        H = skeleton_graph(m, res, m.shape[1] * res)
        assert H.number_of_edges() > 3
        assert _same_graph(H, _skeleton_graph_path_by_path(m, res, m.shape[1] * res))


def test_vectoriser_adds_roads_as_add_segment_does(monkeypatch):
    """The vectoriser adds a road between two nodes not yet joined without add_segment's
    checks: the cleaned graph (junctions merged on the way) is the one add_segment builds."""
    from roadweaver_sumo.data import build, vectorise

    fields = [road_field(G, 96) for G in (grid_graph(2000.0, 200.0, margin=100.0, jitter=6.0,
                                                     seed=1), radial_graph())]
    graphs = [field_to_graph(F, 2000.0) for F in fields]
    monkeypatch.setattr(vectorise, "_add_segment", build.add_segment)
    for F, H in zip(fields, graphs, strict=True):
        assert _same_graph(H, field_to_graph(F, 2000.0))


def test_condition_vector_orders_grid_curvy_and_radial_towns():
    grid = grid_graph(2000.0, 150.0, margin=75.0)
    curvy = grid_graph(2000.0, 150.0, margin=75.0, curve=35.0, jitter=20.0)
    radial = radial_graph()
    assert gridness(grid) > 0.8
    assert gridness(curvy) < 0.4
    assert organicness(curvy) > organicness(grid) + 0.3
    assert radialness(radial) > 0.8 and abs(radialness(grid)) < 0.1
    presets = {k: style_preset(k) for k in ("grid", "organic", "radial", "mixed")}
    gi, oi = CONDITION_NAMES.index("gridness"), CONDITION_NAMES.index("organicness")
    assert presets["grid"][gi] > presets["mixed"][gi] > presets["organic"][gi]
    assert presets["organic"][oi] > presets["grid"][oi]
    assert style_preset("grid", density=90.0)[CONDITION_NAMES.index("density")] == 90.0
    with pytest.raises(RoadweaverError):
        style_preset("medieval")
    c = condition_vector(grid, 4.0)
    assert c.shape == (len(CONDITION_NAMES),) == (11,) and np.isfinite(c).all()
    assert c[CONDITION_NAMES.index("density")] == pytest.approx(metrics.density(grid, 4.0))


def test_field_quantisation_round_trips_within_one_step():
    F = road_field(grid_graph(640.0, 80.0, margin=40.0), 32)
    assert np.abs(decode_field(encode_field(F)) - F).max() <= 1 / 255 + 1e-6


def test_prepare_dataset_writes_shards_and_manifest(town_files, tmp_path):
    manifest = prepare_dataset([town_files / "town.osm.pbf"], tmp_path / "ds", tile_m=300.0,
                               size=32, shifts=(0.0,), min_coverage=0.3, log=lambda _: None)
    assert manifest["attribution"] == ATTRIBUTION
    assert manifest["tiles"] == 4 and len(manifest["sources"][0]["sha256"]) == 64
    assert json.loads((tmp_path / "ds" / "manifest.json").read_text())["tiles"] == 4
    data = load_dataset(tmp_path / "ds")
    assert data["F"].shape == (4, 32, 32, 6) and data["F"].dtype == np.uint8
    assert data["c"].shape == (4, 11) and sorted(data["angle"]) == [0, 90, 180, 270]
    assert np.all(data["c"] == data["c"][0])  # quarter turns do not change c


def test_prepare_dataset_rejects_missing_input(tmp_path):
    for files in ([], [tmp_path / "missing.osm"]):
        with pytest.raises(RoadweaverError):
            prepare_dataset(files, tmp_path / "ds", log=lambda _: None)


def test_prepare_dataset_rejects_a_map_smaller_than_a_tile(town_files, tmp_path):
    with pytest.raises(RoadweaverError, match="no tile"):
        prepare_dataset([town_files / "town.osm"], tmp_path / "ds", tile_m=2000.0,
                        log=lambda _: None)


def test_reads_an_osmnx_graphml(tmp_path):
    g = nx.MultiDiGraph()
    for n, (x, y) in {1: (0, 0), 2: (100, 0), 3: (100, 100)}.items():
        lon, lat = _lonlat(x, y)
        g.add_node(n, x=lon, y=lat)
    lon_mid, lat_mid = _lonlat(60, 40)
    geometry = f"LINESTRING ({_lonlat(100, 0)[0]} {_lonlat(100, 0)[1]}, {lon_mid} {lat_mid}, " \
               f"{_lonlat(100, 100)[0]} {_lonlat(100, 100)[1]})"
    g.add_edge(1, 2, highway="primary")
    g.add_edge(2, 1, highway="primary")
    g.add_edge(2, 3, highway="['residential', 'tertiary']", geometry=geometry)
    nx.write_graphml(g, tmp_path / "city.graphml")
    G = read_graphml(tmp_path / "city.graphml")
    assert G.number_of_edges() == 2 and metrics.road_node_count(G) == 2
    assert G.edges["2", "3"]["road_class"] == "collector" and len(G.edges["2", "3"]["coords"]) == 3


def test_cli_data_prepare_writes_a_dataset_and_keeps_existing_folders(town_files, tmp_path, capsys):
    from roadweaver_sumo.cli import main

    out = tmp_path / "ds"
    args = ["data", "prepare", "--osm", str(town_files / "town.osm.pbf"), "--out", str(out),
            "--tile", "300", "--size", "32"]
    assert main(args) == 0
    assert json.loads((out / "manifest.json").read_text())["tiles"] > 0
    assert main(args) == 2
    assert "already exists; use --force" in capsys.readouterr().err
    assert main(["data", "prepare", "--osm", str(tmp_path / "none.osm"), "--out",
                 str(tmp_path / "x")]) == 2
    assert "not found" in capsys.readouterr().err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["ds"]
