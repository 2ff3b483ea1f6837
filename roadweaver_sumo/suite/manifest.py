"""``manifest.json`` of a suite: per scenario its spec, the sha256 of every output file (except
``timing.json``, which holds wall-clock times) and the key validation figures.

The manifest holds nothing that depends on how or where the suite was built (no paths, times,
engine or worker count), so the same suite gives the same bytes on one worker, many, or Ray.
"""

from __future__ import annotations

import hashlib
import json
import math
from collections import Counter
from importlib import metadata
from pathlib import Path, PurePosixPath

from .. import __version__
from ..errors import RoadweaverError
from ..spec import DEFAULT_GEO_ORIGIN, ScenarioSpec
from ..validate.report import THRESHOLDS
from .coverage import MAX_RESEEDS, reseeded
from .grid import SuiteSpec

MANIFEST_FILE = "manifest.json"
SCHEMA_VERSION = 1
UNHASHED = frozenset({"timing.json"})
# The threshold figures plus a few that show at a glance what a scenario is like.
FIGURES = tuple(t.figure for t in THRESHOLDS) + (
    "net.road_nodes",
    "net.density",
    "net.lanes",
    "net.dead_end_ratio",
    "net.junction_reachability",
    "simulation.loaded",
    "simulation.arrived",
    "simulation.teleports_total",
    "simulation.mean_travel_time_s",
    "simulation.mean_waiting_time_s",
    # waiting per vehicle on the approaches under each rule: where a changed driver model or
    # SUMO version shows first (``validate.rule_coverage.rule_waits``)
    *(f"simulation.rules.{rule}.waiting_s" for rule in ("signalised", "stop", "all_way_stop",
                                                        "right_before_left", "yield")),
    # walkers: how many arrived and the time a walk lost at crossings and lights
    "simulation.persons_arrived",
    "simulation.persons_time_loss_s",
)
# Packages whose versions change the bytes of a scenario: a hash drift on a machine with other
# versions is then explained rather than a mystery.
VERSIONED = ("eclipse-sumo", "numpy", "numba", "scipy", "shapely", "networkx", "scikit-image",
             "matplotlib")


def file_hashes(folder: Path) -> dict[str, str]:
    """sha256 of every file under ``folder`` by its relative POSIX path, except ``UNHASHED``."""
    folder = Path(folder)
    hashes = {}
    for path in sorted(p for p in folder.rglob("*") if p.is_file()):
        rel = path.relative_to(folder).as_posix()
        if rel not in UNHASHED:
            hashes[rel] = hashlib.sha256(path.read_bytes()).hexdigest()
    return hashes


def key_figures(report: dict) -> dict:
    """The ``FIGURES`` of a report, by dotted name (None where the report has no such figure)."""
    figures = {}
    for name in FIGURES:
        value = report
        for part in name.split("."):
            value = value.get(part) if isinstance(value, dict) else None
        figures[name] = value
    return figures


def scenario_entry(folder: Path, spec: ScenarioSpec) -> dict:
    """The manifest entry of a built scenario folder."""
    report = json.loads((Path(folder) / "report.json").read_text(encoding="utf-8"))
    entry = {"spec": json.loads(spec.to_json()), "files": file_hashes(folder)}
    if "net" in report:
        entry.update(figures=key_figures(report), passed=report["passed"],
                     failures=report["failures"])  # fmt: skip
    else:
        entry.update(figures={}, passed=False, failures=["not validated"])
    return entry


def error_entry(spec: ScenarioSpec, message: str) -> dict:
    """The entry of a scenario whose generation failed: no files, the error in one line."""
    return {"spec": json.loads(spec.to_json()), "error": message, "passed": False,
            "failures": [f"generation failed: {message}"]}  # fmt: skip


def environment() -> dict[str, str]:
    """Versions of roadweaver-sumo and of the packages that shape its outputs."""
    env = {"roadweaver-sumo": __version__}
    for name in VERSIONED:
        try:
            env[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            env[name] = "not installed"
    return env


def manifest_text(suite: SuiteSpec, entries: dict[str, dict]) -> str:
    data = {
        "schema_version": SCHEMA_VERSION,
        "suite": suite.to_dict(),
        "environment": environment(),
        "scenarios": entries,
    }
    return json.dumps(data, indent=2, sort_keys=True, allow_nan=False) + "\n"


def read_manifest(folder: Path) -> tuple[SuiteSpec, dict]:
    """Read and check ``folder/manifest.json``; returns (suite, manifest). Anything malformed is a
    one-line error naming what is wrong, since check-suite must never act on a broken manifest
    (e.g. a file path leading out of the suite)."""
    path = Path(folder) / MANIFEST_FILE
    if not Path(folder).is_dir():
        raise RoadweaverError(f"suite folder {folder} not found")
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise RoadweaverError(f"{folder} is not a suite folder (no {MANIFEST_FILE})") from None
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise RoadweaverError(f"cannot read {path}: {exc}") from None
    if not isinstance(data, dict) or data.get("schema_version") != SCHEMA_VERSION:
        raise RoadweaverError(f"{path}: not a manifest of schema version {SCHEMA_VERSION}")
    suite = SuiteSpec.from_dict(data.get("suite"))
    scenarios = data.get("scenarios")
    if not isinstance(scenarios, dict):
        raise RoadweaverError(f"{path}: 'scenarios' must be an object")
    # a suite with a minimum coverage may hold a grid scenario built with a later seed
    tries = range(MAX_RESEEDS + 1) if suite.min_coverage else range(1)
    grid = {spec.name: spec for spec in suite.scenarios()}
    stands_for = {reseeded(spec, k).name: name for name, spec in grid.items() for k in tries}
    for name in sorted(set(scenarios) - set(stands_for)):
        raise RoadweaverError(f"{path}: the manifest lists scenario {name!r}, its suite does not")
    held = Counter(stands_for[name] for name in scenarios)
    for name in grid:
        if not held[name]:
            raise RoadweaverError(f"{path}: the manifest lacks scenario {name!r}, its suite "
                                  "does not")
        if held[name] > 1:
            raise RoadweaverError(f"{path}: the manifest holds scenario {name!r} twice")
    for name, entry in scenarios.items():
        _check_entry(path, name, entry)
    if not isinstance(data.get("environment", {}), dict):
        raise RoadweaverError(f"{path}: 'environment' must be an object")
    return suite, data


def _check_entry(path: Path, name: str, entry) -> None:
    if not isinstance(entry, dict) or not isinstance(entry.get("spec"), dict):
        raise RoadweaverError(f"{path}: scenario {name!r} has no spec")
    spec = spec_from_entry(entry, f"{path}: scenario {name!r}")
    if spec.name != name:
        raise RoadweaverError(f"{path}: scenario {name!r} has the spec of {spec.name!r}")
    if "error" in entry:
        return
    files, figures = entry.get("files"), entry.get("figures")
    if not isinstance(files, dict) or not isinstance(figures, dict):
        raise RoadweaverError(f"{path}: scenario {name!r} needs 'files' and 'figures' objects")
    for rel, digest in files.items():
        parts = PurePosixPath(rel).parts
        if not parts or rel.startswith("/") or ".." in parts or "\\" in rel:
            raise RoadweaverError(f"{path}: scenario {name!r} lists a bad file path {rel!r}")
        if not isinstance(digest, str) or len(digest) != 64:
            raise RoadweaverError(f"{path}: scenario {name!r}: {rel} has no sha256")


def spec_from_entry(entry: dict, where: str) -> ScenarioSpec:
    """The ``ScenarioSpec`` of a manifest entry (``where`` prefixes the error message)."""
    data = entry["spec"]
    origin = data.get("geo_origin", DEFAULT_GEO_ORIGIN)
    if not (isinstance(origin, (list, tuple)) and len(origin) == 2
            and all(isinstance(v, (int, float)) and math.isfinite(v) for v in origin)):
        raise RoadweaverError(f"{where}: geo_origin must be [lat, lon]")
    try:
        return ScenarioSpec.from_dict(data)
    except (TypeError, ValueError) as exc:
        raise RoadweaverError(f"{where}: bad spec: {exc}") from None
    except RoadweaverError as exc:
        raise RoadweaverError(f"{where}: {exc}") from None
