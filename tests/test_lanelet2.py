"""lanelet2_map.osm in lanelet2 format: structure read back with lxml, and lanelet2 itself when installed."""

from __future__ import annotations

import numpy as np
import pytest
from lxml import etree

from roadweaver_sumo.expand import expand_skeleton
from roadweaver_sumo.export.lanelet2 import LANE_TAG, write_lanelet2
from roadweaver_sumo.export.lanelet2_boundaries import untangle
from roadweaver_sumo.export.map_files import write_map_files
from roadweaver_sumo.hdmap import build_hdmap
from roadweaver_sumo.integrations.tactics2d import hd_lane_relations
from roadweaver_sumo.projection import latlon_to_local, local_to_latlon
from roadweaver_sumo.skeleton import make_skeleton
from roadweaver_sumo.spec import ScenarioSpec
from roadweaver_sumo.validate.lanelet2_check import (
    check_lanelet2,
    lanelet2_failures,
    osm_lane_relations,
)

SPEC = ScenarioSpec(density=30, vehicles=1, width=1000, height=1000, style="organic", seed=0,
                    skeleton="procedural")


def _hdmap():
    graph = expand_skeleton(SPEC, make_skeleton(SPEC))
    return build_hdmap(graph, SPEC.geo_origin, traffic_lights=SPEC.traffic_lights)


@pytest.fixture(scope="module")
def hd():
    return _hdmap()


@pytest.fixture(scope="module")
def osm(hd, tmp_path_factory):
    """The lanelet2 file as the pipeline writes it: after netconvert, with SUMO's right of
    way on the connectors (``hd`` carries it afterwards)."""
    return write_map_files(hd, tmp_path_factory.mktemp("lanelet2"))["lanelet2"]


class OsmFile:
    """The parts of a written lanelet2_map.osm the tests look at, keyed by our lane ids."""

    def __init__(self, path):
        root = etree.parse(str(path)).getroot()
        self.root = root
        self.nodes = {n.get("id"): (float(n.get("lat")), float(n.get("lon")))
                      for n in root.iter("node")}
        self.ways = {w.get("id"): [nd.get("ref") for nd in w.iter("nd")] for w in root.iter("way")}
        self.lanelets, self.tags, self.regulatory, self.rules = {}, {}, {}, {}
        for rel in root.iter("relation"):
            tags = {t.get("k"): t.get("v") for t in rel.iter("tag")}
            members = [(m.get("type"), m.get("role"), m.get("ref")) for m in rel.iter("member")]
            if tags["type"] == "lanelet":
                self.lanelets[tags[LANE_TAG]] = {role: ref for _, role, ref in members
                                                 if role != "regulatory_element"}
                self.rules[tags[LANE_TAG]] = [ref for _, role, ref in members
                                              if role == "regulatory_element"]
                self.tags[tags[LANE_TAG]] = tags
            else:
                self.regulatory[rel.get("id")] = (tags, members)

    def bound(self, lane: str, side: str) -> list[str]:
        return self.ways[self.lanelets[lane][side]]

    def xy(self, node: str, origin) -> np.ndarray:
        lat, lon = self.nodes[node]
        return np.array(latlon_to_local(lat, lon, origin), float)


@pytest.fixture(scope="module")
def parsed(osm):
    return OsmFile(osm)


def test_osm_header_is_josm_style(parsed):
    assert parsed.root.tag == "osm"
    assert parsed.root.get("version") == "0.6"
    assert parsed.root.get("generator") == "roadweaver-sumo"
    ids = [int(e.get("id")) for e in parsed.root if e.tag in ("node", "way", "relation")]
    assert min(ids) > 0 and len(ids) == len(set(ids)), "positive ids, one id space"
    assert not parsed.root.findall("node/tag"), "nodes carry no ele or other tags"


def test_one_lanelet_per_hdmap_lane(hd, parsed):
    assert sorted(parsed.lanelets) == sorted(hd.lanes)
    for tags in parsed.tags.values():
        assert tags["subtype"] == "road" and tags["location"] == "urban"
        assert tags["one_way"] == "yes"


def test_same_direction_neighbours_share_their_boundary_way(hd, parsed):
    pairs = [(lane.id, lane.left_neighbour) for lane in hd.lanes.values() if lane.left_neighbour]
    assert pairs, "the test map needs multi-lane roads"
    for lane, left in pairs:
        assert parsed.lanelets[lane]["left"] == parsed.lanelets[left]["right"]
    dashed = {parsed.lanelets[lane]["left"] for lane, _ in pairs}
    for way in parsed.root.iter("way"):
        if way.get("id") in dashed:
            tags = {t.get("k"): t.get("v") for t in way.iter("tag")}
            assert tags == {"type": "line_thin", "subtype": "dashed"}


def test_every_successor_link_is_shared_end_and_start_nodes(hd, parsed):
    links = [(lane.id, succ) for lane in hd.lanes.values() for succ in lane.successors]
    assert links
    missing = [(a, b) for a, b in links for side in ("left", "right")
               if parsed.bound(a, side)[-1] != parsed.bound(b, side)[0]]
    assert not missing, f"successor links not realised as shared nodes: {missing[:5]}"


def test_file_topology_is_exactly_the_hdmap_lane_graph(hd, osm):
    assert osm_lane_relations(osm) == hd_lane_relations(hd)


def test_a_link_lost_in_the_file_is_noticed(hd, osm, tmp_path):
    lane = next(lane for lane in hd.road_lanes() if lane.successors)
    text = osm.read_text(encoding="utf-8")
    root = etree.fromstring(text.encode())
    way_id = OsmFile(osm).lanelets[lane.id]["right"]
    last = root.find(f"way[@id='{way_id}']").findall("nd")[-1]
    last.set("ref", next(n.get("id") for n in root.iter("node")))  # detach the end node
    broken = tmp_path / "broken.osm"
    broken.write_bytes(etree.tostring(root))
    assert osm_lane_relations(broken)[lane.id]["successors"] == []


def test_speed_limits_and_widths_match_the_hdmap(hd, parsed):
    for lane in hd.lanes.values():
        assert float(parsed.tags[lane.id]["speed_limit"]) / 3.6 == pytest.approx(lane.speed,
                                                                                abs=0.002)
        left, right = parsed.bound(lane.id, "left"), parsed.bound(lane.id, "right")
        start = np.linalg.norm(parsed.xy(left[0], hd.geo_origin) - parsed.xy(right[0],
                                                                              hd.geo_origin))
        end = np.linalg.norm(parsed.xy(left[-1], hd.geo_origin) - parsed.xy(right[-1],
                                                                             hd.geo_origin))
        assert start == pytest.approx(lane.width, abs=0.01), lane.id
        assert end == pytest.approx(lane.end_width, abs=0.01), lane.id


def test_output_is_byte_identical(hd, osm, tmp_path):
    again = write_map_files(_hdmap(), tmp_path)["lanelet2"]
    assert again.read_bytes() == osm.read_bytes()


def test_nodes_round_trip_to_hdmap_points_within_a_centimetre(hd, parsed):
    for lane in hd.lanes.values():
        for side, points in (("left", lane.left), ("right", lane.right)):
            ends = parsed.bound(lane.id, side)
            for node, point in ((ends[0], points[0]), (ends[-1], points[-1])):
                assert np.linalg.norm(parsed.xy(node, hd.geo_origin) - point) < 0.01


def test_projection_round_trip_is_exact_over_ten_kilometres():
    rng = np.random.default_rng(0)
    x, y = rng.uniform(-5000, 5000, 1000), rng.uniform(-5000, 5000, 1000)
    origin = (48.137, 11.575)
    lat, lon = local_to_latlon(x, y, origin)
    back = latlon_to_local(lat, lon, origin)
    assert np.max(np.hypot(back[0] - x, back[1] - y)) < 1e-5  # 10 micrometres
    assert np.allclose(local_to_latlon(0.0, 0.0, origin), origin, atol=1e-12)
    # one degree of latitude is about 111.2 km on the meridian at 48 degrees north
    assert latlon_to_local(49.137, 11.575, origin)[1] == pytest.approx(111_200, rel=2e-3)


def test_traffic_lights_guard_the_approaches_of_signalised_junctions(hd, parsed):
    approaches = [road.lanes(d) for road in hd.roads.values() for d in ("f", "b")
                  if road.lanes(d) and hd.junctions[road.ends_at(d)].type == "traffic_light"]
    assert approaches, "the test map needs traffic lights"
    lights = {rid: members for rid, (tags, members) in parsed.regulatory.items()
              if tags == {"type": "regulatory_element", "subtype": "traffic_light"}}
    assert len(lights) == len(approaches)
    for members in lights.values():
        assert sorted(role for _, role, _ in members) == ["ref_line", "refers"]
    for lanes in approaches:
        refs = {rid for lane in lanes for rid in parsed.rules[lane] if rid in lights}
        assert len(refs) == 1, "one light for all lanes of an approach"


def test_untangle_cuts_loops_and_fold_backs_and_keeps_ends():
    swallowtail = np.array([[0, 0], [10, 0], [12, 2], [11, 3], [10, 2], [10.5, -1], [20, -1]],
                           float)
    clean = untangle(swallowtail)
    assert (clean[0] == swallowtail[0]).all() and (clean[-1] == swallowtail[-1]).all()
    steps = np.diff(clean, axis=0)
    assert (np.einsum("ij,ij->i", steps[:-1], steps[1:]) >= 0).all()
    straight = np.array([[0, 0], [5, 0], [5.0000001, 0], [10, 0]], float)
    assert len(untangle(straight)) == 3


def test_lanelet2_loads_the_map_and_routes_random_pairs(hd, osm):
    pytest.importorskip("lanelet2")
    result = check_lanelet2(osm, hd.geo_origin, pairs=1000, seed=0)
    assert lanelet2_failures(result) == []
    assert result["lanelets"] == len(hd.lanes)
    assert result["inverted_bounds"] == [] and result["topology_mismatches"] == []
    assert result["speed_limit_mismatches"] == 0 and result["lanelets_without_following"] == 0
    def reach(lane, side: str) -> int:  # lanelet2's lefts/rights: every lane a change away
        count = 0
        while (lane := hd.lanes.get(getattr(lane, side) or "")) is not None:
            count += 1
        return count

    neighbours = sum(reach(lane, "left_neighbour") + reach(lane, "right_neighbour")
                     for lane in hd.lanes.values())
    assert result["lane_change_relations"] == neighbours > 0 and result["traffic_lights"] > 0
    assert result["route_success"] >= 0.99
    assert result["projection_max_error_m"] < 0.001


def test_lanelet2_check_reports_a_broken_map_instead_of_crashing(tmp_path):
    pytest.importorskip("lanelet2")
    broken = tmp_path / "broken.osm"
    broken.write_text('<osm version="0.6"><relation id="1"><member type="way" ref="7" '
                      'role="left"/><tag k="type" v="lanelet"/></relation></osm>')
    result = check_lanelet2(broken, (48.0, 11.0), pairs=10)
    assert lanelet2_failures(result), result


def test_dead_end_uturn_lanelets_are_valid_polygons(tmp_path):
    """Every lanelet's outline (left bound, then the right bound reversed) is a valid polygon
    in the written file, the U-turns at dead ends included (their inner bound, one centre
    line point there, is a way of two nodes), and lanelet2 routes through them."""
    from shapely.geometry import Polygon
    from test_hdmap import t_junction

    hd = build_hdmap(t_junction(), SPEC.geo_origin)
    path = write_lanelet2(hd, tmp_path / "lanelet2_map.osm")
    parsed = OsmFile(path)
    for lane in hd.lanes:
        left = [parsed.xy(n, hd.geo_origin) for n in parsed.bound(lane, "left")]
        right = [parsed.xy(n, hd.geo_origin) for n in parsed.bound(lane, "right")]
        assert len(left) >= 2 and len(right) >= 2
        assert Polygon(np.vstack([left, right[::-1]])).is_valid, lane
    try:
        import lanelet2  # noqa: F401
    except ImportError:  # the outlines above are the point; routing where lanelet2 is there
        return
    result = check_lanelet2(path, hd.geo_origin, pairs=200, seed=0)
    assert lanelet2_failures(result) == [] and result["route_success"] == 1.0
