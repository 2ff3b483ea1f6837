"""Validation: net metrics read back from .net.xml, libsumo runs, thresholds and report.json."""

from __future__ import annotations

import json
import os
from pathlib import Path

import networkx as nx
import pytest

from roadweaver_sumo.errors import RoadweaverError
from roadweaver_sumo.scenario.demand import write_demand
from roadweaver_sumo.scenario.sumocfg import write_sumocfg
from roadweaver_sumo.sumo_tools import binary, run
from roadweaver_sumo.validate.net_metrics import net_metrics, reachable_share
from roadweaver_sumo.validate.netgraph import lane_graph, load_net, road_graph
from roadweaver_sumo.validate.report import (
    check_thresholds,
    summary_lines,
    validate_scenario,
    wall_cap_s,
    write_report,
)
from roadweaver_sumo.validate.simulation import run_simulation, started_simulation

GRID = 3  # junctions per side: 9 junctions, 24 one-lane edges, 150 m blocks (300 x 300 m)


def _grid(folder: Path, *extra: str) -> Path:
    """A netgenerate grid written as ``folder/map.net.xml`` (``extra``: more netconvert steps)."""
    folder.mkdir(parents=True, exist_ok=True)
    run([binary("netgenerate"), "--grid", "--grid.number", str(GRID), "--grid.length", "150",
         "-o", "grid.net.xml"], folder, "netgenerate")  # fmt: skip
    run(
        [binary("netconvert"), "-s", "grid.net.xml", *extra, "-o", "map.net.xml"],
        folder,
        "netconvert",
    )
    (folder / "grid.net.xml").unlink()
    return folder / "map.net.xml"


def _scenario(folder: Path, vehicles: int = 120, duration: float = 240.0, seed: int = 4) -> Path:
    """Demand, sumocfg and spec.json next to ``folder/map.net.xml``."""
    write_demand(folder, vehicles=vehicles, duration=duration, seed=seed)
    write_sumocfg(folder, duration=duration, seed=seed)
    spec = {"width": 300, "height": 300, "seed": seed, "vehicles": vehicles, "duration": duration}
    (folder / "spec.json").write_text(json.dumps(spec), encoding="utf-8")
    return folder


@pytest.fixture(scope="module")
def healthy(tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp("healthy")
    _grid(folder)
    return _scenario(folder)


def test_reachable_share_counts_ordered_pairs_of_distinct_nodes():
    D = nx.DiGraph([("a", "b"), ("b", "c"), ("c", "b")])
    D.add_node("d")
    # a reaches b, c; b reaches c; c reaches b; d nothing: 4 of 4 * 3 ordered pairs
    assert reachable_share(D, D.nodes, D.nodes, key=lambda n: n) == pytest.approx(4 / 12)


def test_lane_and_junction_reachability_on_a_one_way_chain(tmp_path):
    # A -> B -> C, one way; A->B has two lanes. Lanes: AB_0 and AB_1 reach each other (lane
    # change) and BC_0; BC_0 reaches nothing: 4 of 6 pairs. Junctions: AB, AC, BC of 6 pairs.
    (tmp_path / "n.nod.xml").write_text(
        '<nodes><node id="A" x="0" y="0"/><node id="B" x="100" y="0"/>'
        '<node id="C" x="200" y="0"/></nodes>'
    )
    (tmp_path / "e.edg.xml").write_text(
        '<edges><edge id="AB" from="A" to="B" numLanes="2"/>'
        '<edge id="BC" from="B" to="C" numLanes="1"/></edges>'
    )
    args = [binary("netconvert"), "-n", "n.nod.xml", "-e", "e.edg.xml", "-o", "map.net.xml"]
    run(args, tmp_path, "netconvert")
    lanes = lane_graph(load_net(tmp_path / "map.net.xml"))
    assert sorted(lanes.nodes) == ["AB_0", "AB_1", "BC_0"]
    assert lanes.edges["AB_0", "AB_1"]["kind"] == "lane_change"
    metrics = net_metrics(tmp_path / "map.net.xml", area_km2=0.02)
    assert metrics["lane_reachability"] == pytest.approx(4 / 6)
    assert metrics["junction_reachability"] == pytest.approx(3 / 6)


def test_grid_net_reads_back_as_a_road_graph_with_aligned_lane_ends(tmp_path):
    net_path = _grid(tmp_path)
    G = road_graph(load_net(net_path))
    assert G.number_of_nodes() == GRID * GRID
    assert G.number_of_edges() == 2 * GRID * (GRID - 1)  # both directions merged into one road
    for u, v, data in G.edges(data=True):
        assert tuple(data["coords"][0]) == G.nodes[data["start"]]["xy"]
        assert tuple(data["coords"][-1]) == G.nodes[v if data["start"] == u else u]["xy"]
    metrics = net_metrics(net_path, area_km2=0.09)
    assert metrics["lcc_ratio"] == 1.0 and metrics["crossings_without_junction"] == 0
    assert metrics["lane_reachability"] == 1.0 and metrics["junction_reachability"] == 1.0
    assert metrics["alignment"]["count"] > 0 and metrics["alignment"]["max"] < 1e-6


def test_healthy_grid_scenario_passes_every_threshold(healthy):
    report, timing = validate_scenario(healthy)
    assert report["failures"] == [] and report["passed"] is True
    sim = report["simulation"]
    assert sim["arrived"] >= 0.99 * 120 and sim["completed"] and sim["collisions"] == 0
    assert sim["routing_success_rate"] == 1.0 and sim["collision_sites"] == []
    assert timing["sim_s_per_wall_s"] > 0 and timing["routing_ms_per_route"] > 0
    first = write_report(healthy, report).read_bytes()
    again, _ = validate_scenario(healthy)
    assert write_report(healthy, again).read_bytes() == first  # deterministic, no timings inside
    assert json.loads(first)["schema_version"] == 1
    assert 5 <= len(summary_lines(report)) <= 10 and summary_lines(report)[0].startswith("PASSED")


def test_net_with_a_sink_corner_fails_on_lane_reachability(tmp_path):
    # Both roads leaving corner A0 removed: cars can drive into A0 but never out again.
    _grid(tmp_path, "--remove-edges.explicit", "A0A1,A0B0")
    report, _ = validate_scenario(_scenario(tmp_path))
    assert not report["passed"]
    assert report["net"]["lcc_ratio"] == 1.0  # still one piece on the undirected map
    failed = [f for f in report["failures"] if f.startswith("net.lane_reachability")]
    assert len(failed) == 1 and "limit >= 0.995" in failed[0], report["failures"]


def test_wall_cap_stops_the_run_and_fails_completion(healthy):
    results, _ = run_simulation(healthy, wall_cap_s=0.0, routing_tasks=10)
    assert results["completed"] is False and results["arrived"] < 120
    failures = check_thresholds({"simulation": results})
    assert any(f.startswith("simulation.completed") for f in failures)


def test_wall_cap_grows_with_the_vehicles_beyond_a_thousand():
    """A 10,000-vehicle run on a 20 km map goes 10-17 sim-s per wall-s when healthy: its cap
    allows ten times the floor speed of a run of up to 1000 vehicles, which keeps its cap."""
    one_hour = wall_cap_s(3600.0, 500)
    assert one_hour == wall_cap_s(3600.0, 1000) == 60.0 + 7200.0 / 20.0
    assert wall_cap_s(3600.0, 10000) - 60.0 == pytest.approx(10 * (one_hour - 60.0))
    assert wall_cap_s(7200.0, 500) > one_hour


def test_simulation_that_cannot_load_raises_a_one_line_error(healthy, tmp_path):
    for name in ("map.net.xml", "scenario.sumocfg"):
        (tmp_path / name).write_bytes((healthy / name).read_bytes())
    (tmp_path / "demand.rou.xml").write_text(
        '<routes><vehicle id="v" depart="0"><route edges="nowhere"/></vehicle></routes>'
    )
    with pytest.raises(RoadweaverError, match="sumo could not load .*nowhere") as caught:
        run_simulation(tmp_path, wall_cap_s=10.0, routing_tasks=1)
    assert "\n" not in str(caught.value)


def test_report_without_validation_figures_fails_with_one_line(tmp_path):
    report = json.loads(write_report(tmp_path, {"validated": False}).read_text())
    assert report["passed"] is False and report["schema_version"] == 1
    assert report["failures"] == ["not validated: the report has no net or simulation figures"]


def test_validation_with_net_figures_measured_before_reports_the_same(healthy):
    figures = net_metrics(healthy / "map.net.xml", area_km2=0.09)
    given, timing = validate_scenario(healthy, net_figures=figures)
    measured, _ = validate_scenario(healthy)
    assert given == measured and "net_metrics_s" not in timing
    figures["lcc_ratio"] = 0.5  # the given figures are the ones judged
    assert validate_scenario(healthy, net_figures=figures)[0]["failures"][0].startswith(
        "net.lcc_ratio")


def _children() -> list[int]:
    me, out = os.getpid(), []
    for entry in os.listdir("/proc"):
        try:
            stat = Path(f"/proc/{entry}/stat").read_text()
        except OSError:
            continue
        if entry.isdigit() and int(stat.rsplit(")", 1)[1].split()[1]) == me:
            out.append(int(entry))
    return out


@pytest.mark.parametrize("split_routing, children", [(True, 2), (False, 1)])
def test_simulation_children_are_killed_when_the_caller_fails(healthy, split_routing, children):
    before = set(_children())
    with pytest.raises(RuntimeError, match="measuring failed"), \
            started_simulation(healthy, wall_cap_s=60.0, split_routing=split_routing):
        assert len(set(_children()) - before) == children  # simulation (+ routing) child
        raise RuntimeError("measuring failed")
    assert set(_children()) - before == set()


def test_routing_in_the_simulations_process_reports_the_same(healthy):
    """A suite's workers keep the cores busy, so there the simulation's child answers the
    routing queries itself instead of a second child loading the net again."""
    split, split_timing = validate_scenario(healthy)
    single, single_timing = validate_scenario(healthy, split_routing=False)
    assert single == split
    assert single_timing["routing_ms_per_route"] > 0 and split_timing["routing_ms_per_route"] > 0
