"""Our three map formats, written from one finished HD map (paper §III-D, export): SUMO plain
XML and the net netconvert builds from it, then OpenDRIVE and lanelet2.

SUMO comes first because netconvert decides the right of way at every junction (who yields,
who stops, which light controls a link); OpenDRIVE and lanelet2 are written after it from the
HD map carrying that decision (``hdmap.right_of_way``), so all three formats hold the same
rules."""

from __future__ import annotations

from collections.abc import Callable
from contextlib import AbstractContextManager, nullcontext
from pathlib import Path

from ..hdmap.crossings import read_crossings
from ..hdmap.model import HDMap
from ..hdmap.right_of_way import attach_right_of_way
from .lanelet2 import write_lanelet2
from .netconvert import NET_NAME, run_netconvert
from .opendrive import write_opendrive
from .sumo_plain import write_plain

PLAIN_DIR, XODR_FILE, LANELET2_FILE = "plain", "map.xodr", "lanelet2_map.osm"


def write_map_files(hd: HDMap, folder: Path, template: str = "urban",
                    timed: Callable[[str, str], AbstractContextManager] = lambda *_: nullcontext(),
                    ) -> dict[str, Path]:
    """``folder/plain/``, ``folder/map.net.xml`` (netconvert with ``template``),
    ``folder/map.xodr`` and ``folder/lanelet2_map.osm``; returns their paths by format.
    ``timed(message, stage)`` wraps each step (the pipeline's stage timer)."""
    folder = Path(folder)
    with timed("export ...", "export"):
        write_plain(hd, folder / PLAIN_DIR)
    with timed("netconvert ...", "netconvert"):
        net = run_netconvert(folder, template, walkingareas=bool(hd.sidewalks))
    with timed("OpenDRIVE and lanelet2 with SUMO's right of way ...", "formats"):
        attach_right_of_way(hd, net)
        if hd.sidewalks:  # crossings and walking areas only where there are sidewalks
            hd.crosswalks, hd.walking_areas = read_crossings(net)
        write_opendrive(hd, folder / XODR_FILE)
        write_lanelet2(hd, folder / LANELET2_FILE)
    return {"plain": folder / PLAIN_DIR, "sumo": folder / NET_NAME,
            "opendrive": folder / XODR_FILE, "lanelet2": folder / LANELET2_FILE}
