"""Our three map formats, written from one finished HD map: SUMO plain XML, OpenDRIVE and
lanelet2 (paper §III-D, export)."""

from __future__ import annotations

from pathlib import Path

from ..hdmap.model import HDMap
from .lanelet2 import write_lanelet2
from .opendrive import write_opendrive
from .sumo_plain import write_plain

PLAIN_DIR, XODR_FILE, LANELET2_FILE = "plain", "map.xodr", "lanelet2_map.osm"


def write_map_files(hd: HDMap, folder: Path) -> None:
    """``folder/plain/``, ``folder/map.xodr`` and ``folder/lanelet2_map.osm``."""
    folder = Path(folder)
    write_plain(hd, folder / PLAIN_DIR)
    write_opendrive(hd, folder / XODR_FILE)
    write_lanelet2(hd, folder / LANELET2_FILE)
