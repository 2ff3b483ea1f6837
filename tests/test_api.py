"""The Python API: the README's example runs as written, and the objects hold what it says."""

import re
from pathlib import Path

import networkx as nx

import roadweaver_sumo as rw

README = Path(__file__).resolve().parents[1] / "README.md"


def test_the_readmes_python_example_runs(tmp_path, monkeypatch, capsys):
    block = re.search(r"## Python API.*?```python\n(.*?)```", README.read_text(), re.DOTALL)
    monkeypatch.chdir(tmp_path)
    exec(compile(block.group(1), "README.md", "exec"), {})  # noqa: S102 - the README's own code
    lines = capsys.readouterr().out.splitlines()
    assert lines[1].startswith("True 1.0 ") and lines[1].endswith("scenario.sumocfg")
    assert abs(float(lines[2]) - 20) <= 1.0
    for name in ("map.net.xml", "map.xodr", "lanelet2_map.osm", "plain/map.con.xml",
                 "netconvert.netccfg"):
        assert (tmp_path / "api-map" / name).is_file(), name


def test_generate_map_gives_the_road_graph_with_the_hd_map():
    spec = rw.ScenarioSpec(density=20, vehicles=1, width=800, height=800, skeleton="procedural")
    hd = rw.generate_map(spec)
    assert isinstance(hd, rw.HDMap) and isinstance(hd.graph, nx.Graph)
    assert hd.graph.number_of_edges() == len(hd.roads)
    assert {d["road_class"] for *_, d in hd.graph.edges(data=True)} <= {
        "arterial", "collector", "local"}


def test_unknown_names_are_an_attribute_error():
    try:
        rw.no_such_function  # noqa: B018
    except AttributeError as exc:
        assert "no_such_function" in str(exc)
    else:
        raise AssertionError("expected AttributeError")
