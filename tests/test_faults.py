"""Faults and bad input: a killed run leaves no process and no stray file, and the next run on
its output works; every bad argument is refused up front in one line, never a traceback.

The kill tests start the real command line and find every process of the run by a marker in
its environment (children inherit it), whatever their process group or parent."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
import uuid
from pathlib import Path

import numpy as np
import pytest

from roadweaver_sumo import children, cli
from roadweaver_sumo.staging import remove_stale, staged_folder

CLI = str(Path(sys.executable).with_name("roadweaver-sumo"))
MARKER = "ROADWEAVER_TEST_RUN"
SMALL = ["make-scenario", "--size", "1000", "--density", "20", "--vehicles", "50"]


def _processes_with(token: str) -> dict[int, str]:
    """Live (not zombie) processes whose environment carries ``token``: pid -> command line."""
    found = {}
    for entry in os.scandir("/proc"):
        if not entry.name.isdigit():
            continue
        try:
            environ = Path(f"/proc/{entry.name}/environ").read_bytes().split(b"\0")
            if f"{MARKER}={token}".encode() not in environ:
                continue
            state = Path(f"/proc/{entry.name}/stat").read_text().rsplit(")", 1)[1].split()[0]
            if state not in "ZX":
                cmd = Path(f"/proc/{entry.name}/cmdline").read_bytes()
                found[int(entry.name)] = cmd.replace(b"\0", b" ").decode(errors="replace")
        except OSError:
            continue
    return found


def _gone(token: str, within: float) -> dict[int, str]:
    """The run's processes still alive after ``within`` seconds (killed, then returned)."""
    deadline = time.monotonic() + within
    while (alive := _processes_with(token)) and time.monotonic() < deadline:
        time.sleep(0.05)
    for pid in alive:  # started by this test's run: do not leave them to others
        os.kill(pid, signal.SIGKILL)
    return alive


@pytest.mark.parametrize(
    ("signum", "needle"),
    [
        (signal.SIGTERM, "/netconvert"),
        (signal.SIGTERM, "roadweaver_sumo.validate.simulation"),
        (signal.SIGKILL, "randomTrips.py"),
    ],
)
def test_a_killed_run_leaves_no_process_no_stray_file_and_the_next_run_works(
        tmp_path, signum, needle):
    parent, system_tmp = tmp_path / "parent", tmp_path / "tmp"
    parent.mkdir()
    system_tmp.mkdir()
    token = uuid.uuid4().hex
    env = {**os.environ, MARKER: token, "TMPDIR": str(system_tmp)}
    argv = [CLI, *SMALL, "--out", str(parent / "scn")]
    run = subprocess.Popen(argv, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                           text=True)
    seen = False
    while run.poll() is None and not seen:
        seen = any(needle in cmd for pid, cmd in _processes_with(token).items() if pid != run.pid)
        time.sleep(0.005)
    assert seen, f"the run ended before {needle} started"
    run.send_signal(signum)
    _, err = run.communicate(timeout=60)
    assert run.returncode == (128 + signum if signum == signal.SIGTERM else -signum), err
    # within a second: a child that outlived the run would mostly still be working (the
    # tests below check the mechanism on children that would live a minute)
    assert _gone(token, 1.0) == {}
    assert list(system_tmp.iterdir()) == []
    left = [p.name for p in parent.iterdir()]
    if signum == signal.SIGTERM:
        assert left == [] and "Traceback" not in err
        assert err.strip().splitlines()[-1] == ("roadweaver-sumo: terminated; nothing was left "
                                                "half-written")
    else:  # nothing could remove it, but it is beside the output, named after the dead run
        assert len(left) == 1 and left[0].startswith(f".scn.partial-{run.pid}-")
    again = subprocess.run([*argv, "--no-validate"], env=env, capture_output=True, text=True,
                           check=False, timeout=120)
    assert again.returncode == 0, again.stderr
    assert [p.name for p in parent.iterdir()] == ["scn"]
    assert list(system_tmp.iterdir()) == [] and _gone(token, 1.0) == {}


def test_a_killed_check_suite_leaves_its_temporary_files_only_beside_the_suite(tmp_path):
    """check-suite rebuilds each scenario from its spec: killed (SIGKILL) while the rebuild
    runs netconvert, it leaves no process, nothing in the system's temporary folder and only
    its hidden staging folder beside the suite, which the next check removes."""
    parent, system_tmp = tmp_path / "parent", tmp_path / "tmp"
    parent.mkdir()
    system_tmp.mkdir()
    suite = parent / "suite"
    made = subprocess.run([CLI, "make-suite", "--densities", "20", "--styles", "grid", "--seeds",
                           "0", "--size", "500", "--vehicles", "15", "--duration", "60",
                           "--skeleton", "procedural", "--quiet", "--out", str(suite)],
                          capture_output=True, text=True, check=False, timeout=300)
    assert made.returncode == 0, made.stderr
    token = uuid.uuid4().hex
    env = {**os.environ, MARKER: token, "TMPDIR": str(system_tmp)}
    run = subprocess.Popen([CLI, "check-suite", str(suite), "--workers", "1", "--quiet"], env=env,
                           stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    seen = False
    while run.poll() is None and not seen:
        seen = any("/netconvert" in cmd for cmd in _processes_with(token).values())
        time.sleep(0.005)
    assert seen, "check-suite ended before its rebuild ran netconvert"
    run.kill()
    run.wait(timeout=60)
    assert _gone(token, 2.0) == {}
    assert list(system_tmp.iterdir()) == []
    left = sorted(p.name for p in parent.iterdir())
    assert len(left) == 2 and left[0].startswith(f".suite.partial-{run.pid}-"), left
    again = subprocess.run([CLI, "check-suite", str(suite), "--no-regenerate", "--quiet"],
                           env=env, capture_output=True, text=True, check=False, timeout=300)
    assert again.returncode == 0, again.stderr
    assert [p.name for p in parent.iterdir()] == ["suite"]
    assert list(system_tmp.iterdir()) == [] and _gone(token, 1.0) == {}


_WITH_GRANDCHILD = ("import subprocess, time\n"
                    "print(subprocess.Popen(['sleep', '60']).pid, flush=True)\ntime.sleep(60)")


def _child_script(body: str) -> list[str]:
    return [sys.executable, "-c", "import subprocess, sys, time\n"
            "from roadweaver_sumo import children\n" + body]


def test_children_and_grandchildren_die_with_a_parent_killed_outright():
    """SIGKILL runs no clean-up: Linux's parent-death signal ends the child, and the watchdog
    its process group, where the grandchild is (a parent-death signal is not inherited)."""
    parent = subprocess.Popen(_child_script(
        "p = children.popen([sys.executable, '-c', " + repr(_WITH_GRANDCHILD) + "],\n"
        "                   stdout=subprocess.PIPE, text=True)\n"
        "print(p.pid, p.stdout.readline().strip(), flush=True)\ntime.sleep(60)"),
        stdout=subprocess.PIPE, text=True)
    child, grandchild = map(int, parent.stdout.readline().split())
    assert _alive(child) and _alive(grandchild)
    parent.kill()
    parent.wait()
    deadline = time.monotonic() + 3
    while (_alive(child) or _alive(grandchild)) and time.monotonic() < deadline:
        time.sleep(0.02)
    assert not _alive(child) and not _alive(grandchild)


def test_sigterm_kills_children_and_grandchildren_and_exits(tmp_path):
    """A child's own children share its process group, which the handler kills whole; then
    the process exits with 128 + 15 after ``before_exit``."""
    said = tmp_path / "said"
    parent = subprocess.Popen(_child_script(
        "from pathlib import Path\n"
        f"with children.handle_termination(lambda s: Path({str(said)!r}).write_text(str(s))):\n"
        "    p = children.popen([sys.executable, '-c', " + repr(_WITH_GRANDCHILD) + "],\n"
        "                       stdout=subprocess.PIPE, text=True)\n"
        "    print(p.pid, p.stdout.readline().strip(), flush=True)\n"
        "    time.sleep(60)"), stdout=subprocess.PIPE, text=True)
    child, grandchild = map(int, parent.stdout.readline().split())
    parent.send_signal(signal.SIGTERM)
    assert parent.wait(timeout=10) == 128 + signal.SIGTERM
    assert said.read_text() == str(int(signal.SIGTERM))
    deadline = time.monotonic() + 3
    while (_alive(child) or _alive(grandchild)) and time.monotonic() < deadline:
        time.sleep(0.02)
    assert not _alive(child) and not _alive(grandchild)


def test_the_handlers_are_taken_back_after_the_block():
    before = signal.getsignal(signal.SIGTERM)
    with children.handle_termination(lambda signum: None):
        assert signal.getsignal(signal.SIGTERM) is not before
    assert signal.getsignal(signal.SIGTERM) is before


def test_run_kills_a_child_that_times_out():
    start = time.monotonic()
    with pytest.raises(subprocess.TimeoutExpired):
        children.run(["sleep", "60"], timeout=0.2)
    assert time.monotonic() - start < 10


def _alive(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return False
    return state not in "ZX"


def _dead_pid() -> int:
    proc = subprocess.Popen(["true"])
    proc.wait()
    return proc.pid


def test_stale_staging_of_a_dead_run_is_removed_and_a_live_one_kept(tmp_path):
    out = tmp_path / "scn"
    dead = tmp_path / f".scn.partial-{_dead_pid()}-abc"
    live = tmp_path / f".scn.partial-{os.getppid()}-def"  # pytest's parent is alive
    other = tmp_path / f".other.partial-{_dead_pid()}-ghi"
    for folder in (dead, live, other):
        (folder / "plain").mkdir(parents=True)
    with staged_folder(out, force=False) as tmp:
        assert tmp.name.startswith(f".scn.partial-{os.getpid()}-")
        (tmp / "a").write_text("a")
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted([out.name, live.name, other.name])


def test_a_checkpoint_is_written_under_a_hidden_name_and_a_dead_runs_one_removed(tmp_path):
    """A training run killed while it saves leaves ``.NAME.partial-PID`` beside the
    checkpoint, never a half file under the real name; the next save removes it."""
    from roadweaver_sumo.generative.checkpoint import save_checkpoint

    path = tmp_path / "vq.npz"
    left = tmp_path / f".vq.npz.partial-{_dead_pid()}"
    left.write_bytes(b"half a checkpoint")
    save_checkpoint(path, {"w": np.ones(3)}, {"kind": "vqvae"})
    assert [p.name for p in tmp_path.iterdir()] == ["vq.npz"]


def test_an_output_moved_aside_by_a_killed_run_is_put_back(tmp_path):
    out = tmp_path / "scn"
    old = tmp_path / f".scn.old-{_dead_pid()}"
    old.mkdir()
    (old / "report.json").write_text("{}")
    assert remove_stale(out) == [old]
    assert (out / "report.json").read_text() == "{}" and not old.exists()


# Bad input: (arguments, what the one-line error says). Files are made by _bad_input_files.
BAD_INPUTS = [
    (["--density", "inf"], "density must be > 0"),
    (["--density", "1e999"], "density must be > 0"),
    (["--density", "401"], "above 400"),
    (["--vehicles", "1000001"], "--vehicles must be 1..1000000"),
    (["--vehicles", "2.5"], "invalid int value"),
    (["--size", "60000"], "outside 200..50000"),
    (["--size", "1000x"], "not a size"),
    (["--size", "inf"], "not a size"),
    (["--size", "1e999"], "got inf"),
    (["--seed", "2147483648"], "--seed must be a whole number 0..2147483647"),
    (["--seed", "-5"], "--seed must be"),
    (["--duration", "1e12"], "--duration must be 1..604800 s"),
    (["--duration", "604801"], "--duration must be 1..604800 s"),
    (["--duration", "0.5"], "--duration must be 1..604800 s"),
    (["--duration", "nan"], "--duration must be > 0"),
    (["--style", "wavy"], "unknown style"),
    (["--out", "{file}"], "exists and is not a folder"),
    (["--out", "{file}/sub"], "cannot write to"),
    (["--colour", "red"], "unrecognized arguments"),
]
OTHER_BAD_INPUTS = [
    (["validate", "{corrupt}"], "report.json"),
    (["validate", "{number_report}"], "not a report"),
    (["validate", "{dir}/nowhere"], "not a scenario folder"),
    (["evaluate", "{dir}/nowhere.net.xml"], "not found"),
    (["evaluate", "{file}", "--area-km2", "inf"], "argument --area-km2: must be > 0 and finite"),
    (["evaluate", "{file}", "--area-km2", "0"], "must be > 0"),
    (["evaluate", "{file}", "--area-km2", "nan"], "must be > 0"),
    (["evaluate", "{file}"], "not a SUMO network"),
    (["data", "prepare", "--osm", "{file}", "--out", "{dir}/ds", "--tile", "nan"],
     "argument --tile: must be 200..20000, got nan"),
    (["data", "prepare", "--osm", "{file}", "--out", "{dir}/ds", "--tile", "inf"], "--tile"),
    (["data", "prepare", "--osm", "{file}", "--out", "{dir}/ds", "--tile", "1"], "--tile"),
    (["data", "prepare", "--osm", "{file}", "--out", "{dir}/ds", "--size", "100000"],
     "argument --size: must be 8..512"),
    (["data", "prepare", "--osm", "{file}", "--out", "{dir}/ds", "--size", "100"],
     "multiple of 8"),
    (["data", "prepare", "--osm", "{file}", "--out", "{dir}/ds", "--seed", "-5"], "--seed"),
    (["data", "prepare", "--osm", "{dir}/missing.osm", "--out", "{dir}/ds"], "not found"),
    (["train", "vqvae", "--data", "{dataset}", "--out", "{dir}", "--force"], "is a folder"),
    (["train", "vqvae", "--data", "{dataset}", "--out", "{file}"], "--force"),
    (["train", "vqvae", "--data", "{dataset}", "--out", "{dir}/no/x.npz"], "does not exist"),
    (["train", "vqvae", "--data", "{dir}", "--out", "{dir}/x.npz"], "not a prepared dataset"),
    (["train", "vqvae", "--data", "{dataset}", "--out", "{dir}/x.npz", "--steps", "0"],
     "--steps"),
    (["train", "vqvae", "--data", "{dataset}", "--out", "{dir}/x.npz", "--lr", "inf"], "--lr"),
    (["train", "vqvae", "--data", "{dataset}", "--out", "{dir}/x.npz", "--batch", "99999"],
     "--batch"),
    (["train", "maskgit", "--data", "{dataset}", "--vqvae", "{dir}/no.npz", "--out",
      "{dir}/x.npz"], "no such checkpoint"),
    (["make-suite", "--densities", "20", "--seeds", "2147483648", "--out", "{dir}/s"],
     "--seed must be"),
    (["make-suite", "--densities", "20", "--duration", "1e12", "--out", "{dir}/s"],
     "--duration"),
    (["check-suite", "{dir}", "--workers", "0"], "--workers must be 1..256"),
    (["render", "{corrupt}"], "report.json"),
    (["render", "{dir}/nowhere"], "not a folder"),
    (["frobnicate"], "invalid choice"),
]


@pytest.fixture
def bad_input_files(tmp_path) -> dict[str, str]:
    (tmp_path / "a-file").write_text("not a net\n")
    for name, report in (("corrupt", '{"generation": '), ("number_report", "123")):
        (tmp_path / name).mkdir()
        (tmp_path / name / "scenario.sumocfg").write_text("<configuration/>")
        (tmp_path / name / "report.json").write_text(report)
    (tmp_path / "dataset").mkdir()
    (tmp_path / "dataset" / "manifest.json").write_text("{}")
    return {"file": str(tmp_path / "a-file"), "dir": str(tmp_path),
            "corrupt": str(tmp_path / "corrupt"), "dataset": str(tmp_path / "dataset"),
            "number_report": str(tmp_path / "number_report")}


def _one_line_error(capsys) -> str:
    err = capsys.readouterr().err
    assert "Traceback" not in err and err.count("\n") == 1, err
    assert err.startswith("roadweaver-sumo: error: "), err
    return err


@pytest.mark.parametrize(("args", "message"), BAD_INPUTS)
def test_bad_make_scenario_input_is_refused_up_front(bad_input_files, capsys, args, message):
    args = [a.format(**bad_input_files) for a in args]
    base = [*SMALL, "--out", f"{bad_input_files['dir']}/new"]
    for option, value in zip(args[::2], args[1::2]):
        if option in base:
            base[base.index(option) + 1] = value
        else:
            base += [option, value]
    start = time.monotonic()
    assert cli.main(base) == 2
    assert message in _one_line_error(capsys)
    assert time.monotonic() - start < 30  # refused before any work (imports may be slow)
    assert not Path(bad_input_files["dir"], "new").exists()


@pytest.mark.parametrize(("args", "message"), OTHER_BAD_INPUTS)
def test_bad_input_of_every_command_is_refused_up_front(bad_input_files, capsys, args,
                                                        message):
    start = time.monotonic()
    assert cli.main([a.format(**bad_input_files) for a in args]) == 2
    assert message in _one_line_error(capsys)
    assert time.monotonic() - start < 30


@pytest.mark.parametrize("args", [[*SMALL, "--seed", "2147483648"],
                                  ["evaluate", "x.net.xml", "--area-km2", "inf"]])
def test_the_installed_command_refuses_bad_input_in_one_line(tmp_path, args):
    proc = subprocess.run([CLI, *args], cwd=tmp_path, capture_output=True, text=True,
                          check=False, timeout=60)
    assert proc.returncode == 2
    assert proc.stderr.count("\n") == 1 and proc.stderr.startswith("roadweaver-sumo: error:")
    assert list(tmp_path.iterdir()) == []


def test_an_internal_error_is_one_line_naming_a_log_with_the_traceback(tmp_path, capsys,
                                                                      monkeypatch):
    def broken(args):
        raise ValueError("a bug\nover two lines")

    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    monkeypatch.setattr(cli, "_evaluate", broken)
    assert cli.main(["evaluate", "x.net.xml"]) == 3
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "internal error (ValueError: a bug over two lines)" in err
    log = Path(err.split("traceback in ")[1].strip())
    assert log.parent == tmp_path / "roadweaver-sumo"
    assert "Traceback" in log.read_text() and "a bug" in log.read_text()


def test_help_states_ranges_choices_and_defaults(capsys):
    with pytest.raises(SystemExit):
        cli.main(["make-scenario", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    for shown in ("1..1000000", "0..2147483647", "1..604800", "<= 400", "200..50000",
                  "{grid,radial,organic,mixed}", "{learned,procedural}", "(default: 3600.0)",
                  "(default: mixed)"):
        assert shown in text


def test_validate_keeps_its_temporary_files_beside_the_scenario(tmp_path):
    from roadweaver_sumo.staging import scratch_beside, scratch_dir

    folder = tmp_path / "scn"
    folder.mkdir()
    stale = tmp_path / f".scn.partial-{_dead_pid()}-x"
    stale.mkdir()
    with scratch_beside(folder) as scratch:
        assert scratch_dir() == scratch and scratch.parent == tmp_path
        assert not stale.exists()
    assert scratch_dir() is None and sorted(p.name for p in tmp_path.iterdir()) == ["scn"]


def test_temporary_files_of_a_relative_output_are_found_from_any_folder(tmp_path, monkeypatch):
    """SUMO's tools run inside the staging folder: a relative scratch path would point
    elsewhere there."""
    from roadweaver_sumo.staging import scratch_dir

    monkeypatch.chdir(tmp_path)
    with staged_folder(Path("scenarios/scn"), force=False) as tmp:
        assert scratch_dir().is_absolute() and scratch_dir() == tmp.resolve()
