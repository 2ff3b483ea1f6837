"""Bad suite arguments and damaged manifests end in one line on stderr, never a traceback.

These fail before any scenario is built, so they are fast."""

import json
import random

import pytest

from roadweaver_sumo.cli import main
from roadweaver_sumo.errors import RoadweaverError
from roadweaver_sumo.suite import read_manifest
from roadweaver_sumo.suite.grid import parse_seeds

GOOD = {"--densities": "10,20", "--styles": "grid", "--seeds": "0-1", "--size": "1000",
        "--vehicles": "10", "--duration": "60", "--skeleton": "procedural"}  # fmt: skip
MANIFEST = {
    "schema_version": 1,
    "environment": {"roadweaver-sumo": "0.1.0"},
    "suite": {"densities": [20.0], "styles": ["grid"], "seeds": [0], "width": 500.0,
              "height": 500.0, "vehicles": 15, "duration": 60.0, "skeleton": "procedural"},
    "scenarios": {"grid-d20-500x500-s0-v15": {
        "spec": {"density": 20.0, "duration": 60.0, "geo_origin": [48.137, 11.575],
                 "height": 500.0, "seed": 0, "skeleton": "procedural", "style": "grid",
                 "vehicles": 15, "version": "0.1.0", "width": 500.0},
        "files": {"map.net.xml": "0" * 64}, "figures": {}, "passed": True, "failures": []}},
}  # fmt: skip


def _one_line_error(capsys) -> str:
    err = capsys.readouterr().err
    assert "Traceback" not in err and err.count("\n") == 1, err
    assert err.startswith("roadweaver-sumo: error: ")
    return err


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"--densities": ""}, "at least one value"),
        ({"--densities": "10,,20"}, "empty item"),
        ({"--densities": "ten"}, "not a number"),
        ({"--densities": "nan"}, "> 0"),
        ({"--densities": "-5"}, "> 0"),
        ({"--densities": "10,10"}, "twice"),
        ({"--densities": "500"}, "above 400"),
        ({"--densities": "30,30.0000001"}, "same scenario name"),
        ({"--styles": "grid,swirl"}, "unknown style"),
        ({"--seeds": "3-1"}, "backwards"),
        ({"--seeds": "-1"}, "not a seed"),
        ({"--seeds": "0-99999999"}, "more than"),
        ({"--seeds": "1.5"}, "not a seed"),
        ({"--size": "0"}, "must be > 0"),
        ({"--size": "1e999"}, "got inf"),
        ({"--size": "big"}, "not a size"),
        ({"--vehicles": "0"}, "--vehicles"),
        ({"--vehicles": "many"}, "invalid int"),
        ({"--duration": "inf"}, "> 0"),
        ({"--skeleton": "magic"}, "unknown skeleton"),
        ({"--workers": "0"}, "--workers"),
        ({"--engine": "spark"}, "unknown engine"),
        ({"--address": "1.2.3.4:6379"}, "--engine ray"),
        ({"--min-coverage": "bridges=2"}, "not a rule situation"),
        ({"--min-coverage": "turn_bays=0"}, "KIND=N with N >= 1"),
        ({"--min-coverage": "turn_bays"}, "KIND=N with N >= 1"),
        ({"--min-coverage": "turn_bays=1,turn_bays=2"}, "twice"),
    ],
)
def test_bad_suite_arguments_give_one_line_errors(tmp_path, capsys, change, message):
    args = {**GOOD, **change}
    argv = ["make-suite", "--out", str(tmp_path / "s")] + [x for kv in args.items() for x in kv]
    assert main(argv) == 2
    assert message in _one_line_error(capsys)
    assert not (tmp_path / "s").exists()


def test_unreachable_ray_address_fails_fast(tmp_path, capsys):
    argv = ["make-suite", "--out", str(tmp_path / "s"), "--engine", "ray", "--address",
            "127.0.0.1:1"] + [x for kv in GOOD.items() for x in kv]  # fmt: skip
    assert main(argv) == 2
    err = _one_line_error(capsys)
    assert "cannot reach Ray at 127.0.0.1:1" in err or "needs Ray" in err
    assert not (tmp_path / "s").exists()


def test_fuzzed_suite_arguments_never_raise(tmp_path, capsys):
    """Random values for every option: always a one-line error (the output path is a file, so
    even a valid combination stops before building anything)."""
    blocker = tmp_path / "a-file"
    blocker.write_text("")
    junk = ["", " ", "0", "-1", "1e9", "nan", "inf", "2-1", "0-3", ",", "a,b", "10,20", "grid",
            "x" * 300, "1x1", "3000x", "é", "\x00", "--", "0.5", "99999999999999999999"]
    rng = random.Random(0)
    options = [*GOOD, "--workers", "--engine"]
    for _ in range(100):
        args = dict(GOOD)
        for option in rng.sample(options, rng.randint(1, 4)):
            args[option] = rng.choice(junk)
        argv = ["make-suite", "--out", str(blocker)] + [x for kv in args.items() for x in kv]
        assert main(argv) == 2, argv
        _one_line_error(capsys)


@pytest.mark.parametrize(
    ("mutate", "message"),
    [
        (lambda m: m.clear(), "schema version"),
        (lambda m: m.update(schema_version=2), "schema version"),
        (lambda m: m.update(suite=[]), "'suite' must be an object"),
        (lambda m: m["suite"].update(densities="20"), "must be a list"),
        (lambda m: m["suite"].update(styles=["grid", "grid"]), "twice"),
        (lambda m: m["suite"].update(colour="red"), "unknown suite field"),
        (lambda m: m["suite"].update(seeds=[1]), "lists scenario"),
        (lambda m: m.update(scenarios=[]), "'scenarios' must be an object"),
        (lambda m: _entry(m).update(spec="x"), "has no spec"),
        (lambda m: _entry(m)["spec"].update(seed=-3), "--seed"),
        (lambda m: _entry(m)["spec"].update(geo_origin="here"), "geo_origin"),
        (lambda m: _entry(m)["spec"].update(width=700.0), "has the spec of"),
        (lambda m: _entry(m).update(files={"../../etc/passwd": "0" * 64}), "bad file path"),
        (lambda m: _entry(m).update(files={"/etc/passwd": "0" * 64}), "bad file path"),
        (lambda m: _entry(m).update(files={"map.net.xml": 5}), "no sha256"),
        (lambda m: _entry(m).pop("figures"), "'files' and 'figures'"),
    ],
)
def test_damaged_manifest_gives_one_line_error(tmp_path, capsys, mutate, message):
    manifest = json.loads(json.dumps(MANIFEST))
    mutate(manifest)
    (tmp_path / "manifest.json").write_text(json.dumps(manifest))
    assert main(["check-suite", str(tmp_path), "--quiet"]) == 2
    assert message in _one_line_error(capsys)


def test_fuzzed_manifests_raise_only_roadweaver_errors(tmp_path):
    """Random values at random places of a manifest: read_manifest accepts it or says why."""
    rng = random.Random(1)
    junk = [None, True, -1, 0, 1.5, "", "x", "../x", [], {}, [1, "a"], {"a": 1}, "0" * 64, 1e308]
    for _ in range(300):
        manifest = json.loads(json.dumps(MANIFEST))
        node = manifest
        while isinstance(node, dict) and node and rng.random() < 0.7:
            key = rng.choice(sorted(node))
            if not isinstance(node[key], dict) or rng.random() < 0.3:
                node[key] = rng.choice(junk)
                break
            node = node[key]
        (tmp_path / "manifest.json").write_text(json.dumps(manifest))
        try:
            read_manifest(tmp_path)
        except RoadweaverError as exc:
            assert "\n" not in str(exc)


def test_check_suite_and_render_refuse_folders_that_are_not_theirs(tmp_path, capsys):
    assert main(["check-suite", str(tmp_path / "nowhere")]) == 2
    assert "not found" in _one_line_error(capsys)
    assert main(["check-suite", str(tmp_path)]) == 2
    assert "no manifest.json" in _one_line_error(capsys)
    (tmp_path / "manifest.json").write_text("{not json")
    assert main(["check-suite", str(tmp_path)]) == 2
    assert "cannot read" in _one_line_error(capsys)
    assert main(["render", str(tmp_path)]) == 2
    assert "not a scenario folder" in _one_line_error(capsys)
    assert main(["check-suite"]) == 2
    _one_line_error(capsys)


def test_seed_lists_and_ranges():
    assert parse_seeds("0-3,7, 9") == (0, 1, 2, 3, 7, 9)
    assert parse_seeds("5") == (5,)


def _entry(manifest: dict) -> dict:
    return manifest["scenarios"]["grid-d20-500x500-s0-v15"]
