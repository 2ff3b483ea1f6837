"""``roadweaver-sumo evaluate``: our metrics on SUMO nets we did not make (netgenerate grids)."""

from __future__ import annotations

import json
import subprocess

import pytest

from roadweaver_sumo.cli import main
from roadweaver_sumo.errors import RoadweaverError
from roadweaver_sumo.sumo_tools import binary, child_env
from roadweaver_sumo.validate.evaluate import evaluate_net


@pytest.fixture(scope="module")
def grid_net(tmp_path_factory):
    """A 5 x 5 netgenerate grid, 200 m blocks: 25 junctions, the 4 corners of degree 2."""
    folder = tmp_path_factory.mktemp("grid")
    subprocess.run([binary("netgenerate"), "--grid", "--grid.number", "5", "--grid.length", "200",
                    "-o", "grid.net.xml"], cwd=folder, env=child_env(), check=True,
                   capture_output=True)  # fmt: skip
    return folder / "grid.net.xml"


def test_grid_counts_road_nodes_and_takes_area_from_conv_boundary(grid_net):
    result = evaluate_net(grid_net)
    assert result["road_nodes"] == 21
    assert result["area_km2"] == pytest.approx(0.64)  # 800 m x 800 m convBoundary
    assert result["area_source"] == "convBoundary"
    assert result["density"] == pytest.approx(21 / 0.64)
    assert result["lcc_ratio"] == 1.0
    assert result["dead_end_ratio"] == 0.0
    assert result["crossings_without_junction"] == 0
    assert result["sharp_bends"] == 0
    assert result["orientation_order"] == pytest.approx(1.0)
    assert result["lane_reachability"] == 1.0


def test_given_area_overrides_the_boundary(grid_net):
    result = evaluate_net(grid_net, area_km2=2.0)
    assert result["density"] == pytest.approx(10.5)
    assert result["area_source"] == "given"


def test_cli_prints_json(grid_net, capsys):
    assert main(["evaluate", str(grid_net), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["road_nodes"] == 21


@pytest.mark.parametrize(
    ("content", "message"),
    [(None, "not found"), ("<routes/>", "not a SUMO network"), ("garbage", "not a SUMO network"),
     ('<net version="1.20"/>', "holds no roads")],
)
def test_bad_input_is_one_line_error(tmp_path, capsys, content, message):
    path = tmp_path / "x.net.xml"
    if content is not None:
        path.write_text(content)
    with pytest.raises(RoadweaverError, match=message):
        evaluate_net(path)
    assert main(["evaluate", str(path)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and message in err


def test_bad_area_is_refused(grid_net):
    with pytest.raises(RoadweaverError, match="area-km2"):
        evaluate_net(grid_net, area_km2=0.0)


def test_realism_statistics_of_a_grid_closed_by_its_border_road(grid_net):
    realism = evaluate_net(grid_net)["realism"]
    assert realism["four_way_share_inner"] == 1.0  # the 3 x 3 inner crossings
    assert realism["frame_share"] == pytest.approx(0.4)  # 4 of the 10 streets run on the border
    assert realism["block_area_median"] == pytest.approx(200.0**2)
    assert realism["block_area_median_inner"] == pytest.approx(200.0**2)  # the 4 central ones
    assert realism["small_block_share_inner"] == 0.0
