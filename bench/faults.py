"""Kill ``make-scenario`` with SIGTERM and with SIGKILL at 10 points of its run each; after each
kill, report whether any process of the run survived, whether a file was left outside the
output's parent (or, beside the output, other than the output), and whether the next run on the
same ``--out`` worked.

Every process of a run is found by a marker in its environment (children inherit it), so the
check does not depend on process groups, parents or names. Each run gets a ``TMPDIR`` of its own
outside the output's parent: a temporary file left by the run shows up there.

Usage: ``python bench/faults.py [--size 1500 --density 30 --vehicles 300] [--only netconvert]``
(processes that survive are killed afterwards, by pid).
"""

from __future__ import annotations

import argparse
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
import uuid
from pathlib import Path

MARKER = "ROADWEAVER_FAULTS_RUN"
CLI = str(Path(sys.executable).with_name("roadweaver-sumo"))
HANG_S = 120.0  # a run that has not ended this long after the signal is hung
GRACE_S = 0.5  # a process of the run still alive this long after the run ended survived it


def run_processes(token: str) -> dict[int, str]:
    """Live (not zombie) processes whose environment carries ``token``: pid -> command line."""
    found = {}
    for entry in os.scandir("/proc"):
        if not entry.name.isdigit():
            continue
        try:
            with open(f"/proc/{entry.name}/environ", "rb") as f:
                if f"{MARKER}={token}".encode() not in f.read().split(b"\0"):
                    continue
            with open(f"/proc/{entry.name}/stat") as f:
                if f.read().rsplit(")", 1)[1].split()[0] in "ZX":
                    continue
            with open(f"/proc/{entry.name}/cmdline", "rb") as f:
                found[int(entry.name)] = f.read().replace(b"\0", b" ").decode(errors="replace")
        except OSError:
            continue
    return found


class Run:
    """One ``make-scenario`` in a subprocess, its stderr lines collected as they come."""

    def __init__(self, argv: list[str], tmpdir: Path) -> None:
        self.token = uuid.uuid4().hex
        env = {**os.environ, MARKER: self.token, "TMPDIR": str(tmpdir)}
        self.started = time.monotonic()
        self.proc = subprocess.Popen([CLI, *argv], env=env, stdout=subprocess.DEVNULL,
                                     stderr=subprocess.PIPE, text=True)
        self.lines: list[tuple[float, str]] = []
        self.reader = threading.Thread(target=self._read, daemon=True)
        self.reader.start()

    def _read(self) -> None:
        for line in self.proc.stderr:
            self.lines.append((time.monotonic(), line.strip()))

    def logged(self, text: str) -> float | None:
        """When a stderr line containing ``text`` appeared, else None."""
        return next((t for t, line in list(self.lines) if text in line), None)

    def children(self) -> dict[int, str]:
        return {p: c for p, c in run_processes(self.token).items() if p != self.proc.pid}


def after_log(text: str, delay: float = 0.0):
    def reached(run: Run) -> bool:
        t = run.logged(text)
        return t is not None and time.monotonic() >= t + delay
    return reached


def child_running(needle: str):
    def reached(run: Run) -> bool:
        return any(needle in cmd for cmd in run.children().values())
    return reached


def forked_child(run: Run) -> bool:
    """A forked writer: a child whose command line is the run's own."""
    try:
        own = Path(f"/proc/{run.proc.pid}/cmdline").read_bytes().replace(b"\0", b" ").decode()
    except OSError:
        return False
    return own in run.children().values()


POINTS = {
    "0.5 s after start": lambda run: time.monotonic() >= run.started + 0.5,
    "skeleton": after_log("skeleton ..."),
    "forked writer": forked_child,
    "export": after_log("export ..."),
    "netconvert": child_running("/netconvert"),
    "randomTrips": child_running("randomTrips.py"),
    "duarouter": child_running("/duarouter"),
    "validating": after_log("validating"),
    "libsumo child": child_running("roadweaver_sumo.validate.simulation"),
    "0.8 s after validating": after_log("validating", 0.8),
}


def one_point(base: Path, name: str, reached, signum: int, argv: list[str]) -> dict:
    """Kill a run when ``reached``; then look for survivors and stray files, and run again."""
    slug = f"{signal.Signals(signum).name}-{name.replace(' ', '_').replace('.', '')}"
    parent, tmpdir = base / slug / "parent", base / slug / "tmp"
    parent.mkdir(parents=True)
    tmpdir.mkdir()
    out = parent / "scn"
    argv = [*argv, "--out", str(out)]
    run = Run(argv, tmpdir)
    killed_at = None
    while run.proc.poll() is None:
        if reached(run):
            killed_at = time.monotonic() - run.started
            run.proc.send_signal(signum)
            break
        time.sleep(0.005)
    try:
        exit_code = run.proc.wait(timeout=HANG_S)
    except subprocess.TimeoutExpired:  # it did not end after the signal: hung
        run.proc.kill()
        run.proc.wait()
        exit_code = "hung"
    deadline = time.monotonic() + GRACE_S
    while run.children() and time.monotonic() < deadline:
        time.sleep(0.05)
    survivors = run.children()
    for pid in survivors:  # ours: started by this run
        try:
            os.kill(pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
    stray = sorted(str(p.relative_to(tmpdir)) for p in tmpdir.rglob("*"))
    beside = sorted(p.name for p in parent.iterdir() if p.name != "scn")
    again = Run([*argv, *(["--force"] if out.exists() else [])], tmpdir)
    again_code = again.proc.wait()
    again.reader.join()
    deadline = time.monotonic() + GRACE_S
    while again.children() and time.monotonic() < deadline:
        time.sleep(0.05)
    after = sorted(p.name for p in parent.iterdir())
    return {
        "signal": signal.Signals(signum).name, "point": name,
        "killed_at_s": None if killed_at is None else round(killed_at, 2),
        "exit_code": exit_code,
        "survivors": sorted({_short(c) for c in survivors.values()}),
        "stray_outside_parent": stray,
        "left_beside_output": beside,
        "next_run_ok": again_code == 0 and after == ["scn"] and not any(tmpdir.iterdir())
        and not again.children(),
        "next_run_detail": f"exit {again_code}, parent holds {after}",
    }


def _short(cmdline: str) -> str:
    words = cmdline.split()
    for word in words:
        if word.endswith((".py", "netconvert", "duarouter", "sumo")):
            return Path(word).name
    return " ".join(words[:3])[:60]


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", default="1500")
    parser.add_argument("--density", default="30")
    parser.add_argument("--vehicles", default="300")
    parser.add_argument("--only", help="only the points whose name contains this")
    args = parser.parse_args()
    argv = ["make-scenario", "--size", args.size, "--density", args.density,
            "--vehicles", args.vehicles]
    base = Path(tempfile.mkdtemp(prefix="roadweaver-faults-"))
    rows = []
    try:
        for signum in (signal.SIGTERM, signal.SIGKILL):
            for name, reached in POINTS.items():
                if args.only and args.only not in name:
                    continue
                row = one_point(base, name, reached, signum, argv)
                rows.append(row)
                print(f"{row['signal']:8} {row['point']:24} killed at {row['killed_at_s']} s, "
                      f"exit {row['exit_code']}; survivors {row['survivors'] or 'none'}; "
                      f"stray outside parent {row['stray_outside_parent'] or 'none'}; "
                      f"beside output {row['left_beside_output'] or 'none'}; next run "
                      f"{'ok' if row['next_run_ok'] else 'FAILED: ' + row['next_run_detail']}",
                      flush=True)
    finally:
        shutil.rmtree(base, ignore_errors=True)
    reached = [r for r in rows if r["killed_at_s"] is not None]
    print(f"\n{len(reached)} of {len(rows)} points reached; "
          f"{sum(r['exit_code'] == 'hung' for r in rows)} hung after the signal, "
          f"{sum(bool(r['survivors']) for r in reached)} left a process alive, "
          f"{sum(bool(r['stray_outside_parent']) for r in reached)} a file outside the "
          f"output's parent, {sum(bool(r['left_beside_output']) for r in reached)} a folder "
          f"beside the output; next run failed after {sum(not r['next_run_ok'] for r in rows)}")
    bad = [r for r in reached if r["survivors"] or r["stray_outside_parent"]
           or not r["next_run_ok"] or r["exit_code"] == "hung"]
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
