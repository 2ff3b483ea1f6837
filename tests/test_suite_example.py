"""Regression test over a scenario suite: copy this file into your own tests and point SUITE at
your suite folder (made with ``roadweaver-sumo make-suite ... --out DIR``).

Every scenario is re-validated and regenerated from its spec; a scenario whose files or key
figures drift from ``manifest.json`` fails its own test case with the file and figure named.
The committed example was made with:

    roadweaver-sumo make-suite --densities 10,20 --styles grid,organic --seeds 0 --size 1000 \
        --vehicles 50 --duration 300 --skeleton procedural --out scenarios/examples/suite

A deliberate change to the generator changes the suite: rebuild it with the same command and
``--force``, look at the new previews, and commit it with the change.
"""

from pathlib import Path

import pytest

from roadweaver_sumo.suite import check_suite, environment_note, read_manifest

SUITE = Path(__file__).resolve().parents[1] / "scenarios" / "examples" / "suite"
SCENARIOS = sorted(read_manifest(SUITE)[1]["scenarios"])


@pytest.fixture(scope="module")
def problems() -> dict[str, list[str]]:
    return check_suite(SUITE, regenerate=True, workers=2)


def test_suite_folder_holds_only_its_scenarios(problems):
    assert problems["(suite)"] == []


@pytest.mark.parametrize("name", SCENARIOS)
def test_scenario_matches_its_manifest(problems, name):
    note = environment_note(SUITE)  # other package versions explain most drift
    assert problems[name] == [], "\n".join([*problems[name], note or ""])
