"""Junction control by regional rules (issue 36): what each rule set puts in the SUMO net, and
the rule coverage report.json counts on it."""

import pytest

import roadweaver_sumo as rw
from roadweaver_sumo.cli import main


@pytest.fixture(scope="module")
def default(tmp_path_factory):
    spec = rw.ScenarioSpec(density=30, vehicles=150, duration=900)
    return rw.make_scenario(spec, tmp_path_factory.mktemp("de") / "scenario")


def test_the_default_scenario_has_four_junction_controls_and_passes(default):
    """de rules on the main command's map: lights, yield, stop onto arterials and
    right-before-left among residential streets; SUMO drives it without collision."""
    assert default.report.passed
    rules = default.report["net"]["rules"]
    assert {"traffic_light", "priority", "priority_stop", "right_before_left"} <= set(
        rules["junction_controls"])
    assert "allway_stop" not in rules["junction_controls"]
    turns = rules["turns_by_rule"]
    assert turns["stop"] > 0 and turns["right_before_left"] > 0 and turns["signalised"] > 0
    assert rules["speed_limits_kmh"] == [30, 40, 50] and rules["speed_limit_changes"] > 0


def test_us_rules_make_all_way_stops_and_stop_signs(tmp_path):
    spec = rw.ScenarioSpec(density=30, vehicles=150, duration=900, rules="us")
    report = rw.make_scenario(spec, tmp_path / "us").report
    assert report.passed
    controls = report["net"]["rules"]["junction_controls"]
    assert controls["allway_stop"] > 0 and controls["priority_stop"] > controls.get("priority", 0)
    assert "right_before_left" not in controls


def test_unknown_rules_are_one_line_errors(tmp_path, capsys):
    assert main(["make-scenario", "--density", "30", "--vehicles", "10", "--rules", "fr",
                 "--out", str(tmp_path / "x")]) == 2
    err = capsys.readouterr().err
    assert "unknown rules 'fr'; choose one of de, us, priority" in err
    assert err.count("\n") == 1 and not (tmp_path / "x").exists()


def test_fringe_factor_sends_through_traffic_across_the_map_and_geo_origin_places_it(tmp_path):
    """--fringe-factor 10 (randomTrips', on the border dead ends marked fringe="outer"):
    most trips start where a road leaves the map; --geo-origin moves every format's
    geo-reference; both are in spec.json."""
    import json

    import sumolib
    from lxml import etree

    folder = tmp_path / "through"
    assert main(["make-scenario", "--density", "30", "--vehicles", "200", "--duration", "900",
                 "--fringe-factor", "10", "--geo-origin", "52.52,13.405", "--no-validate",
                 "--out", str(folder)]) == 0
    net = sumolib.net.readNet(str(folder / "map.net.xml"))
    outer = {n.getID() for n in net.getNodes() if n.getFringe() == "outer"}
    assert outer and all(min(x, y, 2000 - x, 2000 - y) < 1.0 for x, y in
                         (net.getNode(n).getCoord()[:2] for n in outer))  # on the border
    starts = [v.find("route").get("edges").split()[0]
              for v in etree.parse(str(folder / "demand.rou.xml")).getroot().iter("vehicle")]
    share = sum(net.getEdge(e).getFromNode().getID() in outer for e in starts) / len(starts)
    assert share > 0.6
    spec = json.loads((folder / "spec.json").read_text())
    assert spec["fringe_factor"] == 10.0 and spec["geo_origin"] == [52.52, 13.405]
    assert "+lat_0=52.52 +lon_0=13.405" in (folder / "map.net.xml").read_text()
    bounds = etree.parse(str(folder / "lanelet2_map.osm")).getroot().find("bounds")
    assert abs(float(bounds.get("minlat")) - 52.52) < 0.01


def test_bad_geo_origin_is_a_one_line_error(tmp_path, capsys):
    assert main(["make-scenario", "--density", "30", "--vehicles", "10", "--geo-origin",
                 "95,10", "--out", str(tmp_path / "x")]) == 2
    err = capsys.readouterr().err
    assert "--geo-origin: latitude 95 is outside -85..85 degrees" in err and err.count("\n") == 1


def test_insertion_rate_gives_the_vehicles_over_the_duration(tmp_path, capsys):
    """--insertion-rate (randomTrips' vehicles per hour) instead of --vehicles; not both."""
    import json

    folder = tmp_path / "rate"
    assert main(["make-scenario", "--density", "30", "--insertion-rate", "300", "--duration",
                 "600", "--no-validate", "--out", str(folder)]) == 0
    assert json.loads((folder / "spec.json").read_text())["vehicles"] == 50
    assert (folder / "demand.rou.xml").read_text().count("<vehicle ") == 50
    capsys.readouterr()
    assert main(["make-scenario", "--density", "30", "--vehicles", "10", "--insertion-rate",
                 "300", "--out", str(tmp_path / "both")]) == 2
    assert "not allowed with argument --vehicles" in capsys.readouterr().err
