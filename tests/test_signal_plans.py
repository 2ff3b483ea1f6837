"""Traffic-light programs: fixed-time, timed as green waves by SUMO's tlsCoordinator along
the demand's routes; the offsets are written once, the same each time, and the scenario runs
with them."""

from __future__ import annotations

import json
import shutil

import pytest
from lxml import etree

from roadweaver_sumo.cli import main
from roadweaver_sumo.scenario.signal_plans import OFFSETS_FILE, coordinate_lights


@pytest.fixture(scope="module")
def scenario(tmp_path_factory):
    out = tmp_path_factory.mktemp("lights") / "town"
    code = main(["make-scenario", "--density", "40", "--vehicles", "200", "--size", "1500",
                 "--duration", "900", "--seed", "3", "--bus-lines", "0", "--out", str(out)])
    return out, code


def test_the_lights_run_fixed_time_programs_and_the_report_counts_them(scenario):
    out, _ = scenario
    root = etree.parse(str(out / "map.net.xml")).getroot()
    programs = {t.get("id"): t.get("type") for t in root.iter("tlLogic")}
    assert len(programs) >= 2 and set(programs.values()) == {"static"}
    report = json.loads((out / "report.json").read_text())
    assert report["generation"]["traffic_lights"]["programs"] == {"static": len(programs)}


def test_green_wave_offsets_are_loaded_and_the_same_each_time(scenario, tmp_path):
    out, code = scenario
    offsets = etree.parse(str(out / OFFSETS_FILE)).getroot().findall("tlLogic")
    lights = {t.get("id") for t in etree.parse(str(out / "map.net.xml")).getroot()
              .iter("tlLogic")}
    assert offsets and {o.get("id") for o in offsets} <= lights
    assert any(float(o.get("offset")) != 0.0 for o in offsets), "timed, not all at 0 s"
    assert OFFSETS_FILE in (out / "scenario.sumocfg").read_text()
    report = json.loads((out / "report.json").read_text())
    assert code == (0 if report["passed"] else 1)
    again = tmp_path / "again"
    shutil.copytree(out, again)
    (again / OFFSETS_FILE).unlink()
    assert coordinate_lights(again)["coordinated"] == len(offsets)
    assert (again / OFFSETS_FILE).read_bytes() == (out / OFFSETS_FILE).read_bytes()
