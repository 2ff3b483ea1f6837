"""OpenDRIVE check of issue 3: XSD validity, ASAM quality checker, lane-end alignment and a
netconvert round trip, for given ``.xodr`` files or a generated sweep.

The ASAM checker (PyPI ``asam-qc-opendrive``, which ships the OpenDRIVE 1.7 XSD) pins
numpy < 2 and lxml < 6, so it lives in its own venv and is run as a child process::

    python3 -m venv /work/qcvenv && /work/qcvenv/bin/pip install asam-qc-opendrive
    python bench/check_opendrive.py --qc-python /work/qcvenv/bin/python       # the sweep
    python bench/check_opendrive.py --qc-python /work/qcvenv/bin/python a.xodr b.xodr

``--qc-python`` defaults to ``$ROADWEAVER_QC_PYTHON``. Without files the sweep generates maps
(densities x seeds, ``--size`` metres square, ``--style``) as the pipeline writes them and also
compares netconvert's import with the HD map: road nodes (degree != 2, within 2 %) and
lane-level reachability. Prints one row per map (alignment in micrometres) and totals; ``--json`` saves the rows.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from lxml import etree
from quality_sweep import seeds_arg  # bench/ is sys.path[0] when run as a script

from roadweaver_sumo.errors import RoadweaverError
from roadweaver_sumo.expand import expand_skeleton
from roadweaver_sumo.export.map_files import write_map_files
from roadweaver_sumo.hdmap import build_hdmap, lane_reachability
from roadweaver_sumo.metrics import road_node_count
from roadweaver_sumo.skeleton import make_skeleton
from roadweaver_sumo.spec import ScenarioSpec
from roadweaver_sumo.sumo_tools import binary, run
from roadweaver_sumo.validate import net_metrics
from roadweaver_sumo.validate.netgraph import lane_graph, load_net, road_graph
from roadweaver_sumo.validate.xodr_alignment import xodr_alignment

# Runs inside the qc venv: validate argv[1] against the OpenDRIVE 1.7 XSD shipped with
# qc_opendrive (lxml, as the checker does for <= 1.7) and print the result as JSON.
XSD_SNIPPET = """
import importlib.resources, json, sys
from lxml import etree
from qc_opendrive.schema import schema_files
xsd = importlib.resources.files("qc_opendrive.schema").joinpath(schema_files.SCHEMA_FILES["1.7.0"])
schema = etree.XMLSchema(etree.parse(str(xsd)))
valid = schema.validate(etree.parse(sys.argv[1]))
errors = [f"line {e.line}: {e.message}" for e in schema.error_log]
print(json.dumps({"valid": bool(valid), "errors": len(errors), "first": errors[:3]}))
"""

CHECKER_CONFIG = """<?xml version="1.0" encoding="UTF-8"?>
<Config>
  <Param name="InputFile" value="{xodr}"/>
  <CheckerBundle application="xodrBundle">
    <Param name="resultFile" value="{result}"/>
  </CheckerBundle>
</Config>
"""
LEVELS = {"1": "errors", "2": "warnings", "3": "info"}  # qc_baselib IssueSeverity


def xsd_check(xodr: Path, qc_python: str) -> dict:
    """Validity against the OpenDRIVE 1.7 XSD shipped in ``asam-qc-opendrive``."""
    proc = subprocess.run([qc_python, "-c", XSD_SNIPPET, str(xodr)], capture_output=True,
                          text=True, check=False)
    if proc.returncode != 0:
        raise RoadweaverError(f"XSD check failed: {proc.stderr.strip().splitlines()[-1:]}")
    return json.loads(proc.stdout)


def asam_check(xodr: Path, qc_python: str, work: Path) -> dict:
    """Run the ASAM OpenDRIVE checker bundle (all checks, default configuration) and count
    the issues of its ``.xqar`` result by level and by checker."""
    config, result = work / "qc_config.xml", work / "qc_result.xqar"
    config.write_text(CHECKER_CONFIG.format(xodr=xodr.resolve(), result=result.resolve()))
    result.unlink(missing_ok=True)
    proc = subprocess.run([qc_python, "-m", "qc_opendrive.main", "-c", str(config)],
                          capture_output=True, text=True, check=False, cwd=work)
    if proc.returncode != 0 or not result.exists():
        raise RoadweaverError(f"ASAM checker failed: {proc.stderr.strip().splitlines()[-1:]}")
    counts = {"errors": 0, "warnings": 0, "info": 0, "by_checker": {}, "not_completed": []}
    for checker in etree.parse(str(result)).getroot().iter("Checker"):
        name = checker.get("checkerId").removeprefix("check_asam_xodr_")
        if checker.get("status") != "completed":
            counts["not_completed"].append(f"{name}:{checker.get('status')}")
        for issue in checker.iter("Issue"):
            counts[LEVELS.get(issue.get("level"), "info")] += 1
            counts["by_checker"][name] = counts["by_checker"].get(name, 0) + 1
    return counts


def netconvert_check(xodr: Path, work: Path) -> dict:
    """Import the file with netconvert; road nodes, lane reachability and the alignment of
    the imported lanes, read back from the ``.net.xml``."""
    net_path = work / "xodr.net.xml"
    start = time.perf_counter()
    try:
        run([binary("netconvert"), "--opendrive-files", str(xodr.resolve()), "-o", net_path.name],
            cwd=work, what="netconvert")
    except RoadweaverError as err:
        return {"ok": False, "error": str(err)}
    net = load_net(net_path)
    return {"ok": True, "seconds": time.perf_counter() - start,
            "road_nodes": road_node_count(road_graph(net)),
            "lane_reachability": net_metrics.lane_reachability(lane_graph(net)),
            "net_alignment_max": net_metrics.alignment_errors(net)["max"]}


def check_file(xodr: Path, qc_python: str | None, work: Path) -> dict:
    """Every check of one file (the ASAM ones only with a qc venv)."""
    row: dict = {"file": str(xodr), "alignment": xodr_alignment(xodr)}
    if qc_python:
        row["xsd"] = xsd_check(xodr, qc_python)
        row["asam"] = asam_check(xodr, qc_python, work)
    row["netconvert"] = netconvert_check(xodr, work)
    return row


def sweep_row(density: float, seed: int, args, work: Path) -> dict:
    """Generate one map, write its ``.xodr``, check it and compare with its HD map."""
    spec = ScenarioSpec(density=density, vehicles=1, width=args.size, height=args.size,
                        style=args.style, seed=seed)
    start = time.perf_counter()
    hd = build_hdmap(expand_skeleton(spec, make_skeleton(spec)), spec.geo_origin,
                     rules=spec.rules, one_way_share=spec.one_way_share)
    xodr = write_map_files(hd, work)["opendrive"]  # after netconvert: with its right of way
    row = check_file(xodr, args.qc_python, work)
    row.update(density=density, seed=seed, roads=len(hd.roads),
               connectors=sum(len(j.connectors) for j in hd.junctions.values()),
               hd_road_nodes=sum(1 for j in hd.junctions.values() if len(j.roads) != 2),
               hd_lane_reachability=lane_reachability(hd),
               seconds=time.perf_counter() - start)
    return row


def format_row(row: dict) -> str:
    """One table line: XSD, checker issues, alignment (µm), netconvert comparison."""
    name = (f"d={row['density']:>4g} s={row['seed']}" if "density" in row
            else Path(row["file"]).name[-12:].rjust(12))
    xsd = "-" if "xsd" not in row else ("valid" if row["xsd"]["valid"] else
                                        f"{row['xsd']['errors']} err")
    asam = row.get("asam", {})
    issues = f"{asam.get('errors', '-'):>3} {asam.get('warnings', '-'):>3}"
    al = row["alignment"]
    net = row["netconvert"]
    text = (f"{name}  {xsd:>7}  {issues}  {al['mean'] * 1e6:8.4f} {al['max'] * 1e6:8.4f}  "
            f"{'ok' if net['ok'] else 'FAIL':>4}")
    if net["ok"] and "hd_road_nodes" in row:
        text += (f"  {row['hd_road_nodes']:>4}/{net['road_nodes']:<4} "
                 f"{row['hd_lane_reachability']:.4f}/{net['lane_reachability']:.4f}")
    elif net["ok"]:  # a file without its HD map: the net's own figures
        text += f"     -/{net['road_nodes']:<4}      -/{net['lane_reachability']:.4f}"
    if "seconds" in row:
        text += f"  {row['seconds']:5.1f}s"
    return text


HEADER = ("map             xsd   err warn  mean(um)  max(um)  net  nodes hd/net"
          "  reach hd/net    time")


def totals(rows: list[dict]) -> list[str]:
    """Summary lines over all rows."""
    n = len(rows)
    lines = []
    if all("xsd" in r for r in rows):
        valid = sum(r["xsd"]["valid"] for r in rows)
        errors = sum(r["asam"]["errors"] for r in rows)
        warnings = sum(r["asam"]["warnings"] for r in rows)
        by_checker: dict = {}
        for r in rows:
            for k, v in r["asam"]["by_checker"].items():
                by_checker[k] = by_checker.get(k, 0) + v
        lines.append(f"XSD valid {valid}/{n}; ASAM checker: {errors} errors, {warnings} warnings"
                     + (f" {by_checker}" if by_checker else ""))
        skipped = sorted({s for r in rows for s in r["asam"]["not_completed"]})
        lines.append(f"checks not completed: {', '.join(skipped) or 'none'}")
    means = [r["alignment"]["mean"] for r in rows]
    worst = max(r["alignment"]["max"] for r in rows)
    lines.append(f"alignment: mean {sum(means) / n * 1e6:.4f} µm, max {worst * 1e6:.4f} µm "
                 f"over {sum(r['alignment']['count'] for r in rows)} linked lane ends")
    ok = [r for r in rows if r["netconvert"]["ok"]]
    net_gap = max((r["netconvert"]["net_alignment_max"] for r in ok), default=0.0)
    lines.append(f"netconvert import: {len(ok)}/{n} succeeded; its lane-end gaps at most "
                 f"{net_gap * 1e3:.3f} mm")
    compared = [r for r in ok if "hd_road_nodes" in r]
    if compared:
        node_dev = max(abs(r["netconvert"]["road_nodes"] - r["hd_road_nodes"])
                       / max(r["hd_road_nodes"], 1) for r in compared)
        reach_dev = max(abs(r["netconvert"]["lane_reachability"] - r["hd_lane_reachability"])
                        for r in compared)
        lines.append(f"road nodes net vs HD map: max deviation {node_dev:.2%} "
                     f"({'within' if node_dev <= 0.02 else 'OUTSIDE'} 2 %); lane reachability: "
                     f"max |net - HD map| {reach_dev:.4f}")
    return lines


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("files", nargs="*", type=Path, help=".xodr files (default: a sweep)")
    ap.add_argument("--qc-python", default=os.environ.get("ROADWEAVER_QC_PYTHON"),
                    help="python of the venv with asam-qc-opendrive ($ROADWEAVER_QC_PYTHON)")
    ap.add_argument("--densities", default="10,20,30,40,60")
    ap.add_argument("--seeds", default="0-4")
    ap.add_argument("--size", type=float, default=2000.0)
    ap.add_argument("--style", default="mixed")
    ap.add_argument("--json", type=Path, help="write the rows as JSON here")
    args = ap.parse_args()
    if not args.qc_python:
        print("no --qc-python / ROADWEAVER_QC_PYTHON: XSD and ASAM checks skipped", file=sys.stderr)
    rows = []
    print(HEADER, flush=True)
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        if args.files:
            jobs = [lambda f=f: check_file(f, args.qc_python, work) for f in args.files]
        else:
            jobs = [lambda d=d, s=s: sweep_row(d, s, args, work)
                    for d in (float(x) for x in args.densities.split(","))
                    for s in seeds_arg(args.seeds)]
        for job in jobs:
            rows.append(job())
            print(format_row(rows[-1]), flush=True)
    print("\n".join(totals(rows)))
    if args.json:
        args.json.write_text(json.dumps(rows, indent=2))


if __name__ == "__main__":
    main()
