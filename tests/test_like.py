"""``--like``: a real network measured with the report's code steers the map (issue 35)."""

from pathlib import Path

import numpy as np
import pytest

from roadweaver_sumo.cli import main
from roadweaver_sumo.expand import expand_skeleton
from roadweaver_sumo.like import closest_map, distance, measure_city, measure_network
from roadweaver_sumo.realism import realism_statistics
from roadweaver_sumo.skeleton import make_skeleton
from roadweaver_sumo.spec import ScenarioSpec
from roadweaver_sumo.validate.evaluate import evaluate_net

EXAMPLE = Path(__file__).resolve().parents[1] / "scenarios" / "examples" / "suite"
SHARED_OSM = Path(__file__).resolve().parents[2] / "shared" / "data" / "osm"


def _town(style: str) -> dict:
    """A 1 km town of ``style`` at density 60 (a learned map of another seed), measured as a
    city."""
    spec = ScenarioSpec(density=60, vehicles=1, width=1000, height=1000, seed=3, style=style)
    G = expand_skeleton(spec, make_skeleton(spec))
    return measure_network(G, (0.0, 0.0, 1000.0, 1000.0), f"{style}-town")


def test_a_sumo_net_is_measured_as_evaluate_measures_it():
    """A network smaller than a tile is measured whole, with the statistics `evaluate`
    reports for it."""
    net = EXAMPLE / "grid-d20-1000x1000-s0-v50" / "map.net.xml"
    like = measure_city(net)
    realism = evaluate_net(net)["realism"]
    assert like["name"] == "map" and like["tiles"] == 0
    assert like["density"] == pytest.approx(realism["density"], rel=1e-4)
    for name in ("dead_end_share_inner", "bearing_entropy", "edge_length_mean"):
        assert like["statistics"][name] == pytest.approx(realism[name], rel=1e-4)


def test_a_map_like_a_town_is_closer_to_it_than_to_another_town():
    """Conditioned on a town's priors, given its share of dead ends and chosen among
    candidates by closeness to it, the map is closer to its own town than to the other (a
    grid town and an organic one), and it is the closest of its candidates."""
    towns = {style: _town(style) for style in ("grid", "organic")}
    made = {}
    for style, like in towns.items():
        spec = ScenarioSpec(density=like["density"], vehicles=1, width=1000, height=1000,
                            seed=1, like=like)
        _, graph, report = closest_map(spec)
        made[style] = realism_statistics(graph)
        assert report["candidates"] == 8 and 0 <= report["chosen"] < 8
        city = like["statistics"]
        assert made[style]["dead_end_share_inner"] == pytest.approx(
            city["dead_end_share_inner"], abs=0.06)
        first = realism_statistics(expand_skeleton(spec, make_skeleton(spec)))
        assert report["distance"] == pytest.approx(distance(made[style], city), abs=1e-4)
        assert report["distance"] <= distance(first, city) + 1e-4
    for style, other in (("grid", "organic"), ("organic", "grid")):
        assert distance(made[style], towns[style]["statistics"]) < distance(
            made[style], towns[other]["statistics"])


@pytest.mark.skipif(not (SHARED_OSM / "heidelberg-de.osm.pbf").is_file(),
                    reason="needs ../shared/data/osm")
def test_make_scenario_like_an_osm_extract(tmp_path, capsys):
    """The main command with --like and no --density: the map takes Heidelberg's density
    (median covered 2 km tile), is validated, and the report says how close it came."""
    out = tmp_path / "like"
    code = main(["make-scenario", "--like", str(SHARED_OSM / "heidelberg-de.osm.pbf"),
                 "--vehicles", "50", "--size", "1000", "--duration", "300", "--out", str(out)])
    text = capsys.readouterr().out
    assert code == 0, text
    spec = ScenarioSpec.from_json_file(out / "spec.json")
    assert spec.like["name"] == "heidelberg-de" and spec.like["tiles"] >= 4
    assert spec.density == spec.like["density"]
    assert "like heidelberg-de (its figures in brackets" in text
    assert np.isfinite(spec.like["statistics"]["bearing_entropy"])
