"""Work shared with one forked child: the second core, for steps whose parts do not depend on
each other.

A forked child sees this process's memory as it was (copy-on-write: the road graph, the cost
map and the HD map are not pickled), so only its results travel back, through a pipe. Each part
is computed by the same code either way, so results do not depend on whether a child was used.
"""

from __future__ import annotations

import multiprocessing
import os
from collections.abc import Callable
from typing import TypeVar

from . import children

T = TypeVar("T")
U = TypeVar("U")


def can_fork() -> bool:
    """Fork exists (not on Windows), there is a second core, and this process may have
    children (a daemonic multiprocessing worker may not)."""
    return ("fork" in multiprocessing.get_all_start_methods() and (os.cpu_count() or 1) > 1
            and not multiprocessing.current_process().daemon)


def beside(in_child: Callable[[], T], here: Callable[[], U], *, name: str) -> tuple[U, T]:
    """``(here(), in_child())``, with ``in_child`` run by a forked child (``name`` says what it
    does, in error messages) while this process runs ``here``; both in turn where a child
    cannot be forked. The child is always collected before an error is raised; an error of
    ``here`` is raised first. When this process is interrupted (Ctrl-C, SIGTERM: anything not
    an ``Exception``) the child is killed rather than waited for; it also dies with this
    process (``children.die_with_parent``)."""
    if not can_fork():
        return here(), in_child()
    context = multiprocessing.get_context("fork")
    receive, send = context.Pipe(duplex=False)
    child = context.Process(target=_run_in_child, args=(in_child, send, name, os.getpid()),
                            name=name)
    child.start()
    send.close()
    failure: BaseException | None = None
    try:
        try:
            mine = here()
        except Exception as exc:  # noqa: BLE001 - the child is collected before raising
            failure = exc
        try:
            ok, theirs = receive.recv()
        except EOFError:
            child.join()
            ok, theirs = False, RuntimeError(f"the process {name} died (exit code {child.exitcode})")
    except BaseException:
        child.kill()
        raise
    finally:
        child.join()
        receive.close()
    if failure is not None:
        raise failure
    if not ok:
        raise theirs
    return mine, theirs


def _run_in_child(job: Callable, send, name: str, parent_pid: int) -> None:
    """Send ``(True, job())`` or ``(False, the exception)`` (its text if it cannot be
    pickled)."""
    children.forget_inherited(parent_pid)
    try:
        outcome = (True, job())
    except BaseException as exc:  # noqa: BLE001 - handed to the parent, which raises it
        outcome = (False, exc)
    try:
        send.send(outcome)
    except Exception as exc:  # noqa: BLE001 - an exception or a result that does not pickle
        ok, value = outcome
        error = (f"its result cannot be sent back ({exc})" if ok
                 else f"{type(value).__name__}: {value}")
        send.send((False, RuntimeError(f"{name}: {error}")))
    send.close()
