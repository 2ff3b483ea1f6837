"""``--lanes CLASS=N``: lanes per direction by road class (``hdmap.lane_counts``), in the HD
map, SUMO's net and spec.json; a road that would crowd another with them keeps its class's."""

from __future__ import annotations

import json
import re

from test_hdmap import _graph
from test_one_way import local_grid

from roadweaver_sumo.clearance import roads_too_close
from roadweaver_sumo.cli import main
from roadweaver_sumo.hdmap import build_hdmap
from roadweaver_sumo.hdmap.lane_counts import give_lanes


def test_a_road_that_would_crowd_another_keeps_its_class_lanes():
    """Two collectors 15 m apart keep their clearance with one lane each (11.5 m) but not with
    two (18 m): they keep one; a third collector far off gets two; asking for fewer lanes than
    a class has always holds."""
    G = _graph({0: (50, 100), 1: (350, 100), 2: (50, 115), 3: (350, 115), 4: (50, 300),
                5: (350, 300)},
               [(0, 1, "collector"), (2, 3, "collector"), (4, 5, "collector")], size=400.0)
    assert roads_too_close(G) == []
    wide = give_lanes(G, {"collector": 2})
    assert [wide.edges[e].get("lanes") for e in [(0, 1), (2, 3), (4, 5)]] == [None, None, 2]
    assert roads_too_close(wide) == []
    assert "lanes" not in G.edges[4, 5], "the input graph is left as it was"
    assert give_lanes(G, {"collector": 1}) is G, "nothing asked that differs from the class"


def test_the_hd_map_builds_the_asked_lanes():
    hd = build_hdmap(local_grid(), lanes={"local": 2})
    for road in hd.roads.values():
        expected = 2 if road.road_class == "local" else 1
        assert road.lane_count == expected
        assert len(road.lanes("f")) == len(road.lanes("b")) == expected


def test_a_scenario_with_three_lane_arterials_passes(tmp_path):
    out = tmp_path / "lanes"
    code = main(["make-scenario", "--density", "30", "--vehicles", "80", "--size", "1000",
                 "--duration", "600", "--skeleton", "procedural", "--lanes", "arterial=3",
                 "--out", str(out)])
    report = json.loads((out / "report.json").read_text())
    assert code == 0 and report["passed"] and report["simulation"]["collisions"] == 0
    net = (out / "map.net.xml").read_text()
    hd_lanes = {}
    for edge, body in re.findall(r'<edge id="(r\d+_[fb])"[^>]*>(.*?)</edge>', net, re.DOTALL):
        hd_lanes[edge] = body.count("<lane ")
    assert max(hd_lanes.values()) >= 3 and 3 in hd_lanes.values()
    assert json.loads((out / "spec.json").read_text())["lanes"] == {"arterial": 3}


def test_lanes_that_are_not_whole_are_a_one_line_error(tmp_path, capsys):
    code = main(["make-scenario", "--density", "30", "--vehicles", "10", "--lanes",
                 "arterial=2.5", "--out", str(tmp_path / "x")])
    assert code == 2
    assert capsys.readouterr().err.strip().splitlines() == [
        "roadweaver-sumo: error: --lanes: lane counts are whole numbers, e.g. arterial=3"]
