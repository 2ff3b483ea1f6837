"""Where SUMO's binaries and tools are, taken from the ``eclipse-sumo`` wheel (never the system).

``import sumo`` gives the SUMO home shipped on PyPI. The venv's ``bin/netconvert`` etc. are Python
wrappers that cost ~0.2 s per call, so we call the real binaries directly (see shared NOTES).
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import sumo

from . import children
from .errors import RoadweaverError

SUMO_HOME = Path(sumo.SUMO_HOME)


def binary(name: str) -> str:
    """Absolute path of a SUMO binary (``sumo``, ``netconvert``, ``duarouter``, ...)."""
    path = SUMO_HOME / "bin" / name
    if not path.exists():
        raise RoadweaverError(f"SUMO binary {name!r} not found at {path}; reinstall eclipse-sumo")
    return str(path)


def tool(relative: str) -> str:
    """Absolute path of a script under SUMO's ``tools/`` folder, e.g. ``randomTrips.py``."""
    path = SUMO_HOME / "tools" / relative
    if not path.exists():
        raise RoadweaverError(f"SUMO tool {relative!r} not found at {path}; reinstall eclipse-sumo")
    return str(path)


# Runs a Python tool as its own script would run (``__main__``, its folder first on sys.path)
# with the cycle collector off: a short-lived tool needs no cycle collection, and the collector
# costs randomTrips.py a fifth of its time while sumolib reads a large net (2.19 -> 1.76 s on a
# 10 km map; the same trips).
_RUN_WITHOUT_CYCLE_GC = (
    "import gc, os, runpy, sys; gc.disable(); sys.argv = sys.argv[1:]; "
    "sys.path[0] = os.path.dirname(sys.argv[0]); runpy.run_path(sys.argv[0], run_name='__main__')"
)


def python_tool(relative: str) -> list[str]:
    """The command line start that runs the Python script ``relative`` under SUMO's ``tools/``
    (see :func:`tool`) in this interpreter, without cycle collection."""
    return [sys.executable, "-c", _RUN_WITHOUT_CYCLE_GC, tool(relative)]


def child_env() -> dict:
    """Environment for SUMO child processes: SUMO_HOME set so XML validation stays on, and
    PROJ's data folder so geo-referenced nets load without warnings."""
    env = dict(os.environ)
    env["SUMO_HOME"] = str(SUMO_HOME)
    proj = SUMO_HOME / "data" / "proj"
    if proj.is_dir():  # the wheel ships proj.db; without it SUMO warns on geo-referenced nets
        env.setdefault("PROJ_LIB", str(proj))
        env.setdefault("PROJ_DATA", str(proj))
    return env


def run(args: list[str], cwd: Path, what: str) -> subprocess.CompletedProcess:
    """Run a SUMO program in ``cwd`` (a child that dies with this process: ``children``); on
    failure raise a one-line error quoting its last message."""
    proc = children.run(args, cwd=cwd, env=child_env())
    if proc.returncode != 0:
        lines = [ln.strip() for ln in (proc.stderr + proc.stdout).splitlines() if ln.strip()]
        errors = [ln for ln in lines if ln.startswith("Error:")]
        reason = errors[0] if errors else (lines[-1] if lines else f"exit code {proc.returncode}")
        raise RoadweaverError(f"{what} failed: {reason}")
    return proc


def strip_generated_comment(path: Path) -> None:
    """Drop the ``<!-- generated on <timestamp> ... -->`` header SUMO writes, so outputs are
    byte-identical across runs (the rest of the header only echoes relative options)."""
    text = Path(path).read_text(encoding="utf-8")
    start = text.find("<!-- generated on")
    if start < 0:
        return
    end = text.find("-->", start)
    text = text[:start] + text[end + 3 :].lstrip("\n")
    Path(path).write_text(text, encoding="utf-8")
