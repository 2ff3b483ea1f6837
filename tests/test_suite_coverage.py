"""``make-suite --min-coverage``: a scenario short of a rule situation is built again with its
next seed, the manifest keeps the seed that had it, and one that never gets it fails, named."""

from __future__ import annotations

import json

from roadweaver_sumo.cli import main
from roadweaver_sumo.suite import check_suite, read_manifest
from roadweaver_sumo.suite.coverage import MAX_RESEEDS, RESEED_STEP, coverage

SUITE = ["make-suite", "--densities", "20", "--styles", "grid", "--seeds", "0", "--size", "1000",
         "--vehicles", "5", "--duration", "60", "--skeleton", "procedural", "--quiet"]


def test_a_scenario_without_the_asked_situation_is_replaced_by_its_next_seed(tmp_path):
    out = tmp_path / "bays"
    assert main([*SUITE, "--min-coverage", "turn_bays=1,traffic_light=1", "--out", str(out)]) == 0
    _, manifest = read_manifest(out)
    # seed 0 of this grid has no light (so no bay); seed 1000 has one light and two bays
    assert list(manifest["scenarios"]) == [f"grid-d20-1000x1000-s{RESEED_STEP}-v5"]
    assert manifest["suite"]["min_coverage"] == {"traffic_light": 1, "turn_bays": 1}
    folder = out / f"grid-d20-1000x1000-s{RESEED_STEP}-v5"
    assert json.loads((folder / "spec.json").read_text())["seed"] == RESEED_STEP
    counts = coverage(folder)
    assert counts["turn_bays"] >= 1 and counts["traffic_light"] >= 1
    report = json.loads((folder / "report.json").read_text())
    assert counts["bus_stops"] == report["generation"]["bus_lines"]["stops"] > 0
    assert not (out / "grid-d20-1000x1000-s0-v5").exists()
    problems = check_suite(out, regenerate=True)  # rebuilt from the seed that made it
    assert f"grid-d20-1000x1000-s{RESEED_STEP}-v5" in problems and not any(problems.values())


def test_a_situation_no_seed_gives_fails_the_scenario_naming_it(tmp_path, capsys):
    out = tmp_path / "allway"  # German rules never make all-way stops
    assert main([*SUITE, "--min-coverage", "allway_stop=1", "--out", str(out)]) == 1
    _, manifest = read_manifest(out)
    (entry,) = manifest["scenarios"].values()
    assert entry["spec"]["seed"] == MAX_RESEEDS * RESEED_STEP and not entry["passed"]
    assert entry["failures"][-1] == f"coverage after {MAX_RESEEDS} more seeds: allway_stop 0 < 1"
    assert "allway_stop 0 < 1" in capsys.readouterr().err
