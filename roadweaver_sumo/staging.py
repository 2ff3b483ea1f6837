"""Outputs appear complete or not at all: build in a hidden sibling folder, then move into place."""

from __future__ import annotations

import os
import shutil
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from .errors import RoadweaverError


@contextmanager
def staged_folder(out_dir: Path, force: bool) -> Iterator[Path]:
    """Yield a temporary folder next to ``out_dir``; when the block succeeds it becomes
    ``out_dir``. An existing ``out_dir`` is an error unless ``force``, and is then replaced only
    after the new folder is complete. On failure the temporary folder is removed."""
    out_dir = Path(out_dir)
    if out_dir.exists() and not out_dir.is_dir():
        raise RoadweaverError(f"output path {out_dir} exists and is not a folder")
    if out_dir.exists() and not force:
        raise RoadweaverError(f"output folder {out_dir} already exists; use --force to replace it")
    parent = out_dir.parent if str(out_dir.parent) else Path(".")
    try:
        parent.mkdir(parents=True, exist_ok=True)
        tmp = Path(tempfile.mkdtemp(prefix=f".{out_dir.name}.partial-", dir=parent))
    except OSError as exc:
        raise RoadweaverError(f"cannot write to {parent}: {exc.strerror or exc}") from None
    try:
        yield tmp
        _move_into_place(tmp, out_dir, force)
    finally:
        if tmp.exists():
            shutil.rmtree(tmp, ignore_errors=True)


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
