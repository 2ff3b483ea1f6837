"""A traffic-rule regression, end to end (issue 36): does check-suite name the scenarios and the
rule situations whose figures change when the driver model changes at one rule?

Usage: python bench/rule_regression.py [--work DIR] [--option ignore-junction-blocker=5]

Builds a suite of 8 scenarios (2 km, density 30, the four styles x 2 seeds, default rules and
vehicle mix, sidewalks and 100 walkers, 500 vehicles over an hour), checks it untouched (must
pass), then writes one SUMO option into every scenario's ``scenario.sumocfg`` (default:
``ignore-junction-blocker 5``, vehicles drive past a blocker after 5 s) and runs
``check-suite --no-regenerate``: a fresh validation of each folder against the manifest.
Prints, per scenario, the files and the figures that check-suite names, and how many
scenarios changed at which rule situation.
"""

from __future__ import annotations

import argparse
import re
import tempfile
import time
from collections import Counter
from pathlib import Path

from lxml import etree

from roadweaver_sumo.spec import DEFAULT_PERSONS, DEFAULT_RULES, DEFAULT_VEHICLE_MIX, STYLES
from roadweaver_sumo.suite import SuiteSpec, check_suite, make_suite
from roadweaver_sumo.suite.grid import parse_seeds


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--work", type=Path)
    parser.add_argument("--option", default="ignore-junction-blocker=5",
                        help="SUMO option NAME=VALUE written into every scenario.sumocfg")
    parser.add_argument("--seeds", default="0-1")
    args = parser.parse_args()
    work = args.work or Path(tempfile.mkdtemp(prefix="rule-regression-"))
    suite = SuiteSpec(densities=(30.0,), styles=STYLES, seeds=parse_seeds(args.seeds),
                      skeleton="learned", boundary="open", rules=DEFAULT_RULES,
                      vehicle_mix=dict(DEFAULT_VEHICLE_MIX), departures="random",
                      sidewalks=True, persons=DEFAULT_PERSONS)
    began = time.perf_counter()
    result = make_suite(suite, work / "suite", force=True, workers=2)
    print(f"built {len(suite.scenarios())} scenarios in {time.perf_counter() - began:.0f} s; "
          f"failed: {result.failed or 'none'}")
    untouched = {k: v for k, v in check_suite(work / "suite", regenerate=False, workers=2).items()
                 if v}
    print(f"untouched suite: {'passes' if not untouched else untouched}")
    name, value = args.option.split("=", 1)
    for cfg in sorted((work / "suite").glob("*/scenario.sumocfg")):
        root = etree.parse(str(cfg)).getroot()
        etree.SubElement(root.find("processing"), name, value=value)
        etree.ElementTree(root).write(str(cfg), xml_declaration=True, encoding="UTF-8")
    problems = check_suite(work / "suite", regenerate=False, workers=2)
    rules: Counter = Counter()
    for scenario, found in sorted(problems.items()):
        if scenario == "(suite)" or not found:
            print(f"{scenario}: unchanged")
            continue
        named = sorted({rule for line in found if (rule := _rule_named(line))})
        rules.update(named)
        print(f"{scenario}: {len(found)} findings; rules changed: {', '.join(named) or 'none'}")
        for line in found:
            print(f"    {line}")
    changed = sum(1 for k, v in problems.items() if k != "(suite)" and v)
    print(f"with {name}={value}: {changed} of {len(suite.scenarios())} scenarios changed; "
          f"rule situations named: {dict(rules)}")


def _rule_named(finding: str) -> str | None:
    """The rule situation a check-suite finding is about: an approach rule whose waiting
    changed, or the crossings where walkers' time loss changed."""
    if match := re.search(r"simulation\.rules\.(\w+)\.waiting_s", finding):
        return match.group(1)
    return "crossings" if "simulation.persons_time_loss_s" in finding else None


if __name__ == "__main__":
    main()
