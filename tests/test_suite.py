"""make-suite / check-suite end to end on a tiny suite (2 scenarios of 500 m), local and on Ray."""

import hashlib
import json
import re
import shutil

import pytest

from roadweaver_sumo.cli import main
from roadweaver_sumo.suite import MANIFEST_FILE

SUITE_ARGS = ["make-suite", "--densities", "20,30", "--styles", "grid", "--seeds", "0",
              "--size", "500", "--vehicles", "15", "--duration", "60", "--skeleton", "procedural",
              "--bus-lines", "0"]
NAMES = ["grid-d20-500x500-s0-v15", "grid-d30-500x500-s0-v15"]


@pytest.fixture(scope="module")
def suite(tmp_path_factory):
    out = tmp_path_factory.mktemp("suite") / "local"
    assert main([*SUITE_ARGS, "--workers", "2", "--quiet", "--out", str(out)]) == 0
    return out


def test_suite_folder_has_a_scenario_each_and_a_manifest(suite):
    assert sorted(p.name for p in suite.iterdir()) == sorted([*NAMES, MANIFEST_FILE])
    manifest = json.loads((suite / MANIFEST_FILE).read_text())
    assert sorted(manifest["scenarios"]) == NAMES
    for name, entry in manifest["scenarios"].items():
        assert entry["passed"] and entry["spec"]["style"] == "grid"
        assert "timing.json" not in entry["files"] and "preview.png" in entry["files"]
        assert entry["files"].keys() == {
            p.relative_to(suite / name).as_posix()
            for p in (suite / name).rglob("*") if p.is_file() and p.name != "timing.json"}
        assert entry["figures"]["simulation.loaded"] == 15
    assert manifest["suite"]["densities"] == [20.0, 30.0]


def test_existing_suite_is_kept_without_force(suite, capsys):
    before = (suite / MANIFEST_FILE).read_bytes()
    assert main([*SUITE_ARGS, "--quiet", "--out", str(suite)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("roadweaver-sumo: error:") and "--force" in err and "\n" not in err
    assert (suite / MANIFEST_FILE).read_bytes() == before
    assert not [p for p in suite.parent.iterdir() if ".partial-" in p.name]


def test_ray_engine_writes_the_same_manifest(suite, tmp_path, capsys, monkeypatch):
    ray = pytest.importorskip("ray")
    monkeypatch.chdir(tmp_path)  # Ray puts the driver's directory on its workers' sys.path
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
    try:
        out = tmp_path / "ray"
        assert main([*SUITE_ARGS, "--engine", "ray", "--out", str(out)]) == 0
    finally:
        ray.shutdown()
    assert (out / MANIFEST_FILE).read_bytes() == (suite / MANIFEST_FILE).read_bytes()
    err = capsys.readouterr().err
    assert "2/2" in err and "ETA" in err  # progress lines on stderr


def test_check_suite_passes_on_an_untouched_suite(suite, capsys):
    # --no-regenerate keeps this quick; tests/test_suite_example.py regenerates a whole suite
    assert main(["check-suite", str(suite), "--no-regenerate", "--json"]) == 0
    result = json.loads(capsys.readouterr().out)
    assert result["passed"] and result["checked"] == 2 and result["drift"] == {}


def test_check_suite_names_the_scenario_file_and_figure_that_drifted(suite, tmp_path, capsys):
    copy = tmp_path / "edited"
    shutil.copytree(suite, copy)
    demand = copy / NAMES[1] / "demand.rou.xml"
    first_vehicle = re.compile(r'<vehicle id="veh0".*?</vehicle>\s*', flags=re.DOTALL)
    demand.write_text(first_vehicle.sub("", demand.read_text(), count=1))
    (copy / NAMES[0] / "map.xodr").unlink()
    (copy / NAMES[0] / "notes.txt").write_text("mine")
    assert main(["check-suite", str(copy), "--no-regenerate", "--quiet"]) == 1
    out, err = capsys.readouterr()
    assert f"{NAMES[1]}: file demand.rou.xml differs from the manifest" in out
    assert f"{NAMES[1]}: figure simulation.loaded is 14, manifest 15" in out
    assert f"{NAMES[0]}: file map.xodr is missing" in out
    assert f"{NAMES[0]}: file notes.txt is not in the manifest" in out
    assert err.startswith("roadweaver-sumo: error:") and err.count("\n") == 1




def test_check_suite_names_the_line_where_a_rebuilt_map_really_changed(suite, tmp_path, capsys):
    """The suite's map is edited as a generator change would (one junction moved 3 m) and its
    manifest follows: the rebuild then differs beyond the tolerances, and the line is named."""
    copy = tmp_path / "moved"
    shutil.copytree(suite, copy)
    nodes = copy / NAMES[0] / "plain" / "map.nod.xml"
    text = nodes.read_text()
    x = re.search(r'<node id="n1" x="([-\d.]+)"', text)
    moved = text.replace(x.group(0), x.group(0).replace(x.group(1), f"{float(x.group(1)) + 3:.2f}"))
    nodes.write_text(moved)
    manifest = json.loads((copy / MANIFEST_FILE).read_text())
    manifest["scenarios"][NAMES[0]]["files"]["plain/map.nod.xml"] = \
        hashlib.sha256(moved.encode()).hexdigest()
    (copy / MANIFEST_FILE).write_text(json.dumps(manifest))
    shutil.rmtree(copy / NAMES[1])  # one scenario is enough to rebuild
    assert main(["check-suite", str(copy), "--quiet"]) == 1
    out = capsys.readouterr().out
    assert (f"{NAMES[0]}: regenerated plain/map.nod.xml differs from the manifest: line "
            in out) and 'id="n1"' in out


def test_legacy_choices_reach_the_scenarios(tmp_path):
    """A suite asked for the ring boundary and priority rules (the values spec.json leaves
    unsaid) builds its scenarios with them, not with make-scenario's defaults."""
    out = tmp_path / "legacy"
    assert main(["make-suite", "--densities", "20", "--styles", "grid", "--seeds", "0",
                 "--size", "500", "--vehicles", "15", "--duration", "60", "--skeleton",
                 "procedural", "--boundary", "ring", "--rules", "priority", "--quiet", "--out",
                 str(out)]) == 0
    spec = json.loads((out / NAMES[0] / "spec.json").read_text())
    assert "boundary" not in spec and "rules" not in spec  # legacy values are left unsaid
    nodes = (out / NAMES[0] / "plain" / "map.nod.xml").read_text()
    assert 'type="priority"' in nodes
    assert not re.search(r'type="(right_before_left|priority_stop|allway_stop)"', nodes)


def test_demand_choices_reach_the_manifest_and_the_scenarios(tmp_path):
    """Vehicle mix, departures and fringe factor are suite fields: in the manifest's suite,
    in every scenario's spec.json and demand."""
    out = tmp_path / "demand"
    assert main(["make-suite", "--densities", "20", "--styles", "grid", "--seeds", "0",
                 "--size", "1000", "--vehicles", "15", "--duration", "60", "--skeleton",
                 "procedural", "--vehicle-mix", "passenger:0.5,truck:0.5", "--departures",
                 "even", "--fringe-factor", "5", "--quiet", "--out", str(out)]) == 0
    suite = json.loads((out / MANIFEST_FILE).read_text())["suite"]
    assert (suite["vehicle_mix"], suite["fringe_factor"]) == ({"passenger": 0.5, "truck": 0.5},
                                                              5.0)
    assert "departures" not in suite  # even: the earlier versions' value, left unsaid
    name = "grid-d20-1000x1000-s0-v15"
    spec = json.loads((out / name / "spec.json").read_text())
    assert spec["fringe_factor"] == 5.0 and spec["vehicle_mix"]["truck"] == 0.5
    assert 'vClass="truck"' in (out / name / "demand.rou.xml").read_text()


def test_a_map_too_small_for_a_fringe_factor_is_a_one_line_error(tmp_path, capsys):
    """500 m with every road reaching the border: randomTrips finds no trip; the error names
    the option and what to do."""
    assert main(["make-scenario", "--density", "20", "--size", "500", "--vehicles", "15",
                 "--duration", "60", "--skeleton", "procedural", "--style", "grid",
                 "--fringe-factor", "5", "--out", str(tmp_path / "x")]) == 2
    last = capsys.readouterr().err.splitlines()[-1]
    assert last.startswith("roadweaver-sumo: error: --fringe-factor 5: randomTrips found no trip")
    assert last.endswith("(use 1)") and "--allow-fringe" not in last
