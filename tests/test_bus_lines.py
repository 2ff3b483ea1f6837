"""Bus lines (``--bus-lines``): routes across the map's main roads both ways, stops on lanes
buses may use along them, buses that SUMO runs to the end of their line."""

from __future__ import annotations

import itertools
import json

import pytest
import sumolib
from lxml import etree

from roadweaver_sumo.cli import main


@pytest.fixture(scope="module")
def scenario(tmp_path_factory):
    out = tmp_path_factory.mktemp("bus") / "town"
    code = main(["make-scenario", "--density", "30", "--vehicles", "80", "--size", "1500",
                 "--duration", "1200", "--skeleton", "procedural", "--bus-lines", "2",
                 "--out", str(out)])
    return out, code


def test_each_line_runs_there_and_back_on_connected_edges_with_stops(scenario):
    out, _ = scenario
    net = sumolib.net.readNet(str(out / "map.net.xml"))
    stops = {s.get("id"): s for s in etree.parse(str(out / "bus_stops.add.xml")).getroot()}
    routes = etree.parse(str(out / "bus_lines.rou.xml")).getroot().findall("route")
    assert sorted(r.get("id") for r in routes) == ["line0_back", "line0_there", "line1_back",
                                                   "line1_there"]
    for route in routes:
        edges = [net.getEdge(e) for e in route.get("edges").split()]
        assert sum(e.getLength() for e in edges) > 1000, "a line crosses the map"
        for a, b in itertools.pairwise(edges):
            assert b in a.getOutgoing(), f"{a.getID()} does not lead to {b.getID()}"
        on_route = [stops[s.get("busStop")] for s in route.findall("stop")]
        assert len(on_route) >= 2
        ids = [e.getID() for e in edges]
        positions = [ids.index(s.get("lane").rsplit("_", 1)[0]) for s in on_route]
        assert positions == sorted(positions), "stops in driving order"
        for stop in on_route:
            lane = net.getLane(stop.get("lane"))
            assert lane.allows("bus")
            assert 0 <= float(stop.get("startPos")) < float(stop.get("endPos")) <= lane.getLength()


def test_the_buses_run_and_the_scenario_counts_them(scenario):
    out, code = scenario
    report = json.loads((out / "report.json").read_text())
    sim = report["simulation"]
    buses = 4 * 2  # four routes, a bus every 10 minutes over 20 minutes
    assert sim["loaded"] == 80 + buses and sim["arrived"] == sim["loaded"]
    assert report["generation"]["bus_lines"]["lines"] == 2
    cfg = (out / "scenario.sumocfg").read_text()
    assert "bus_lines.rou.xml" in cfg and "bus_stops.add.xml" in cfg
    assert code == (0 if report["passed"] else 1)


def test_bus_lines_out_of_range_and_too_many_for_the_map_are_one_line_errors(tmp_path, capsys):
    assert main(["make-scenario", "--density", "30", "--vehicles", "10", "--bus-lines", "5",
                 "--out", str(tmp_path / "a")]) == 2
    assert main(["make-scenario", "--density", "40", "--vehicles", "10", "--size", "400",
                 "--skeleton", "procedural", "--bus-lines", "4", "--no-validate",
                 "--out", str(tmp_path / "b")]) == 2
    lines = [ln for ln in capsys.readouterr().err.splitlines() if not ln.startswith("  ")]
    assert len(lines) == 2 and "--bus-lines" in lines[0] and "--bus-lines 4" in lines[1]
    assert not (tmp_path / "b").exists(), "a failed run leaves no folder"


def test_the_default_line_is_left_out_where_the_map_has_no_room_for_it(tmp_path):
    """Asked for, a line the main roads have no room for is an error; by default the map
    goes without (a one-way triangle: no two-way main road for a line to run both ways)."""
    import subprocess

    from roadweaver_sumo.errors import RoadweaverError
    from roadweaver_sumo.scenario.bus_lines import write_bus_lines
    from roadweaver_sumo.sumo_tools import binary

    (tmp_path / "n.nod.xml").write_text(
        '<nodes><node id="a" x="0" y="0"/><node id="b" x="600" y="0"/>'
        '<node id="c" x="300" y="500"/></nodes>')
    (tmp_path / "e.edg.xml").write_text(
        '<edges><edge id="ab" from="a" to="b"/><edge id="bc" from="b" to="c"/>'
        '<edge id="ca" from="c" to="a"/></edges>')
    subprocess.run([binary("netconvert"), "-n", "n.nod.xml", "-e", "e.edg.xml", "-o",
                    "map.net.xml"], cwd=tmp_path, check=True, capture_output=True)
    with pytest.raises(RoadweaverError, match="--bus-lines 1: the map has main roads for only 0"):
        write_bus_lines(tmp_path, 1, 600.0)
    assert write_bus_lines(tmp_path, 1, 600.0, asked=False) == {
        "lines": 0, "stops": 0, "route_length_m": 0.0}
    assert not (tmp_path / "bus_lines.rou.xml").exists()
