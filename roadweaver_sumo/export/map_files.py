"""Our three map formats, written side by side.

SUMO plain XML, OpenDRIVE and lanelet2 all read the same finished HD map and write different
files; at 10 km lanelet2 takes about 0.8-0.9 s, OpenDRIVE 0.8-0.9 s and the plain files 0.2 s
(edges 0.1 s) in one process. Where the platform can fork, one forked child writes the plain
nodes and connections and then OpenDRIVE (the map is shared copy-on-write, nothing is
pickled) while this process writes lanelet2, the longest, and the plain edges: two processes
for two cores, and the longest writer runs where the map is already in its own memory (in a
child it took 0.4-0.7 s longer, copying the pages its reference counts touch). (With all
three plain files the child took 0.12-0.47 s longer than this process, learned 10 km maps.)
The bytes are the same either way: each writer is unchanged.
"""

from __future__ import annotations

from pathlib import Path

from ..forked import beside
from ..hdmap.model import HDMap
from .lanelet2 import write_lanelet2
from .opendrive import write_opendrive
from .sumo_plain import write_plain

PLAIN_DIR, XODR_FILE, LANELET2_FILE = "plain", "map.xodr", "lanelet2_map.osm"
CHILD_PLAIN_FILES, PARENT_PLAIN_FILES = ("map.nod.xml", "map.con.xml"), ("map.edg.xml",)


def write_map_files(hd: HDMap, folder: Path, *, parallel: bool = True) -> None:
    """``folder/plain/``, ``folder/map.xodr`` and ``folder/lanelet2_map.osm``; an error in any writer is
    raised here, after the child has ended."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)  # before the child: either process may be first

    def child_files() -> None:
        write_plain(hd, folder / PLAIN_DIR, files=CHILD_PLAIN_FILES)
        write_opendrive(hd, folder / XODR_FILE)

    def own_files() -> None:
        write_lanelet2(hd, folder / LANELET2_FILE)
        write_plain(hd, folder / PLAIN_DIR, files=PARENT_PLAIN_FILES)

    if parallel:
        beside(child_files, own_files, name=f"writing {PLAIN_DIR}/ and {XODR_FILE}")
    else:
        child_files()
        own_files()
