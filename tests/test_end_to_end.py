"""make-scenario end to end on a small map: real netconvert, randomTrips, libsumo runs."""

import filecmp
import json
import subprocess
import sys
from pathlib import Path

import pytest
from lxml import etree

from roadweaver_sumo.cli import main
from roadweaver_sumo.spec import DEFAULT_PERSONS
from roadweaver_sumo.sumo_tools import binary, strip_generated_comment

ARGS = ["make-scenario", "--density", "30", "--vehicles", "60", "--size", "800",
        "--duration", "300", "--seed", "1", "--style", "grid"]
EXPECTED_FILES = {
    "scenario.sumocfg", "map.net.xml", "demand.rou.xml", "spec.json", "report.json",
    "netconvert.netccfg", "timing.json", "plain", "map.xodr", "lanelet2_map.osm", "preview.png",
    "bus_lines.rou.xml", "bus_stops.add.xml", "persons.rou.xml",
}


@pytest.fixture(scope="module")
def scenario(tmp_path_factory):
    out = tmp_path_factory.mktemp("e2e") / "a"
    assert main([*ARGS, "--out", str(out)]) == 0
    return out


def test_scenario_folder_is_complete_and_passes(scenario):
    assert {p.name for p in scenario.iterdir()} == EXPECTED_FILES
    assert {p.name for p in (scenario / "plain").iterdir()} == {
        "map.nod.xml", "map.edg.xml", "map.con.xml"}
    report = json.loads((scenario / "report.json").read_text())
    assert report["passed"] and report["failures"] == []
    net, sim = report["net"], report["simulation"]
    assert abs(net["density"] - 30) / 30 <= 0.10
    assert net["lcc_ratio"] == 1.0 and net["crossings_without_junction"] == 0
    assert net["lane_reachability"] >= 0.995
    assert net["alignment"]["mean"] <= 0.05
    buses = 2 * report["generation"]["bus_lines"]["lines"]  # one from each end within 300 s
    assert sim["loaded"] == 60 + buses and sim["arrived"] >= 59 + buses
    assert sim["collisions"] == 0
    assert sim["persons_loaded"] == DEFAULT_PERSONS and sim["persons_arrived"] == DEFAULT_PERSONS
    assert report["net"]["rules"]["pedestrian_crossings"]
    assert report["generation"]["hdmap"]["strongly_connected"]


def test_timing_has_every_stage_and_the_whole_run(scenario):
    timing = json.loads((scenario / "timing.json").read_text())
    stages = timing["stages_s"]
    assert set(stages) == {"skeleton", "expansion", "hdmap", "export", "netconvert", "formats",
                           "demand", "validate", "preview"}
    assert min(stages.values()) > 0
    assert sum(stages.values()) <= timing["total_s"]  # the stages run one after another
    assert timing["validation"]


def test_same_seed_gives_byte_identical_folder(scenario, tmp_path):
    again = tmp_path / "b"
    assert main([*ARGS, "--out", str(again)]) == 0
    cmp = filecmp.dircmp(scenario, again, ignore=["timing.json"])
    assert cmp.diff_files == [] and cmp.left_only == [] and cmp.right_only == []
    assert filecmp.dircmp(scenario / "plain", again / "plain").diff_files == []


def test_sumocfg_runs_with_sumo_from_any_directory(scenario, tmp_path):
    proc = subprocess.run([binary("sumo"), "-c", str(scenario / "scenario.sumocfg"),
                           "--no-step-log", "--duration-log.statistics"],
                          cwd=tmp_path, capture_output=True, text=True, timeout=120, check=False)
    assert proc.returncode == 0, proc.stderr
    vehicles = proc.stdout.split("Vehicles:")[1]
    buses = len(etree.parse(str(scenario / "bus_lines.rou.xml")).getroot().findall("route"))
    inserted = 60 + buses  # one bus leaves each end of a line at 0 s (the next after 600 s)
    assert f"Inserted: {inserted}" in vehicles and "Running: 0" in vehicles
    assert "Waiting: 0" in vehicles


def test_netconvert_reproduces_the_net_from_the_written_template(scenario, tmp_path):
    copy = tmp_path / "copy"
    copy.mkdir()
    (copy / "plain").mkdir()
    for name in ("map.nod.xml", "map.edg.xml", "map.con.xml"):
        (copy / "plain" / name).write_bytes((scenario / "plain" / name).read_bytes())
    (copy / "netconvert.netccfg").write_bytes((scenario / "netconvert.netccfg").read_bytes())
    proc = subprocess.run([binary("netconvert"), "-c", "netconvert.netccfg"], cwd=copy,
                          capture_output=True, text=True, check=False)
    assert proc.returncode == 0, proc.stderr
    strip_generated_comment(copy / "map.net.xml")
    assert (copy / "map.net.xml").read_bytes() == (scenario / "map.net.xml").read_bytes()


def test_validate_command_rewrites_the_same_report(scenario):
    before = (scenario / "report.json").read_bytes()
    assert main(["validate", str(scenario)]) == 0
    assert (scenario / "report.json").read_bytes() == before


def test_force_replaces_a_folder(tmp_path):
    out = tmp_path / "s"
    out.mkdir()
    (out / "old.txt").write_text("old")
    assert main([*ARGS, "--no-validate", "--vehicles", "10", "--out", str(out), "--force"]) == 0
    assert not (out / "old.txt").exists() and (out / "map.net.xml").exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s"]


def test_console_script_is_installed():
    proc = subprocess.run([str(Path(sys.executable).parent / "roadweaver-sumo"), "--version"],
                          capture_output=True, text=True, check=False)
    assert proc.returncode == 0 and proc.stdout.startswith("roadweaver-sumo ")
