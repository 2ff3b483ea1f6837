"""``--junction-mix``: shares of the junction controls asked for, placed where a town would put
them (``hdmap.control.plan_controls``), in the HD map, SUMO's net and the report."""

from __future__ import annotations

import json
from collections import Counter

from test_one_way import local_grid

from roadweaver_sumo.cli import main
from roadweaver_sumo.hdmap import build_hdmap
from roadweaver_sumo.hdmap.control import plan_controls


def test_a_mix_puts_lights_at_the_major_junctions_and_right_before_left_at_the_minor():
    """A grid of local streets in a collector frame: 12 frame junctions (two collector arms),
    9 inside (four local arms). A fifth each of lights and right-before-left: 4 lights on the
    frame, 4 right-before-left inside; the rest keep the German rules, but the 5 junctions
    inside that those rules make right-before-left too get the first kind not asked for."""
    G = local_grid()
    frame = {n for n in G if G.degree(n) == 3}
    inside = {n for n in G if G.degree(n) == 4}
    plan = plan_controls(G, "de", True, {"traffic_light": 0.2, "right_before_left": 0.2})
    assert Counter(plan.assigned.values()) == {"traffic_light": 4, "right_before_left": 4,
                                               "priority": 13}
    assert {n for n, kind in plan.assigned.items() if kind == "traffic_light"} <= frame
    assert {n for n, kind in plan.assigned.items() if kind == "right_before_left"} <= inside
    hd = build_hdmap(G, rules="de", junction_mix={"traffic_light": 0.2, "right_before_left": 0.2})
    assert {n: hd.junctions[n].type for n in plan.assigned} == plan.assigned
    assert plan_controls(G, "de").assigned == {}, "no mix: every junction by the rules"


def test_a_scenario_with_a_mix_holds_it_and_passes(tmp_path):
    out = tmp_path / "mix"
    code = main(["make-scenario", "--density", "40", "--vehicles", "80", "--size", "1000",
                 "--duration", "600", "--skeleton", "procedural", "--junction-mix",
                 "allway_stop=0.5,traffic_light=0.1", "--roundabouts", "0", "--out", str(out)])
    report = json.loads((out / "report.json").read_text())
    assert code == 0 and report["passed"]
    assert report["simulation"]["collisions"] == 0
    controls = report["net"]["rules"]["junction_controls"]
    junctions = sum(n for kind, n in controls.items() if kind != "zipper")  # 3+ arms
    assert controls["allway_stop"] == round(0.5 * junctions)
    assert controls["traffic_light"] == round(0.1 * junctions)
    spec = json.loads((out / "spec.json").read_text())
    assert spec["junction_mix"] == {"allway_stop": 0.5, "traffic_light": 0.1}


def test_a_mix_over_one_is_a_one_line_error(tmp_path, capsys):
    code = main(["make-scenario", "--density", "30", "--vehicles", "10", "--junction-mix",
                 "allway_stop=0.6,priority=0.6", "--out", str(tmp_path / "x")])
    err = capsys.readouterr().err.strip().splitlines()
    message = "roadweaver-sumo: error: --junction-mix: the shares add up to 1.2, more than 1"
    assert code == 2 and err == [message]
    assert not (tmp_path / "x").exists()
