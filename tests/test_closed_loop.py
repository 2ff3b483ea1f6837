"""Closed loop (issue 37): ego routes, the control loop over libsumo and the driving score."""

import json
import subprocess
from itertools import pairwise

import pytest

import roadweaver_sumo as rw
from roadweaver_sumo.cli import main
from roadweaver_sumo.closed_loop.routes import FRINGE_M, LENGTH_TOLERANCE
from roadweaver_sumo.sumo_tools import binary


@pytest.fixture(scope="module")
def scenario(tmp_path_factory):
    folder = tmp_path_factory.mktemp("drive") / "scenario"
    spec = rw.ScenarioSpec(density=30, vehicles=200, duration=600, seed=2, ego_routes=2,
                           ego_length=3000)
    rw.make_scenario(spec, folder, validate=False)
    return folder


def test_ego_routes_are_long_inner_and_load_in_sumo(scenario):
    routes = json.loads((scenario / "routes.json").read_text())
    assert [r["id"] for r in routes] == ["ego_route_0", "ego_route_1"]
    import sumolib

    net = sumolib.net.readNet(str(scenario / "map.net.xml"))
    x0, y0, x1, y1 = net.getBoundary()
    for r in routes:
        assert abs(r["length_m"] - 3000) <= LENGTH_TOLERANCE * 3000
        assert sum(net.getEdge(e).getLength() for e in r["edges"]) == pytest.approx(
            r["length_m"], abs=0.1)
        for e in (r["edges"][0], r["edges"][-1]):
            x, y = net.getEdge(e).getFromNode().getCoord()[:2]
            assert min(x - x0, y - y0, x1 - x, y1 - y) > FRINGE_M
        assert sum(r["situations"].values()) > 5 and not any("u_turn" in k for k in r["situations"])
    run = subprocess.run([binary("sumo"), "-c", str(scenario / "scenario.sumocfg"),
                          "--route-files", "demand.rou.xml,ego_routes.rou.xml", "--end", "1500",
                          "--no-step-log", "true", "--tripinfo-output", "trips.xml"],
                         cwd=scenario, capture_output=True, text=True, check=False)
    assert run.returncode == 0, run.stderr
    assert 'id="ego_0"' in (scenario / "trips.xml").read_text()


def test_sumo_drives_clean_and_the_naive_controller_is_caught(scenario):
    reference = rw.closed_loop.run(scenario, "sumo", route=0)
    assert reference["arrived"] and reference["score"] == 1.0
    assert reference["infractions"] == []
    naive = rw.closed_loop.run(scenario, "naive", route=0)
    assert naive["route_completion"] == 1.0
    assert naive["infraction_counts"]["speeding"] >= 1
    assert naive["score"] < 0.9 * reference["score"]
    for red in (i for i in naive["infractions"] if i["type"] == "red_light"):
        assert red["state"] == "r" and red["signal"]
    assert naive["loop_overhead_ms"] < 1.0


def test_a_controller_that_never_moves_is_blocked(scenario):
    report = rw.closed_loop.run(scenario, lambda obs: {"speed": 0.0}, route=1)
    assert [i["type"] for i in report["infractions"]] == ["blocked"]
    assert not report["arrived"] and report["route_completion"] < 0.05
    assert report["score"] == pytest.approx(0.7 * report["route_completion"], abs=1e-4)


def test_drive_command_writes_its_report_and_refuses_bad_input(scenario, tmp_path, capsys):
    out = tmp_path / "report.json"
    assert main(["drive", str(scenario), "--route", "1", "--out", str(out)]) == 0
    assert json.loads(out.read_text())["route"] == "ego_route_1"
    assert "score 1.000" in capsys.readouterr().out
    for args, message in ((["--controller", "nowhere:drive"], "not sumo, naive or an importable"),
                          (["--route", "5"], "the scenario has routes 0..1")):
        assert main(["drive", str(scenario), *args]) == 2
        err = capsys.readouterr().err
        assert message in err and err.count("\n") == 1
    assert main(["drive", str(tmp_path)]) == 2
    assert "not a scenario folder" in capsys.readouterr().err


def test_the_readme_example_controller_keeps_signals_and_limits(scenario):
    """The controller the README shows (docs/examples/my_stack.py, the same text) drives both
    routes to the end without running a light or speeding."""
    import importlib.util
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    source = (root / "docs" / "examples" / "my_stack.py").read_text()
    assert source.rstrip() in (root / "README.md").read_text()
    spec = importlib.util.spec_from_file_location("my_stack", root / "docs/examples/my_stack.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    for route in (0, 1):
        report = rw.closed_loop.run(scenario, module.control, route=route)
        assert report["arrived"], report
        assert not {"red_light", "speeding"} & set(report["infraction_counts"]), report


def test_carla_route_files_lie_on_connected_lanes_of_the_xodr(scenario):
    """Every waypoint of carla_routes.xml is on a lane of map.xodr as CARLA's map code reads it
    (PyPI ``carla``, no server), and each next one is reachable in CARLA's topology."""
    carla = pytest.importorskip("carla")
    import networkx as nx
    from lxml import etree
    from test_carla import topology_graph

    m = carla.Map("map", (scenario / "map.xodr").read_text())
    graph = topology_graph(m)
    routes = etree.parse(str(scenario / "carla_routes.xml")).getroot().findall("route")
    assert len(routes) == 2
    for route in routes:
        keys = []
        for p in route.iter("position"):
            x, y = float(p.get("x")), float(p.get("y"))
            w = m.get_waypoint(carla.Location(x, y, 0.0))
            assert w.transform.location.distance(carla.Location(x, y, 0.0)) < 0.5 * w.lane_width
            keys.append((w.road_id, w.section_id, w.lane_id))
        assert len(keys) > 10
        for a, b in pairwise(keys):
            assert nx.has_path(graph, a, b), (a, b)
