"""Minimum rule coverage of a suite's scenarios (``make-suite --min-coverage``, issue 36).

A traffic-rule regression suite must hold the situations it is meant to regress on: a suite
for all-way stops is no use if a seed happened to draw none. With a minimum, every scenario
must hold at least that many of each asked-for situation, counted as ``report.json`` counts
them (``net.rules``, ``validate.rule_coverage``); a scenario that falls short is built again
with the next seed of its own (``RESEED_STEP`` further on), up to ``MAX_RESEEDS`` times, and
the manifest keeps the seed that made it, so ``check-suite`` rebuilds the same scenario.
"""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

from ..errors import RoadweaverError
from ..hdmap.control import CONTROLS
from ..spec import ScenarioSpec

#: what a minimum can be asked for: a junction control (SUMO node types, junctions of three
#: or more roads), or one of the other counts of ``net.rules``
KINDS = (*(c for c in CONTROLS if c != "dead_end"), "roundabouts", "roundabout_entries",
         "one_way_edges", "turn_bays", "protected_lefts", "pedestrian_crossings",
         "speed_limit_changes", "bus_stops")
RESEED_STEP = 1000  # the next seed tried: far from the grid's own seeds (0-9 and the like)
MAX_RESEEDS = 8


def parse_min_coverage(text: str) -> dict[str, int]:
    """``"turn_bays=2,allway_stop=1"`` -> {"allway_stop": 1, "turn_bays": 2}."""
    found: dict[str, int] = {}
    for item in str(text).split(","):
        kind, sep, count = item.strip().partition("=")
        if kind not in KINDS:
            raise RoadweaverError(f"--min-coverage: {kind!r} is not a rule situation; one of "
                                  f"{', '.join(KINDS)}")
        if not sep or not count.strip().isdigit() or int(count) < 1:
            raise RoadweaverError(f"--min-coverage: {item.strip()!r} must be KIND=N with N >= 1")
        if kind in found:
            raise RoadweaverError(f"--min-coverage names {kind!r} twice")
        found[kind] = int(count)
    return dict(sorted(found.items()))


def coverage(folder: Path) -> dict[str, int]:
    """The counts of every ``KINDS`` situation in a built scenario's ``report.json``."""
    report = json.loads((Path(folder) / "report.json").read_text(encoding="utf-8"))
    rules = report["net"]["rules"]
    counts = {kind: rules["junction_controls"].get(kind, 0) for kind in CONTROLS}
    counts["bus_stops"] = (report["generation"].get("bus_lines") or {}).get("stops", 0)
    counts["pedestrian_crossings"] = sum(rules.get("pedestrian_crossings", {}).values())
    for kind in ("roundabouts", "roundabout_entries", "one_way_edges", "turn_bays",
                 "protected_lefts", "speed_limit_changes"):
        counts[kind] = rules.get(kind, 0)
    return {kind: counts[kind] for kind in KINDS}


def shortfall(folder: Path, minimum: dict[str, int]) -> list[str]:
    """What a built scenario lacks of ``minimum``, e.g. ``["turn_bays 0 < 2"]``."""
    counts = coverage(folder)
    return [f"{kind} {counts[kind]} < {need}" for kind, need in minimum.items()
            if counts[kind] < need]


def reseeded(spec: ScenarioSpec, attempt: int) -> ScenarioSpec:
    """The spec built in place of ``spec`` on its ``attempt``-th retry."""
    return replace(spec, seed=spec.seed + attempt * RESEED_STEP)
