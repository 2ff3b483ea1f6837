"""A controller over a whole suite (issue 37): one score table, and what changed against an
earlier one.

This is what users keep in CI: a suite made with ``make-suite --ego-routes N`` stays fixed,
each version of their stack drives every route of it (``drive-suite``), and the table of that
run is compared with the last accepted one. A route that scores lower, or shows an infraction
kind it did not have, is a regression; every change is listed by scenario, route and
infraction.
"""

from __future__ import annotations

import json
from pathlib import Path

from ..errors import RoadweaverError
from ..suite.manifest import read_manifest
from .drive import run
from .routes import read_ego_routes

SCORES_FILE = "drive_scores.json"
SCORE_TOLERANCE = 1e-3  # scores are rounded to 4 decimals; smaller changes are float noise


def drive_suite(suite_dir: Path, controller, progress=None) -> dict:
    """Drive ``controller`` along every ego route of every scenario of the suite; returns the
    score table: the controller, each route's score, completion and infraction counts, and
    the mean score. ``progress`` (a :class:`~roadweaver_sumo.suite.Progress`) hears of each
    route driven."""
    suite, manifest = read_manifest(suite_dir)
    if not suite.ego_routes:
        raise RoadweaverError(f"{suite_dir}: the suite has no ego routes; make it with "
                              "make-suite --ego-routes N")
    names = sorted(manifest["scenarios"])
    rows = []
    for name in names:
        for k, _ in enumerate(read_ego_routes(Path(suite_dir) / name)):
            report = run(Path(suite_dir) / name, controller, route=k)
            rows.append({"scenario": name, "route": k, "score": report["score"],
                         "route_completion": report["route_completion"],
                         "infractions": report["infraction_counts"]})
            if progress:
                progress.done(f"{name} route {k}", f"{report['score']:.3f}")
    mean = sum(r["score"] for r in rows) / len(rows)
    return {"controller": report["controller"], "mean_score": round(mean, 4), "routes": rows}


def compare_scores(baseline: dict, table: dict) -> tuple[list[str], bool]:
    """Lines naming each route whose score or infraction counts changed from ``baseline`` to
    ``table``, and whether any of them is a regression (a lower score, or an infraction kind
    the route did not have)."""
    before = {(r["scenario"], r["route"]): r for r in _rows(baseline)}
    lines, regressed = [], False
    for row in _rows(table):
        old = before.pop((row["scenario"], row["route"]), None)
        where = f"{row['scenario']} route {row['route']}"
        if old is None:
            lines.append(f"{where}: new route, score {row['score']:.3f}")
            continue
        delta = row["score"] - old["score"]
        kinds = sorted(set(old["infractions"]) | set(row["infractions"]))
        changed = [f"{k} {old['infractions'].get(k, 0)} -> {row['infractions'].get(k, 0)}"
                   for k in kinds if old["infractions"].get(k, 0) != row["infractions"].get(k, 0)]
        if abs(delta) > SCORE_TOLERANCE or changed:
            worse = delta < -SCORE_TOLERANCE or bool(set(row["infractions"]) -
                                                     set(old["infractions"]))
            regressed |= worse
            lines.append(f"{where}: score {old['score']:.3f} -> {row['score']:.3f}"
                         f"{' (worse)' if worse else ''}" +
                         (f"; {', '.join(changed)}" if changed else ""))
    lines += [f"{s} route {k}: in the baseline only" for s, k in sorted(before)]
    return lines, regressed


def read_scores(path: Path) -> dict:
    """A score table written by ``drive-suite``; a one-line error if it is not one."""
    try:
        table = json.loads(Path(path).read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise RoadweaverError(f"cannot read score table {path}: {exc}") from None
    _rows(table, path)
    return table


def table_lines(table: dict) -> list[str]:
    """The score table as text: one line per route, then the mean."""
    mean = (f"controller {table['controller']}: mean score {table['mean_score']:.3f} over "
            f"{len(table['routes'])} routes")
    return [_row_line(r) for r in table["routes"]] + [mean]


def _row_line(row: dict) -> str:
    kinds = ", ".join(f"{k} x{n}" for k, n in sorted(row["infractions"].items())) or "none"
    return (f"{row['scenario']:<40} route {row['route']}  score {row['score']:.3f}  "
            f"completion {row['route_completion']:.3f}  infractions: {kinds}")


def _rows(table, path: Path | str = "score table") -> list[dict]:
    rows = table.get("routes") if isinstance(table, dict) else None
    if not isinstance(rows, list) or not all(
            isinstance(r, dict) and {"scenario", "route", "score", "infractions"} <= set(r)
            for r in rows):
        raise RoadweaverError(f"{path} is not a drive-suite score table (no 'routes' rows)")
    return rows
