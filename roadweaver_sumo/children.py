"""Child processes that never outlive the run that started them.

Every program a run starts (netconvert, randomTrips, duarouter, the libsumo validators, the
lanelet2 check) goes through :func:`popen` or :func:`run`, which

* start it in a session of its own, so that killing its process group also ends whatever it
  started, and so that a terminal's Ctrl-C reaches only this process, which decides what ends;
* ask Linux to SIGKILL it when its parent dies (``PR_SET_PDEATHSIG``): even a SIGKILL of this
  process, which runs no clean-up code at all, takes the children along. That signal is not
  inherited, so a child's own children (randomTrips can start duarouter) would outlive it: a
  watchdog process in a session of its own learns each child's process group and kills the
  groups still listed when this process is gone (``_WATCHDOG``);
* remember it while it runs, so that the SIGTERM and SIGINT handlers of
  :func:`handle_termination` kill every live child's group before this process exits.

Linux sends the parent-death signal when the *thread* that started the child ends, so a child
must be waited for by the thread that started it (every caller here does). Pool workers
(``suite/engines.py``) are not started through ``popen``; they call :func:`die_with_parent`
themselves.
"""

from __future__ import annotations

import ctypes
import multiprocessing
import os
import signal
import subprocess
import sys
import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from functools import partial

PR_SET_PDEATHSIG = 1  # from <linux/prctl.h>


def _prctl():
    """libc's ``prctl``, looked up once: a forked child calls it before ``exec``, where as
    little as possible should run."""
    if not sys.platform.startswith("linux"):
        return None
    try:
        fn = ctypes.CDLL(None, use_errno=True).prctl
    except (OSError, AttributeError):
        return None
    fn.argtypes = [ctypes.c_int, ctypes.c_ulong]
    return fn


_PRCTL = _prctl()
_live: set[subprocess.Popen] = set()
_watchdog: subprocess.Popen | None = None  # of this process (a forked child starts its own)
_watchdog_lock = threading.Lock()


def die_with_parent(parent_pid: int | None = None) -> None:
    """Have Linux SIGKILL this process when its parent dies; at once if the parent (whose pid
    was ``parent_pid`` before the fork) died already. Does nothing off Linux."""
    if _PRCTL is None:
        return
    _PRCTL(PR_SET_PDEATHSIG, signal.SIGKILL)
    if parent_pid is not None and os.getppid() != parent_pid:
        os.kill(os.getpid(), signal.SIGKILL)


def popen(args: list[str], **kwargs) -> subprocess.Popen:
    """``subprocess.Popen(args, **kwargs)`` in a session of its own that dies with this
    process."""
    for done in [p for p in list(_live) if p.returncode is not None]:
        _forget(done)
    proc = subprocess.Popen(args, start_new_session=True,
                            preexec_fn=partial(die_with_parent, os.getpid()),  # noqa: PLW1509 - prctl only
                            **kwargs)
    _live.add(proc)
    _tell_watchdog(f"+{proc.pid}")
    return proc


def run(args: list[str], *, timeout: float | None = None, **kwargs) -> subprocess.CompletedProcess:
    """``subprocess.run(args, capture_output=True, text=True, **kwargs)`` through :func:`popen`.
    On a time-out (``subprocess.TimeoutExpired`` is raised) or any other exception while
    waiting, the child's whole process group is killed first."""
    proc = popen(args, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, **kwargs)
    try:
        out, err = proc.communicate(timeout=timeout)
    except BaseException:
        kill(proc)
        raise
    _forget(proc)
    return subprocess.CompletedProcess(args, proc.returncode, out, err)


def wait(proc: subprocess.Popen, timeout: float | None = None) -> int:
    """``proc.wait(timeout)``, then forget the child (``subprocess.TimeoutExpired`` leaves it
    running and remembered)."""
    code = proc.wait(timeout)
    _forget(proc)
    return code


def kill(proc: subprocess.Popen) -> None:
    """SIGKILL ``proc``'s process group (if it has not been collected yet) and collect it."""
    _kill_group(proc)
    proc.wait()
    _forget(proc)


def _forget(proc: subprocess.Popen) -> None:
    """A collected child: neither the handlers nor the watchdog may signal its group (the pid
    is free to be reused)."""
    if proc in _live:
        _live.discard(proc)
        _tell_watchdog(f"-{proc.pid}")


def _kill_group(proc: subprocess.Popen) -> None:
    """Send SIGKILL, never wait: a signal handler may run while this thread holds the child's
    wait lock. An uncollected child's pid cannot have been reused."""
    if proc.returncode is None:
        try:
            os.killpg(proc.pid, signal.SIGKILL)
        except (ProcessLookupError, PermissionError):
            pass


# The watchdog: '+PGID' and '-PGID' lines on stdin; at end of input (its parent is gone, however
# it ended) it kills the groups still listed. Its own session: a kill of the parent's process
# group does not reach it.
_WATCHDOG = """
import os, signal, sys
signal.signal(signal.SIGINT, signal.SIG_IGN)
groups = set()
for line in sys.stdin:
    (groups.add if line[0] == "+" else groups.discard)(int(line[1:]))
for pgid in groups:
    try:
        os.killpg(pgid, signal.SIGKILL)
    except OSError:
        pass
"""


def _tell_watchdog(line: str) -> None:
    """Send ``line`` to this process's watchdog, started on first use."""
    global _watchdog
    with _watchdog_lock:
        if _watchdog is None:
            _watchdog = subprocess.Popen([sys.executable, "-c", _WATCHDOG], stdin=subprocess.PIPE,
                                         stdout=subprocess.DEVNULL, start_new_session=True)
        try:
            _watchdog.stdin.write(f"{line}\n".encode())
            _watchdog.stdin.flush()
        except OSError:  # it died (killed by hand): the parent-death signal still holds
            pass


def stop_children() -> None:
    """Kill every live child's process group; their waiting threads then collect them."""
    for proc in list(_live):
        _kill_group(proc)


@contextmanager
def handle_termination(before_exit: Callable[[int], None]) -> Iterator[None]:
    """While the block runs (in the main thread), SIGTERM and SIGINT stop this process at once:
    every child's process group and every forked worker are killed, ``before_exit(signum)``
    runs (remove what was being written, say why), and the process exits with 128 + signum.

    It exits rather than raising into the interrupted code: an exception raised by a signal
    handler is swallowed where it lands in an at-fork hook or a finaliser, which then leaves
    a lock held (logging's, by a fork's hook) and the run hung. A child started by another
    thread in that instant dies with this process (its parent-death signal). The previous
    handlers come back when the block ends."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def stop(signum: int, frame) -> None:
        stop_children()
        workers = multiprocessing.active_children()
        for worker in workers:
            worker.kill()
        for worker in workers:  # gone before anything they were writing is removed
            worker.join(1.0)
        before_exit(signum)
        os._exit(128 + signum)

    previous = {s: signal.signal(s, stop) for s in (signal.SIGTERM, signal.SIGINT)}
    try:
        yield
    finally:
        for signum, handler in previous.items():
            signal.signal(signum, handler)
