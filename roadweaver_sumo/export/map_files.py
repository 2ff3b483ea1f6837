"""Our three map formats, written side by side.

SUMO plain XML, OpenDRIVE and lanelet2 all read the same finished HD map and write different
files; at 10 km lanelet2 takes about 2.8 s, OpenDRIVE 1.7 s and the plain files 0.4 s. Where the
platform can fork, one forked child writes the plain files and then OpenDRIVE (the map is shared
copy-on-write, nothing is pickled) while this process writes lanelet2, the longest: two
processes for two cores, and the longest writer runs where the map is already in its own
memory (in a child it took 0.4-0.7 s longer, copying the pages its reference counts touch).
The bytes are the same either way: each writer is unchanged.
"""

from __future__ import annotations

import multiprocessing
import os
from pathlib import Path

from ..hdmap.model import HDMap
from .lanelet2 import write_lanelet2
from .opendrive import write_opendrive
from .sumo_plain import write_plain

PLAIN_DIR, XODR_FILE, LANELET2_FILE = "plain", "map.xodr", "map.osm"


def write_map_files(hd: HDMap, folder: Path, *, parallel: bool = True) -> None:
    """``folder/plain/``, ``folder/map.xodr`` and ``folder/map.osm``; an error in any writer is
    raised here, after the child has ended."""
    folder = Path(folder)
    child_jobs = [(write_plain, folder / PLAIN_DIR), (write_opendrive, folder / XODR_FILE)]
    if not (parallel and _can_fork()):
        for writer, path in child_jobs:
            writer(hd, path)
        write_lanelet2(hd, folder / LANELET2_FILE)
        return
    context = multiprocessing.get_context("fork")
    receive, send = context.Pipe(duplex=False)
    child = context.Process(target=_write_in_child, args=(child_jobs, hd, send),
                            name="write plain + xodr")
    child.start()
    send.close()
    errors: list[BaseException] = []
    try:
        write_lanelet2(hd, folder / LANELET2_FILE)
    except BaseException as exc:  # noqa: BLE001 - the child is collected before raising
        errors.append(exc)
    try:
        outcome = receive.recv()
    except EOFError:
        outcome = RuntimeError(f"the process writing {PLAIN_DIR}/ and {XODR_FILE} died "
                               f"(exit code {child.exitcode})")
    child.join()
    receive.close()
    if outcome is not None:
        errors.append(outcome)
    if errors:
        raise errors[0]


def _can_fork() -> bool:
    """Fork exists (not on Windows), there is a second core, and this process may have
    children (a daemonic multiprocessing worker may not)."""
    return ("fork" in multiprocessing.get_all_start_methods() and (os.cpu_count() or 1) > 1
            and not multiprocessing.current_process().daemon)


def _write_in_child(jobs, hd: HDMap, send) -> None:
    """Run the writers in turn; send None, or the first exception (its text if it cannot be
    pickled)."""
    outcome = None
    try:
        for writer, path in jobs:
            writer(hd, path)
    except BaseException as exc:  # noqa: BLE001 - handed to the parent, which raises it
        outcome = exc
    try:
        send.send(outcome)
    except Exception:  # noqa: BLE001 - an exception that does not pickle
        send.send(RuntimeError(f"writing {path.name}: {type(outcome).__name__}: {outcome}"))
    send.close()
