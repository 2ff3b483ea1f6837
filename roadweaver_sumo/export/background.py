"""Write one export file in a forked child while the caller writes the others.

The exporters are pure Python and independent (each reads the finished HD map and writes its own
file), so on a machine with a spare core the lanelet2 file can be written beside the OpenDRIVE
one: export time becomes the longer of the two instead of their sum. The child runs the same
function on the same data, so the bytes are those of a sequential run.
"""

from __future__ import annotations

import multiprocessing
import os
import threading
import traceback
from collections.abc import Callable, Iterator
from contextlib import contextmanager


def can_fork() -> bool:
    """Forking helps and is safe: a second core, ``fork`` available, and no other thread in this
    process (a forked child would inherit its locks held) nor a daemon process (which may not
    have children)."""
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    return ((cores or 1) >= 2 and "fork" in multiprocessing.get_all_start_methods()
            and threading.active_count() == 1 and not multiprocessing.current_process().daemon)


@contextmanager
def in_background(fn: Callable, *args) -> Iterator[None]:
    """Run ``fn(*args)`` in a forked child while the ``with`` body runs, wait for it at the end
    and re-raise its error here; without :func:`can_fork`, run it after the body instead."""
    if not can_fork():
        yield
        fn(*args)
        return
    context = multiprocessing.get_context("fork")
    receive, send = context.Pipe(duplex=False)
    child = context.Process(target=_child, args=(send, fn, args))
    child.start()
    send.close()
    try:
        yield
    finally:
        try:
            error = receive.recv()
        except EOFError:  # the child died before it could report
            error = None
        child.join()
        receive.close()
    if error is not None:
        raise error
    if child.exitcode != 0:
        raise RuntimeError(f"{getattr(fn, '__name__', fn)} exited with code {child.exitcode}")


def _child(send, fn: Callable, args: tuple) -> None:
    error = None
    try:
        fn(*args)
    except BaseException as exc:  # noqa: BLE001 - every failure goes back to the parent
        error = exc
    try:
        send.send(error)
    except Exception:  # noqa: BLE001 - an exception that does not pickle: send its text
        send.send(RuntimeError("".join(traceback.format_exception(error))))
    send.close()
