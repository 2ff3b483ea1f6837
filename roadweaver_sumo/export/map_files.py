"""Our three map formats, written side by side.

SUMO plain XML, OpenDRIVE and lanelet2 all read the same finished HD map and write different
files; at 10 km lanelet2 takes about 1.5 s, OpenDRIVE 1.3 s and the plain files 0.3 s. Where the
platform can fork, one forked child writes the plain files and then OpenDRIVE (the map is shared
copy-on-write, nothing is pickled) while this process writes lanelet2, the longest: two
processes for two cores, and the longest writer runs where the map is already in its own
memory (in a child it took 0.4-0.7 s longer, copying the pages its reference counts touch).
The bytes are the same either way: each writer is unchanged.
"""

from __future__ import annotations

from pathlib import Path

from ..forked import beside
from ..hdmap.model import HDMap
from .lanelet2 import write_lanelet2
from .opendrive import write_opendrive
from .sumo_plain import write_plain

PLAIN_DIR, XODR_FILE, LANELET2_FILE = "plain", "map.xodr", "map.osm"


def write_map_files(hd: HDMap, folder: Path, *, parallel: bool = True) -> None:
    """``folder/plain/``, ``folder/map.xodr`` and ``folder/map.osm``; an error in any writer is
    raised here, after the child has ended."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)  # before the child: either process may be first

    def plain_and_xodr() -> None:
        write_plain(hd, folder / PLAIN_DIR)
        write_opendrive(hd, folder / XODR_FILE)

    def lanelet2() -> None:
        write_lanelet2(hd, folder / LANELET2_FILE)

    if parallel:
        beside(plain_and_xodr, lanelet2, name=f"writing {PLAIN_DIR}/ and {XODR_FILE}")
    else:
        plain_and_xodr()
        lanelet2()
