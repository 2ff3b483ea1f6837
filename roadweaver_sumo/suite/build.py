"""``make-suite``: build every scenario of a grid through ``pipeline.make_scenario`` and write
``manifest.json``.

The whole suite folder is staged (``staging.staged_folder``): it appears complete or not at all,
and an existing one is replaced only with ``force``. On Ray the scenario is built in a temporary
folder on whichever node runs the task and its files come back to the caller, so a cluster needs
no shared file system.
"""

from __future__ import annotations

import json
import shutil
import tempfile
from dataclasses import dataclass
from pathlib import Path

from .. import __version__
from ..errors import RoadweaverError
from ..spec import ScenarioSpec
from ..staging import staged_folder
from .coverage import MAX_RESEEDS, reseeded, shortfall
from .engines import check_engine, cores_busy, run_jobs
from .grid import SuiteSpec
from .manifest import MANIFEST_FILE, error_entry, manifest_text, scenario_entry
from .progress import Progress


@dataclass
class SuiteResult:
    """The written suite: its folder and the manifest's scenario entries by name."""

    out_dir: Path
    scenarios: dict[str, dict]

    @property
    def failed(self) -> dict[str, list[str]]:
        """Scenarios that failed a threshold or could not be generated, with the reasons."""
        return {n: e["failures"] for n, e in sorted(self.scenarios.items()) if not e["passed"]}


def make_suite(
    suite: SuiteSpec,
    out_dir: Path,
    *,
    force: bool = False,
    engine: str = "local",
    workers: int | None = None,
    address: str | None = None,
    progress: Progress | None = None,
) -> SuiteResult:
    """Build the suite into ``out_dir`` (``engine`` "local" or "ray") and return its entries."""
    out_dir = Path(out_dir)
    check_engine(engine, workers, address)
    specs = {spec.name: spec for spec in suite.scenarios()}
    progress = progress or Progress(len(specs), enabled=False)
    entries: dict[str, dict] = {}
    with staged_folder(out_dir, force) as tmp:

        def on_result(result: tuple) -> None:
            name, error, files = result
            folder = tmp / name
            if files is not None:
                _unpack(files, folder)
            entry = error_entry(specs[name], error) if error else scenario_entry(folder, specs[name])
            entries[name] = entry
            status = "error" if error else ("passed" if entry["passed"] else "FAILED")
            progress.done(name, status)

        local = engine != "ray"  # Ray workers may sit on other machines: files come back
        busy = cores_busy(engine, workers)

        def build(batch: dict[str, ScenarioSpec]) -> None:
            jobs = [(spec.to_json(), str(tmp / name) if local else None, busy)
                    for name, spec in batch.items()]
            run_jobs(build_job, jobs, on_result, engine=engine, workers=workers, address=address)

        where = f"Ray{f' at {address}' if address else ''}" if engine == "ray" else "local workers"
        progress.say(f"building {len(specs)} scenarios on {where} into {out_dir}")
        build(specs)
        if suite.min_coverage:
            _meet_coverage(suite.min_coverage, specs, entries, tmp, build, progress)
        (tmp / MANIFEST_FILE).write_text(manifest_text(suite, entries), encoding="utf-8")
    return SuiteResult(out_dir, entries)


def _meet_coverage(minimum: dict[str, int], specs: dict[str, ScenarioSpec],
                   entries: dict[str, dict], tmp: Path, build, progress: Progress) -> None:
    """Build passing scenarios that lack ``minimum`` again with their next seeds
    (``coverage.reseeded``) until each has it or ``MAX_RESEEDS`` tries are spent; one still
    short then fails with what it lacks. A seed tried in place of a passing one that fails
    its checks is tried past too: asking for coverage must not turn a passing scenario into
    a failing one. ``specs`` and ``entries`` change in place."""
    origin, grid = dict(specs), set(specs)

    def wanting(name: str) -> str | None:
        if not entries[name]["passed"]:
            return None if name in grid else "fails its checks"
        lacking = shortfall(tmp / name, minimum)
        return f"lacks {', '.join(lacking)}" if lacking else None

    for attempt in range(1, MAX_RESEEDS + 1):
        short = {name: why for name in list(specs) if (why := wanting(name))}
        if not short:
            return
        batch = {}
        for name, why in short.items():
            spec = reseeded(origin[name], attempt)
            if spec.name in specs:  # the grid has that seed already
                continue
            progress.say(f"{name} {why}: building seed {spec.seed} instead")
            shutil.rmtree(tmp / name, ignore_errors=True)  # none if it could not be made
            del specs[name], entries[name]
            specs[spec.name], origin[spec.name] = spec, origin.pop(name)
            batch[spec.name] = spec
        progress.total += len(batch)
        build(batch)
    for name in specs:
        lacking = entries[name]["passed"] and shortfall(tmp / name, minimum)
        if lacking:
            entries[name]["passed"] = False
            entries[name]["failures"].append(
                f"coverage after {MAX_RESEEDS} more seeds: {', '.join(lacking)}")


def build_job(job: tuple[str, str | None, bool]) -> tuple[str, str | None, dict | None]:
    """Worker: build one scenario. ``job`` is (spec JSON, folder, cores busy); without a folder
    the scenario is built in a temporary one and its files are returned as {relative path:
    bytes}.

    Returns (name, error message or None, files or None). Errors are returned, not raised, so
    that one broken scenario is recorded in the manifest instead of stopping the whole suite.
    """
    spec_json, dest, busy = job
    spec = _spec_from_json(spec_json)
    try:
        if spec.version != __version__:
            raise RoadweaverError(
                f"this worker runs roadweaver-sumo {__version__}, the suite wants {spec.version}"
            )
        if dest is not None:
            _build(spec, Path(dest), busy)
            return spec.name, None, None
        with tempfile.TemporaryDirectory(prefix="roadweaver-suite-") as tmp:
            folder = Path(tmp) / spec.name
            _build(spec, folder, busy)
            files = {p.relative_to(folder).as_posix(): p.read_bytes()
                     for p in sorted(folder.rglob("*")) if p.is_file()}  # fmt: skip
        return spec.name, None, files
    except RoadweaverError as exc:
        return spec.name, str(exc), None
    except Exception as exc:  # noqa: BLE001 - a bug in one scenario must not lose the others
        return spec.name, f"{type(exc).__name__}: {exc}", None


def _build(spec: ScenarioSpec, folder: Path, busy: bool) -> None:
    from ..pipeline import make_scenario  # imported in the worker: keeps the CLI start fast

    make_scenario(spec, folder, force=False, validate=True, cores_busy=busy)


def _spec_from_json(text: str) -> ScenarioSpec:
    """The spec a worker builds: read as ``spec.json`` is, where fields left unsaid have their
    legacy values (``ScenarioSpec(**data)`` gave a ring suite open maps)."""
    return ScenarioSpec.from_dict(json.loads(text))


def _unpack(files: dict[str, bytes], folder: Path) -> None:
    for rel, data in files.items():
        path = folder / rel
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(data)
