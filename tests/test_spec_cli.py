"""Spec validation and the command line's error contract (one line, non-zero, nothing written)."""

import json

import pytest

from roadweaver_sumo.cli import main
from roadweaver_sumo.errors import RoadweaverError
from roadweaver_sumo.hdmap.lanes import LANE_CONFIGS
from roadweaver_sumo.option_text import parse_size
from roadweaver_sumo.spec import ROAD_CLASSES, ScenarioSpec


def test_parse_size_square_and_rectangle():
    assert parse_size("2000") == (2000.0, 2000.0)
    assert parse_size("3000x2000") == (3000.0, 2000.0)
    with pytest.raises(RoadweaverError, match="not a size"):
        parse_size("big")


def test_spec_round_trips_through_json(tmp_path):
    spec = ScenarioSpec(density=25, vehicles=100, width=1200, height=900, seed=4, style="grid")
    path = tmp_path / "spec.json"
    path.write_text(spec.to_json())
    assert ScenarioSpec.from_json_file(path) == spec
    assert json.loads(path.read_text())["density"] == 25
    assert "speeds" not in json.loads(spec.to_json())  # the classes' own: left unsaid
    assert ROAD_CLASSES == tuple(LANE_CONFIGS)  # the classes --speed names are the HD map's
    fast = ScenarioSpec(density=25, vehicles=100, speeds={"arterial": 70.0})
    path.write_text(fast.to_json())
    assert ScenarioSpec.from_json_file(path) == fast


def test_an_open_boundary_is_written_and_a_ring_left_unsaid(tmp_path):
    """A spec.json written before there was a boundary choice reads as a ring map, and a ring
    spec writes the same bytes as then; an open spec says so and reads back open."""
    ring, opened = (ScenarioSpec(density=25, vehicles=100, boundary=b) for b in ("ring", "open"))
    assert "boundary" not in json.loads(ring.to_json())
    for spec in (ring, opened):
        path = tmp_path / f"{spec.boundary}.json"
        path.write_text(spec.to_json())
        assert ScenarioSpec.from_json_file(path) == spec


@pytest.mark.parametrize(
    "args, message",
    [
        (["--density", "0", "--vehicles", "5"], "density must be > 0"),
        (["--density", "-3", "--vehicles", "5"], "density must be > 0"),
        (["--density", "30", "--vehicles", "5", "--size", "0"], "map width must be > 0"),
        (["--density", "30", "--vehicles", "5", "--size", "50"], "width 50 m is outside"),
        (["--density", "30", "--vehicles", "5", "--style", "wavy"], "unknown style 'wavy'"),
        (["--density", "30", "--vehicles", "5", "--boundary", "square"],
         "unknown boundary 'square'"),
        (["--density", "nan", "--vehicles", "5"], "density must be > 0"),
        (["--density", "abc", "--vehicles", "5"], "invalid float value"),
        (["--vehicles", "5"], "needs --density (road nodes per km²), or --like FILE"),
        (["--density", "30", "--vehicles", "5", "--speed", "arterial=200"],
         "--speed arterial must be 5..130 km/h, got 200"),
        (["--density", "30", "--vehicles", "5", "--speed", "motorway=80"],
         "unknown road class 'motorway'"),
        (["--density", "30", "--vehicles", "5", "--speed", "arterial:80"],
         "'arterial:80' is not class=km/h"),
        (["--vehicles", "5", "--like", "nowhere.osm.pbf"], "--like: nowhere.osm.pbf not found"),
        (["--density", "30", "--vehicles", "5", "--gridness", "2"], "must be 0..1, got 2"),
        (["--density", "30", "--vehicles", "5", "--ego-routes", "-1"], "must be 0..100"),
        (["--density", "30", "--vehicles", "5", "--ego-length", "50"], "must be 200..100000"),
        (["--density", "30", "--vehicles", "5", "--bearing-entropy", "x"], "is not a number"),
        (["--density", "30", "--vehicles", "5", "--organicness", "0.5", "--skeleton",
          "procedural"], "condition the learned skeleton"),
        (["--density", "30", "--vehicles", "0"], "--vehicles must be 1.."),
        (["--density", "30", "--vehicles", "5", "--seed", "-1"], "--seed must be"),
        (["--density", "30", "--vehicles", "5", "--duration", "0"], "--duration must be > 0"),
        (["--density", "900", "--vehicles", "5"], "above 400"),
        (["--density", "30", "--vehicles", "5", "--skeleton", "magic"], "unknown skeleton"),
        (["--density", "5", "--vehicles", "5", "--size", "500"], "holds only 1.2 road nodes"),
    ],
)
def test_bad_input_gives_one_line_error(tmp_path, capsys, args, message):
    out = tmp_path / "out"
    code = main(["make-scenario", *args, "--out", str(out)])
    err = capsys.readouterr().err
    assert code == 2
    assert message in err
    assert err.count("\n") == 1 and err.startswith("roadweaver-sumo: error:")
    assert not out.exists()
    assert list(tmp_path.iterdir()) == []


def test_like_a_file_that_is_no_network_is_a_one_line_error(tmp_path, capsys):
    notes = tmp_path / "town.txt"
    notes.write_text("not a map\n")
    fake = tmp_path / "town.net.xml"
    fake.write_text("<routes/>\n")
    for path, message in ((notes, "is not a road network this reads"),
                          (fake, "is not a SUMO network")):
        code = main(["make-scenario", "--vehicles", "5", "--like", str(path),
                     "--out", str(tmp_path / "out")])
        err = capsys.readouterr().err
        assert code == 2 and message in err and err.count("\n") == 1
    assert not (tmp_path / "out").exists()


def test_priors_and_a_city_are_written_only_when_set(tmp_path):
    """A spec without priors or a city writes the bytes it wrote before they existed; one
    with them reads back equal."""
    plain = ScenarioSpec(density=25, vehicles=100)
    assert not {"gridness", "like"} & set(json.loads(plain.to_json()))
    like = {"name": "town", "tiles": 0, "density": 25.0, "priors": {"gridness": 0.5},
            "statistics": {"dead_end_share_inner": 0.2}}
    spec = ScenarioSpec(density=25, vehicles=100, gridness=0.8, like=like)
    path = tmp_path / "spec.json"
    path.write_text(spec.to_json())
    assert ScenarioSpec.from_json_file(path) == spec
    assert spec.name.startswith("like-town-d25")
    with pytest.raises(RoadweaverError, match="not a finite number"):
        ScenarioSpec(density=25, vehicles=100, like=like | {"density": float("nan")})


def test_existing_folder_is_kept_without_force(tmp_path, capsys):
    out = tmp_path / "out"
    out.mkdir()
    (out / "mine.txt").write_text("keep me")
    code = main(["make-scenario", "--density", "30", "--vehicles", "5", "--out", str(out)])
    assert code == 2
    assert "already exists; use --force" in capsys.readouterr().err
    assert (out / "mine.txt").read_text() == "keep me"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]


def test_unwritable_folder_is_a_clear_error(tmp_path, capsys):
    blocked = tmp_path / "file"
    blocked.write_text("not a folder")
    code = main(["make-scenario", "--density", "30", "--vehicles", "5",
                 "--out", str(blocked / "scenario")])
    assert code == 2
    assert "cannot write to" in capsys.readouterr().err


def test_validate_refuses_a_folder_that_is_not_a_scenario(tmp_path, capsys):
    assert main(["validate", str(tmp_path)]) == 2
    assert "is not a scenario folder" in capsys.readouterr().err
