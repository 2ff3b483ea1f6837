"""``check-suite``: does a suite still match its manifest?

Per scenario, three looks, each naming what drifted:
1. the files on disk against the manifest's sha256 (missing, changed, unexpected files): these
   are the suite's own files, the same bytes on every machine;
2. a fresh validation of the folder on disk against the manifest's key figures (within the last
   rounded decimal: ``compare.same_figure``);
3. unless ``regenerate=False``, a rebuild from the spec into a temporary folder (the generator
   itself has not drifted). Its files should have the manifest's hashes; on another CPU a file
   may differ by floating-point noise in its numbers, so a file whose hash differs is compared
   with the suite's copy within the tolerances of :mod:`.compare`: within them it is a note,
   beyond them drift, named with the first line that differs.
"""

from __future__ import annotations

import hashlib
import json
import tempfile
from pathlib import Path

from ..errors import RoadweaverError
from ..staging import scratch_beside, scratch_dir, scratch_inside
from .compare import compare_files, same_figure
from .engines import check_workers, cores_busy, run_jobs
from .manifest import environment, file_hashes, key_figures, read_manifest, spec_from_entry
from .progress import Progress


def check_suite(
    folder: Path,
    *,
    regenerate: bool = True,
    workers: int | None = None,
    progress: Progress | None = None,
    notes: dict[str, list[str]] | None = None,
) -> dict[str, list[str]]:
    """Problems per scenario name (an empty list when the scenario matches its manifest entry).

    Problems that concern the suite folder itself are listed under the name ``"(suite)"``.
    ``notes``, if given, receives per scenario the files a rebuild wrote with other bytes
    that differ only by floating-point noise (no problem).
    """
    folder = Path(folder)
    check_workers(workers)
    _, manifest = read_manifest(folder)
    entries = manifest["scenarios"]
    problems: dict[str, list[str]] = {"(suite)": _suite_problems(folder, entries)}
    progress = progress or Progress(len(entries), enabled=False)

    def on_result(result: tuple[str, list[str], list[str]]) -> None:
        name, found, noise = result
        problems[name] = found
        if notes is not None and noise:
            notes[name] = noise
        progress.done(name, "ok" if not found else "DRIFTED")

    what = "re-validating and regenerating" if regenerate else "re-validating"
    progress.say(f"{what} {len(entries)} scenarios of {folder}")
    busy = cores_busy("local", workers)
    with scratch_beside(folder) as scratch:  # the workers' temporary files, rebuilds included
        jobs = [(str(folder / name), entry, regenerate, busy, scratch and str(scratch))
                for name, entry in sorted(entries.items())]
        run_jobs(check_job, jobs, on_result, workers=workers)
    return dict(sorted(problems.items()))


def environment_note(folder: Path) -> str | None:
    """A line naming the packages whose versions differ from those the suite was made with."""
    try:
        _, manifest = read_manifest(folder)
    except RoadweaverError:
        return None
    made, here = manifest.get("environment", {}), environment()
    changed = [f"{k} {made[k]} -> {here.get(k, 'not installed')}"
               for k in sorted(made) if made[k] != here.get(k, "not installed")]  # fmt: skip
    return f"made with other versions: {', '.join(changed)}" if changed else None


def check_job(job: tuple[str, dict, bool, bool, str | None]
              ) -> tuple[str, list[str], list[str]]:
    """Worker: the problems of one scenario folder against its manifest entry, and the notes
    on files rebuilt with floating-point noise. ``job`` is (folder, manifest entry,
    regenerate, cores busy, the folder for temporary files or None)."""
    path, entry, regenerate, busy, scratch = job
    folder = Path(path)
    name = folder.name
    if "error" in entry:
        return name, [f"its generation failed when the suite was made: {entry['error']}"], []
    if not folder.is_dir():
        return name, ["scenario folder is missing"], []
    notes: list[str] = []
    try:
        problems = _compare_files("file", file_hashes(folder), entry["files"])
        with scratch_inside(scratch):
            problems += _revalidate(folder, entry["figures"], busy)
            if regenerate:
                problems += _regenerate(entry, busy, folder, notes)
    except OSError as exc:
        problems = [f"cannot read the scenario: {exc.strerror or exc}"]
    except Exception as exc:  # noqa: BLE001 - a damaged folder is a finding, not a crash
        problems = [f"check failed: {type(exc).__name__}: {exc}"]
    return name, problems, notes


def _suite_problems(folder: Path, entries: dict) -> list[str]:
    extra = sorted(p.name for p in folder.iterdir()
                   if p.is_dir() and not p.name.startswith(".") and p.name not in entries)  # fmt: skip
    return [f"folder {name} is not in the manifest" for name in extra]


def _compare_files(what: str, actual: dict[str, str], expected: dict[str, str]) -> list[str]:
    return [message for _, message in _file_drift(what, actual, expected)]


def _file_drift(what: str, actual: dict[str, str],
                expected: dict[str, str]) -> list[tuple[str, str]]:
    """(path, what is wrong with it) for every file missing, unexpected or with other bytes."""
    problems = []
    for rel in sorted(set(actual) | set(expected)):
        if rel not in actual:
            problems.append((rel, f"{what} {rel} is missing"))
        elif rel not in expected:
            problems.append((rel, f"{what} {rel} is not in the manifest"))
        elif actual[rel] != expected[rel]:
            message = (f"{what} {rel} differs from the manifest (sha256 {actual[rel][:12]}..., "
                       f"manifest {expected[rel][:12]}...)")
            problems.append((rel, message))
    return problems


def _revalidate(folder: Path, figures: dict, busy: bool) -> list[str]:
    """Validate the folder on disk again (read-only: SUMO writes into a temporary folder)."""
    from ..validate.report import _with_verdict, validate_scenario

    try:
        report, _ = validate_scenario(folder, split_routing=not busy)
    except RoadweaverError as exc:
        return [f"re-validation failed: {exc}"]
    now = key_figures(_with_verdict(report))  # rounded as report.json is
    return [
        f"figure {name} is {_fmt(now.get(name))}, manifest {_fmt(value)}"
        for name, value in sorted(figures.items())
        if not same_figure(now.get(name), value)
    ]


def _regenerate(entry: dict, busy: bool, folder: Path, notes: list[str]) -> list[str]:
    """Rebuild the scenario; a file with other bytes than the manifest's is drift unless it
    matches the suite's own copy (itself as the manifest has it) within the tolerances."""
    from ..pipeline import make_scenario

    spec = spec_from_entry(entry, "manifest")
    with tempfile.TemporaryDirectory(prefix="regenerated-", dir=scratch_dir()) as tmp:
        out = Path(tmp) / spec.name
        try:
            make_scenario(spec, out, validate=True, cores_busy=busy)
        except RoadweaverError as exc:
            return [f"regeneration failed: {exc}"]
        hashes, expected = file_hashes(out), entry["files"]
        problems = []
        for rel, message in _file_drift("regenerated", hashes, expected):
            own = folder / rel
            if not (rel in hashes and rel in expected and own.is_file()
                    and _sha256(own) == expected[rel]):
                problems.append(message)
                continue
            same, detail = compare_files(out / rel, own)
            if same:
                notes.append(f"regenerated {rel} differs only by floating-point noise ({detail})")
            else:
                problems.append(f"regenerated {rel} differs from the manifest: {detail}")
        return problems


def _sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _fmt(value) -> str:
    return json.dumps(value)
