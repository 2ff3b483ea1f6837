"""preview.png: deterministic bytes, no metadata, collision sites, and clear errors."""

import json
import shutil
import struct
from pathlib import Path

import numpy as np
from matplotlib.image import imread

from roadweaver_sumo.cli import main
from roadweaver_sumo.render import COLLISION_COLOUR, net_drawing, render_preview
from roadweaver_sumo.validate.netgraph import load_net

SUITE = Path(__file__).resolve().parents[1] / "scenarios" / "examples" / "suite"
SCENARIO = SUITE / "grid-d20-1000x1000-s0-v50"


def _chunks(png: Path) -> list[bytes]:
    data, i, names = png.read_bytes(), 8, []
    while i < len(data):
        (length,) = struct.unpack(">I", data[i:i + 4])
        names.append(data[i + 4:i + 8])
        i += 12 + length
    return names


def test_preview_is_redrawn_byte_for_byte(tmp_path, capsys):
    copy = tmp_path / SCENARIO.name
    shutil.copytree(SCENARIO, copy)
    assert main(["render", str(copy)]) == 0
    assert capsys.readouterr().out.strip() == f"wrote {copy / 'preview.png'}"
    assert (copy / "preview.png").read_bytes() == (SCENARIO / "preview.png").read_bytes()


def test_preview_drawn_from_the_validation_net_is_the_same(tmp_path):
    """make-scenario draws from the net validation read (with internal lanes) instead of
    reading it again: the picture must not change."""
    drawing = net_drawing(load_net(SCENARIO / "map.net.xml"))
    out = render_preview(SCENARIO, tmp_path / "p.png", net=drawing)
    assert out.read_bytes() == (SCENARIO / "preview.png").read_bytes()


def test_preview_has_no_date_or_software_metadata():
    chunks = set(_chunks(SCENARIO / "preview.png"))
    assert chunks.isdisjoint({b"tEXt", b"iTXt", b"zTXt", b"tIME"})


def test_preview_marks_collision_sites(tmp_path):
    copy = tmp_path / "s"
    shutil.copytree(SCENARIO, copy)
    report = json.loads((copy / "report.json").read_text())
    report["simulation"]["collision_sites"] = [["junction n1", 2], ["lane nowhere_0", 1]]
    (copy / "report.json").write_text(json.dumps(report))
    image = imread(render_preview(copy, tmp_path / "p.png"))[..., :3]
    green = np.array([int(COLLISION_COLOUR[i:i + 2], 16) / 255 for i in (1, 3, 5)])
    assert (np.abs(image - green).max(axis=-1) < 0.05).sum() > 20


def test_preview_of_an_unvalidated_scenario_shows_the_lanes(tmp_path):
    copy = tmp_path / "s"
    shutil.copytree(SCENARIO, copy)
    (copy / "report.json").write_text('{"validated": false}')
    out = render_preview(copy, tmp_path / "p.png")
    assert out.stat().st_size > 10_000
    assert out.read_bytes() != (SCENARIO / "preview.png").read_bytes()


def test_render_of_a_damaged_net_is_a_one_line_error(tmp_path, capsys):
    (tmp_path / "map.net.xml").write_text("<net><edge id=")
    assert main(["render", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("roadweaver-sumo: error: cannot read") and err.count("\n") == 1


def test_dead_ends_are_marked_although_netconvert_types_them_priority(tmp_path):
    """A spur road's end, where cars can turn around, is a ``priority`` junction in SUMO's
    net; the preview marks it as the dead end it is (as the report counts it)."""
    from roadweaver_sumo.sumo_tools import binary, run

    (tmp_path / "n.nod.xml").write_text(
        '<nodes><node id="A" x="0" y="0"/><node id="B" x="200" y="0"/>'
        '<node id="C" x="100" y="150"/><node id="D" x="300" y="-100"/></nodes>')
    pairs = ("AB", "BC", "CA", "BD")
    (tmp_path / "e.edg.xml").write_text("<edges>" + "".join(
        f'<edge id="{a}{b}" from="{a}" to="{b}"/><edge id="{b}{a}" from="{b}" to="{a}"/>'
        for a, b in pairs) + "</edges>")
    run([binary("netconvert"), "-n", "n.nod.xml", "-e", "e.edg.xml", "-o", "map.net.xml"],
        tmp_path, "netconvert")
    net = load_net(tmp_path / "map.net.xml")
    assert net.getNode("D").getType() == "priority"
    drawing = net_drawing(net)
    assert [tuple(xy) for xy in drawing["nodes"]["dead_end"]] == [net.getNode("D").getCoord()[:2]]
