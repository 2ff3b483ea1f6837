"""Closed loop (issue 37): ego routes, the control loop over libsumo and the driving score."""

import json
import subprocess
from itertools import pairwise
from pathlib import Path

import pytest

import roadweaver_sumo as rw
from roadweaver_sumo.cli import main
from roadweaver_sumo.closed_loop.drive import SSM_THRESHOLDS
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
        roads = [e.rsplit("_", 1)[0] for e in r["edges"]]
        assert len(set(roads)) == len(roads)  # no road driven twice
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


def test_the_tutorial_example_controller_keeps_signals_and_limits(scenario):
    """The controller the closed-loop tutorial shows (docs/closed_loop.md; the same text as
    docs/examples/my_stack.py) drives both routes to the end without running a light or
    speeding."""
    import importlib.util

    root = Path(__file__).resolve().parents[1]
    source = (root / "docs" / "examples" / "my_stack.py").read_text()
    assert source.rstrip() in (root / "docs" / "closed_loop.md").read_text()
    spec = importlib.util.spec_from_file_location("my_stack", root / "docs/examples/my_stack.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    for route in (0, 1):
        report = rw.closed_loop.run(scenario, module.control, route=route)
        assert report["arrived"], report
        assert not {"red_light", "speeding", "stop_sign"} & set(report["infraction_counts"]), report


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


ESMINI = Path(__file__).resolve().parents[2] / "shared" / "tools" / "esmini" / "esmini"


def test_openscenario_routes_lie_on_the_xodr_lanes_of_their_sumo_edges(scenario):
    """Each ego_route_K.xosc loads map.xodr and puts one waypoint on every route edge, on the
    OpenDRIVE road and lane the edge was exported to (a lane of the edge's driving direction),
    and one on the connecting road between each two; the ego starts on the first one; the
    file is OpenSCENARIO 1.2."""
    from lxml import etree

    xodr = etree.parse(str(scenario / "map.xodr")).getroot()
    lanes = {(road.get("id"), lane.get("id")) for road in xodr.iterfind("road")
             for lane in road.iter("lane") if lane.get("type") == "driving"}
    for k, route in enumerate(json.loads((scenario / "routes.json").read_text())):
        root = etree.parse(str(scenario / f"ego_route_{k}.xosc")).getroot()
        assert root.find("FileHeader").get("revMinor") == "2"
        assert root.find("RoadNetwork/LogicFile").get("filepath") == "map.xodr"
        points = [w.find("Position/LanePosition") for w in root.iter("Waypoint")]
        assert len(points) == 2 * len(route["edges"]) - 1  # edges, and connecting roads between
        for edge, point in zip(route["edges"], points[::2]):
            road, direction = edge[1:].rsplit("_", 1)
            assert point.get("roadId") == road and (point.get("roadId"), point.get("laneId")) in lanes
            assert (int(point.get("laneId")) < 0) == (direction == "f")
        for before, point, after in zip(points[::2], points[1::2], points[2::2]):
            link = xodr.find(f"road[@id='{point.get('roadId')}']")
            assert link.get("junction") != "-1"
            assert [link.find(f"link/{end}").get("elementId") for end in ("predecessor",
                    "successor")] == [before.get("roadId"), after.get("roadId")]
        start = root.find("Storyboard/Init/Actions/Private[@entityRef='ego']").find(
            ".//TeleportAction/Position/LanePosition")
        assert start.attrib == points[0].attrib


@pytest.mark.skipif(not ESMINI.exists(), reason="esmini is in ../shared/tools only")
def test_esmini_drives_every_openscenario_route_to_its_end(scenario, tmp_path):
    """esmini (a player we did not write) runs each file headless: the ego reaches the last
    waypoint after driving at least 80 % of the route, before the time limit, with no error
    in its log."""
    import shutil

    for k in range(2):
        work = tmp_path / str(k)
        work.mkdir()
        for name in ("map.xodr", f"ego_route_{k}.xosc"):
            shutil.copy(scenario / name, work / name)
        run = subprocess.run([str(ESMINI), "--headless", "--osc", f"ego_route_{k}.xosc",
                              "--fixed_timestep", "0.05", "--disable_stdout"], cwd=work,
                             capture_output=True, text=True, timeout=300, check=False)
        assert run.returncode == 0, run.stdout[-2000:]
        log = (work / "log.txt").read_text()
        assert "arrived: true" in log and "driven_most: true" in log, log[-2000:]
        assert "time_limit: true" not in log
        errors = [ln for ln in log.splitlines() if "[error]" in ln and "geo reference" not in ln]
        assert not errors, errors[:3]


def test_drive_suite_scores_every_route_and_names_what_a_new_controller_breaks(tmp_path, capsys):
    """make-suite --ego-routes, then drive-suite: SUMO's driver as the baseline table, the
    naive controller against it is a regression (exit 1) listed by scenario, route and
    infraction; the table is not overwritten without --force."""
    suite = tmp_path / "suite"
    assert main(["make-suite", "--densities", "30", "--styles", "grid,organic", "--seeds", "0",
                 "--size", "1000", "--vehicles", "100", "--duration", "900", "--ego-routes",
                 "1", "--ego-length", "1200", "--out", str(suite), "--quiet"]) == 0
    capsys.readouterr()
    assert main(["drive-suite", str(suite), "--controller", "sumo"]) == 0
    baseline = json.loads((suite / "drive_scores.json").read_text())
    assert [(r["route"], r["score"]) for r in baseline["routes"]] == [(0, 1.0), (0, 1.0)]
    assert "mean score 1.000 over 2 routes" in capsys.readouterr().out

    assert main(["drive-suite", str(suite), "--controller", "naive"]) == 2
    assert "drive_scores.json exists; use --force" in capsys.readouterr().err
    out = tmp_path / "naive.json"
    assert main(["drive-suite", str(suite), "--controller", "naive", "--out", str(out),
                 "--baseline", str(suite / "drive_scores.json")]) == 1
    captured = capsys.readouterr()
    assert "2 routes changed" in captured.out and "(worse)" in captured.out
    assert "speeding 0 -> " in captured.out
    assert "a route scores lower or has a new infraction kind" in captured.err
    assert json.loads(out.read_text())["mean_score"] < 0.9
    assert main(["drive-suite", str(suite), "--controller", "sumo", "--out", str(tmp_path / "again.json"),
                 "--baseline", str(suite / "drive_scores.json")]) == 0
    assert "0 routes changed" in capsys.readouterr().out


def test_drive_suite_refuses_a_suite_without_ego_routes(tmp_path, capsys):
    suite = tmp_path / "suite"
    assert main(["make-suite", "--densities", "30", "--styles", "grid", "--seeds", "0",
                 "--size", "500", "--vehicles", "20", "--duration", "300", "--out", str(suite),
                 "--quiet"]) == 0
    capsys.readouterr()
    assert main(["drive-suite", str(suite)]) == 2
    err = capsys.readouterr().err
    assert "the suite has no ego routes; make it with make-suite --ego-routes N" in err
    assert err.count("\n") == 1


REMOTE_STACK = """
import sys, traci
traci.init(int(sys.argv[1]))
traci.setOrder(2)
seen = False
while traci.simulation.getMinExpectedNumber() > 0:
    traci.simulationStep()
    if "ego" in traci.vehicle.getIDList():
        seen = True
        traci.vehicle.setSpeedMode("ego", 0)
        traci.vehicle.setSpeed("ego", 1.3 * traci.vehicle.getAllowedSpeed("ego"))
    elif seen:
        break
traci.close()
"""


def test_a_stack_in_another_process_drives_over_traci_and_is_scored(scenario, capsys):
    """--remote-port: a speeding stack that connects as TraCI client 2 drives the ego; the
    drive loop scores it as it would a controller of its own."""
    import sys

    from sumolib.miscutils import getFreeSocketPort

    port = getFreeSocketPort()
    stack = subprocess.Popen([sys.executable, "-c", REMOTE_STACK, str(port)])
    try:
        assert main(["drive", str(scenario), "--route", "0", "--remote-port", str(port),
                     "--json"]) == 0
    finally:
        stack.wait(timeout=120)
    report = json.loads(capsys.readouterr().out)
    assert report["controller"] == f"external (TraCI port {port})"
    assert report["infraction_counts"].get("speeding", 0) >= 1 and report["score"] < 0.95
    assert stack.returncode == 0
    assert main(["drive", str(scenario), "--controller", "naive", "--remote-port",
                 str(port)]) == 2
    assert "give --controller or --remote-port, not both" in capsys.readouterr().err


def test_near_misses_come_from_sumos_ssm_device(scenario):
    """Conflicts that SUMO's SSM device logs around the ego (time to collision or
    post-encroachment time below its thresholds) are listed with the other vehicle and time;
    they happen in plain driving (SUMO's own driver on these routes) and are not scored."""
    reports = [rw.closed_loop.run(scenario, "sumo", route=k) for k in (0, 1)]
    assert all(r["score"] == 1.0 for r in reports)
    conflicts = [c for r in reports for c in r["near_misses"]["conflicts"]]
    assert len(conflicts) == sum(r["near_misses"]["count"] for r in reports) >= 1
    ttc, pet = (float(v) for v in SSM_THRESHOLDS.split())
    for c in conflicts:
        assert c["other"] and c["time"] > 0
        assert c.get("minTTC", ttc) < ttc or c.get("PET", pet) < pet


def test_stop_signs_are_kept_by_sumo_and_the_example_and_run_by_the_naive_controller(tmp_path):
    """Under US rules most junctions have stop signs: SUMO's driver and the tutorial's example
    controller stand still at each; the naive controller rolls through and each time is a
    stop_sign infraction naming the lane and SUMO's link state (s: stop, w: all-way stop)."""
    import importlib.util

    spec = rw.ScenarioSpec(density=30, vehicles=100, duration=600, seed=4, rules="us",
                           ego_routes=1, ego_length=2500)
    folder = tmp_path / "us"
    rw.make_scenario(spec, folder, validate=False)
    route = json.loads((folder / "routes.json").read_text())[0]
    assert any("_stop" in kind for kind in route["situations"])
    assert rw.closed_loop.run(folder, "sumo", route=0)["infractions"] == []
    example = importlib.util.spec_from_file_location(
        "my_stack", Path(__file__).resolve().parents[1] / "docs/examples/my_stack.py")
    module = importlib.util.module_from_spec(example)
    example.loader.exec_module(module)
    report = rw.closed_loop.run(folder, module.control, route=0)
    assert report["arrived"] and "stop_sign" not in report["infraction_counts"], report
    naive = rw.closed_loop.run(folder, "naive", route=0)
    signs = [i for i in naive["infractions"] if i["type"] == "stop_sign"]
    assert signs and all(i["link_state"] in "sw" and i["lane"].rsplit("_", 1)[0] in
                         route["edges"] for i in signs)
