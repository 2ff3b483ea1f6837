"""Stage 5: demand and sumocfg, checked on real SUMO runs over small netgenerate grids."""

from __future__ import annotations

import subprocess
from collections import Counter
from itertools import pairwise
from pathlib import Path

import pytest
from lxml import etree

from roadweaver_sumo.scenario import demand
from roadweaver_sumo.scenario.demand import write_demand
from roadweaver_sumo.scenario.sumocfg import end_time, write_sumocfg
from roadweaver_sumo.sumo_tools import binary, child_env, run, strip_generated_comment


@pytest.fixture(scope="module")
def grid_net(tmp_path_factory) -> Path:
    """A 4 x 4 grid, 150 m blocks, two lanes each way (built once for the module)."""
    folder = tmp_path_factory.mktemp("grid")
    args = [binary("netgenerate"), "--grid", "--grid.number", "4", "--grid.length", "150",
            "--default.lanenumber", "2", "-o", "map.net.xml"]  # fmt: skip
    run(args, folder, "netgenerate")
    strip_generated_comment(folder / "map.net.xml")
    return folder / "map.net.xml"


def _scenario_dir(tmp_path: Path, grid_net: Path, name: str = "scenario") -> Path:
    folder = tmp_path / name
    folder.mkdir()
    (folder / "map.net.xml").write_bytes(grid_net.read_bytes())
    return folder


def _vehicles(demand: Path) -> list:
    return list(etree.parse(str(demand)).getroot().iter("vehicle"))


def test_demand_has_exactly_the_requested_vehicles_spread_over_the_duration(tmp_path, grid_net):
    folder = _scenario_dir(tmp_path, grid_net)
    demand = write_demand(folder, vehicles=137, duration=300.0, seed=5, departures="even",
                          vehicle_mix={"passenger": 1.0})
    vehicles = _vehicles(demand)
    assert len(vehicles) == 137
    departs = [float(v.get("depart")) for v in vehicles]
    assert departs == sorted(departs) and departs[0] == 0.0 and departs[-1] < 300.0
    assert departs[-1] > 290.0  # spread over the whole duration, not bunched at the start
    routes = [v.find("route").get("edges").split() for v in vehicles]
    assert all(len(r) >= 2 and r[0] != r[-1] for r in routes)
    assert sorted(p.name for p in folder.iterdir()) == ["demand.rou.xml", "map.net.xml"]


def test_demand_mixes_sumo_vehicle_classes_departing_at_random_times(tmp_path, grid_net):
    """A mix of classes: one SUMO vType per class (SUMO's defaults for it), each vehicle's
    class drawn by its share; departures random in [0, duration), in order, not a metronome."""
    mix = {"passenger": 0.5, "truck": 0.25, "bicycle": 0.25}
    demand = write_demand(_scenario_dir(tmp_path, grid_net), vehicles=200, duration=600.0,
                          seed=3, vehicle_mix=mix)
    root = etree.parse(str(demand)).getroot()
    assert {t.get("id"): t.get("vClass") for t in root.iter("vType")} == {
        "bicycle": "bicycle", "passenger": "passenger", "truck": "truck"}
    kinds = Counter(v.get("type") for v in root.iter("vehicle"))
    assert sum(kinds.values()) == 200
    for name, share in mix.items():  # binomial: within 4 standard deviations
        assert abs(kinds[name] - 200 * share) < 4 * (200 * share * (1 - share)) ** 0.5
    departs = [float(v.get("depart")) for v in root.iter("vehicle")]
    gaps = [b - a for a, b in pairwise(departs)]
    assert departs == sorted(departs) and 0 <= departs[0] and departs[-1] < 600.0
    assert max(gaps) > 3 * min(gaps) + 1.0  # uneven, as arrivals are


def test_demand_is_byte_identical_for_the_same_seed_and_differs_for_another(tmp_path, grid_net):
    texts = []
    for name, seed in (("a", 11), ("b", 11), ("c", 12)):
        folder = _scenario_dir(tmp_path, grid_net, name)
        texts.append(write_demand(folder, vehicles=60, duration=120.0, seed=seed).read_bytes())
    assert texts[0] == texts[1]
    assert texts[0] != texts[2]
    assert b"generated on" not in texts[0]


def test_sumocfg_runs_with_sumo_from_another_working_directory(tmp_path, grid_net):
    folder = _scenario_dir(tmp_path, grid_net)
    write_demand(folder, vehicles=40, duration=60.0, seed=3)
    cfg = write_sumocfg(folder, duration=60.0, seed=3)
    assert cfg.read_bytes() == write_sumocfg(folder, duration=60.0, seed=3).read_bytes()
    assert str(tmp_path) not in cfg.read_text()  # relative paths only
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    stats = elsewhere / "stats.xml"
    proc = subprocess.run(
        [binary("sumo"), "-c", str(cfg.resolve()), "--statistic-output", "stats.xml"],
        check=False, cwd=elsewhere, env=child_env(), capture_output=True, text=True,
    )  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    vehicles = etree.parse(str(stats)).getroot().find("vehicles")
    assert vehicles.get("loaded") == "40" and vehicles.get("running") == "0"


def test_sumocfg_ends_after_the_demand_with_teleports_and_warned_collisions(tmp_path):
    cfg = etree.parse(str(write_sumocfg(tmp_path, duration=600.0, seed=9))).getroot()
    value = {e.tag: e.get("value") for e in cfg.iter() if e.get("value") is not None}
    assert float(value["end"]) == end_time(600.0) > 600.0 and value["begin"] == "0"
    assert value["time-to-teleport"] == "300" and value["collision.action"] == "warn"
    assert value["seed"] == "9"
    assert (value["net-file"], value["route-files"]) == ("map.net.xml", "demand.rou.xml")


def test_demand_tops_up_when_the_first_sample_is_too_small(tmp_path, grid_net, monkeypatch):
    monkeypatch.setattr(demand, "OVERSUPPLY", 0.4)  # attempts ask for 0.4x, 0.8x, 1.6x
    folder = _scenario_dir(tmp_path, grid_net)
    assert len(_vehicles(write_demand(folder, vehicles=30, duration=60.0, seed=1))) == 30


@pytest.mark.parametrize("first_share, threads", [(0.5, 2), (10.0, 1)])
def test_demand_routes_do_not_depend_on_how_many_trips_are_routed_first_or_on_threads(
        tmp_path, grid_net, monkeypatch, first_share, threads):
    """Routing a prefix of the sampled trips on two threads (the default) writes the file that
    routing every trip on one thread writes; so does a prefix too short to hold enough cars."""
    routed = []

    def counting_route(out_dir, *args, _route=demand._route):
        trips = etree.parse(str(out_dir / demand._ROUTED_TRIPS)).getroot().findall("trip")
        routed.append(len(trips))
        _route(out_dir, *args)

    monkeypatch.setattr(demand, "_route", counting_route)
    default = write_demand(_scenario_dir(tmp_path, grid_net, "default"), vehicles=100,
                           duration=200.0, seed=4).read_bytes()
    assert routed == [112]  # 1.02 x 100 + 10 of the 125 sampled trips
    monkeypatch.setattr(demand, "ROUTE_FIRST_SHARE", first_share)
    monkeypatch.setattr(demand, "ROUTING_THREADS", threads)
    other = write_demand(_scenario_dir(tmp_path, grid_net, "other"), vehicles=100,
                         duration=200.0, seed=4).read_bytes()
    assert other == default
    if first_share < 1:  # 60 trips hold too few cars: then all of the sampled ones are routed
        assert routed[1:] == [60, routed[-1]] and routed[-1] > 112
    else:
        assert len(routed) == 2 and routed[-1] > 112
