"""Our three map formats, written side by side.

SUMO plain XML, OpenDRIVE and lanelet2 all read the same finished HD map and write different
files; at 10 km the two big ones take about 10 s of CPU each. Where the platform can fork,
OpenDRIVE and lanelet2 are written by forked child processes (the map is shared copy-on-write,
nothing is pickled) while this process writes the plain files, so the export takes about half
the wall time on two cores. The bytes are the same either way: each writer is unchanged.
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
    raised here, after every child has ended."""
    folder = Path(folder)
    side_jobs = [(write_opendrive, folder / XODR_FILE), (write_lanelet2, folder / LANELET2_FILE)]
    if not (parallel and _can_fork()):
        write_plain(hd, folder / PLAIN_DIR)
        for writer, path in side_jobs:
            writer(hd, path)
        return
    context = multiprocessing.get_context("fork")
    children = []
    for writer, path in side_jobs:
        receive, send = context.Pipe(duplex=False)
        child = context.Process(target=_write_in_child, args=(writer, hd, path, send),
                                name=f"write {path.name}")
        child.start()
        send.close()
        children.append((child, receive, path))
    errors: list[BaseException] = []
    try:
        write_plain(hd, folder / PLAIN_DIR)
    except BaseException as exc:  # noqa: BLE001 - the children are collected before raising
        errors.append(exc)
    for child, receive, path in children:
        try:
            outcome = receive.recv()
        except EOFError:
            outcome = RuntimeError(f"the process writing {path.name} died "
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


def _write_in_child(writer, hd: HDMap, path: Path, send) -> None:
    """Run one writer; send None, or the exception (its text if it cannot be pickled)."""
    try:
        writer(hd, path)
        outcome = None
    except BaseException as exc:  # noqa: BLE001 - handed to the parent, which raises it
        outcome = exc
    try:
        send.send(outcome)
    except Exception:  # noqa: BLE001 - an exception that does not pickle
        send.send(RuntimeError(f"writing {path.name}: {type(outcome).__name__}: {outcome}"))
    send.close()
