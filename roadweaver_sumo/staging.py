"""Outputs appear complete or not at all: build in a hidden sibling folder, then move into place.

The sibling is ``.NAME.partial-PID-XXXX``, PID the building process: a run killed outright
(SIGKILL, a power cut) cannot remove it, so the next run on the same output removes every
such folder whose process is gone. While a folder is staged, the run's temporary files go
inside it too (:func:`scratch_dir`), so that they leave with it.
"""

from __future__ import annotations

import os
import re
import shutil
import tempfile
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from .errors import RoadweaverError

_staged: list[Path] = []  # folders being built by this process, the innermost last
_workspaces: list[Path] = []  # where temporary files go (:func:`scratch_dir`), innermost last


@contextmanager
def staged_folder(out_dir: Path, force: bool) -> Iterator[Path]:
    """Yield a temporary folder next to ``out_dir``; when the block succeeds it becomes
    ``out_dir``. An existing ``out_dir`` is an error unless ``force``, and is then replaced only
    after the new folder is complete. On failure the temporary folder is removed."""
    out_dir = Path(out_dir)
    if out_dir.exists() and not out_dir.is_dir():
        raise RoadweaverError(f"output path {out_dir} exists and is not a folder")
    parent = out_dir.parent
    if parent.is_dir():
        remove_stale(out_dir)
    if out_dir.exists() and not force:
        raise RoadweaverError(f"output folder {out_dir} already exists; use --force to replace it")
    try:
        parent.mkdir(parents=True, exist_ok=True)
        tmp = Path(tempfile.mkdtemp(prefix=f".{out_dir.name}.partial-{os.getpid()}-", dir=parent))
    except OSError as exc:
        raise RoadweaverError(f"cannot write to {parent}: {exc.strerror or exc}") from None
    _staged.append(tmp)
    _workspaces.append(tmp)
    try:
        yield tmp
        _move_into_place(tmp, out_dir, force)
    finally:
        _staged.remove(tmp)
        _workspaces.remove(tmp)
        if tmp.exists():
            shutil.rmtree(tmp, ignore_errors=True)


@contextmanager
def scratch_beside(folder: Path) -> Iterator[Path | None]:
    """While the block runs, temporary files of work on the existing ``folder`` (``validate``)
    go to a hidden ``.NAME.partial-PID-*`` folder beside it, removed afterwards, or by the next
    run if this one is killed. Yields None (the system's temporary folder) where the parent
    folder is not writable."""
    folder = Path(folder)
    remove_stale(folder)
    try:
        tmp = Path(tempfile.mkdtemp(prefix=f".{folder.name}.partial-{os.getpid()}-",
                                    dir=folder.parent))
    except OSError:
        yield None
        return
    _staged.append(tmp)
    _workspaces.append(tmp)
    try:
        yield tmp
    finally:
        _staged.remove(tmp)
        _workspaces.remove(tmp)
        shutil.rmtree(tmp, ignore_errors=True)


@contextmanager
def scratch_inside(folder: str | Path | None) -> Iterator[None]:
    """While the block runs, temporary files go inside ``folder``: a worker process's share
    of a run that made ``folder`` with :func:`scratch_beside` (which removes it). None: no
    change."""
    if folder is None:
        yield
        return
    folder = Path(folder)
    _workspaces.append(folder)
    try:
        yield
    finally:
        _workspaces.remove(folder)


def remove_staged(patience_s: float = 2.0) -> None:
    """Remove every folder this process is staging (a run stopped by a signal exits without
    unwinding, see ``children.handle_termination``). Children killed a moment ago may still
    add a file while a folder is removed, so removal is retried for up to ``patience_s``."""
    deadline = time.monotonic() + patience_s
    for folder in _staged:
        shutil.rmtree(folder, ignore_errors=True)
        while folder.exists() and time.monotonic() < deadline:
            time.sleep(0.02)
            shutil.rmtree(folder, ignore_errors=True)


def scratch_dir() -> Path | None:
    """Where temporary files go: inside the folder this process is staging (or was given by
    :func:`scratch_inside`), so that a killed run leaves them only there (removed by the next
    run); None (the system's temporary folder) when there is none."""
    return _workspaces[-1].resolve() if _workspaces else None  # absolute: tools run elsewhere


def remove_stale(out_dir: Path) -> list[Path]:
    """Remove what killed runs on ``out_dir`` left beside it: ``.NAME.partial-PID-*`` folders
    (or files: a checkpoint being written), and ``.NAME.old-PID`` (the previous output, moved
    aside while the new one moved in; put back if ``out_dir`` is missing). Only where process PID is gone. Returns what was
    removed or put back."""
    out_dir = Path(out_dir)
    parent = out_dir.parent
    pattern = re.compile(rf"\.{re.escape(out_dir.name)}\.(partial|old)-(\d+)(-.*)?")
    handled: list[Path] = []
    try:
        siblings = sorted(parent.iterdir())
    except OSError:  # unreadable: creating the staging folder there says why
        return handled
    for path in siblings:
        match = pattern.fullmatch(path.name)
        if not match or _alive(int(match.group(2))):
            continue
        if match.group(1) == "old" and not out_dir.exists():
            path.rename(out_dir)
        elif path.is_dir():
            shutil.rmtree(path, ignore_errors=True)
        else:
            path.unlink(missing_ok=True)
        handled.append(path)
    return handled


def _alive(pid: int) -> bool:
    """Whether process ``pid`` exists (one of another user counts as alive)."""
    if pid == os.getpid():
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    except OverflowError:
        return False
    return True


def _move_into_place(tmp: Path, out_dir: Path, force: bool) -> None:
    """Swap the finished folder in; with ``force`` the old folder goes only after that worked."""
    os.chmod(tmp, 0o755)  # mkdtemp makes it private; an output folder is an ordinary folder
    old = None
    if out_dir.exists():
        if not force:
            raise RoadweaverError(f"output folder {out_dir} already exists; use --force")
        old = out_dir.with_name(f".{out_dir.name}.old-{os.getpid()}")
        out_dir.rename(old)
    try:
        tmp.rename(out_dir)
    except OSError as exc:
        if old is not None:
            old.rename(out_dir)
        raise RoadweaverError(f"cannot move the output into {out_dir}: {exc.strerror}") from None
    if old is not None:
        shutil.rmtree(old, ignore_errors=True)
