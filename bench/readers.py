"""Scenario folders read by readers we did not write (issue 33's done-when): the ASAM
OpenDRIVE checker, CARLA's map code, pyxodr, esmini, shapely on the lanelet2 polygons and a
netconvert re-import of the ``.xodr``. None of them shares code with the generator, so each
sees the files as a user's tool would.

    python bench/readers.py DIR [DIR ...] [--qc-python PY] [--asam-every N] [--esmini-roads N]
                           [--cr-python PY] [--cr-every N] [--cr-roads N]

A DIR is a scenario folder (it holds ``map.xodr``) or a folder of them. Prints one JSON line
per folder as it goes (each reader's figures and ``problem``: null when it accepted the map),
then the totals and every problem. Needs no network. The ASAM checker runs in its own venv
(``--qc-python``, default ``$ROADWEAVER_QC_PYTHON`` or ``/tmp/qcvenv/bin/python``; skipped
with a note when absent); it is slow, so ``--asam-every N`` runs it on every N-th map. esmini
is slower still on big maps: ``--esmini-roads`` (default 5000) bounds the maps it reads.
CommonRoad's converter (commonroad-scenario-designer) pins packages that clash with ours: it
runs in a venv of its own (``--cr-python``, default ``$ROADWEAVER_CR_PYTHON`` or
``/tmp/rd/crvenv/bin/python``; skipped with a note when absent).
"""

from __future__ import annotations

import argparse
import json
import math
import multiprocessing
import os
import re
import subprocess
import sys
import tempfile
import time
from collections import Counter
from itertools import pairwise
from pathlib import Path

import networkx as nx
from check_opendrive import asam_check, xsd_check  # bench/ is sys.path[0] when run as a script
from lxml import etree
from shapely.geometry import Polygon
from shapely.validation import explain_validity

from roadweaver_sumo.sumo_tools import binary, child_env

ESMINI = Path(__file__).resolve().parents[2] / "shared" / "tools" / "esmini"
END = 0.01  # m: how far inside a lane its end waypoint is taken (as tests/test_carla.py)


def first_line(err: BaseException) -> str:
    """``Type: first line of the message``, the one-line form of a reader's failure."""
    lines = str(err).strip().splitlines()
    return f"{type(err).__name__}: {lines[0][:200] if lines else ''}"


def isolated(fn, *args):
    """``fn(*args)`` in a forked child, so that a reader that crashes (CARLA segfaults on
    some malformed files) fails alone instead of ending the benchmark."""
    ctx = multiprocessing.get_context("fork")
    recv, send = ctx.Pipe(duplex=False)

    def child() -> None:
        try:
            send.send((True, fn(*args)))
        except Exception as err:  # noqa: BLE001  (handed to the parent)
            send.send((False, first_line(err)))

    process = ctx.Process(target=child)
    process.start()
    send.close()
    try:
        ok, value = recv.recv()
    except EOFError:
        ok, value = False, None
    process.join()
    if not ok:
        raise ChildProcessError(value or f"crashed (exit code {process.exitcode})")
    return value


def sh(args: list[str], work: Path, **kw) -> tuple[int, str]:
    """Run a reader's program in ``work``: exit code and stdout + stderr."""
    proc = subprocess.run(args, cwd=work, capture_output=True, text=True, timeout=1800,
                          check=False, **kw)
    return proc.returncode, proc.stdout + proc.stderr


def asam(xodr: Path, qc_python: str, work: Path) -> dict:
    """XSD validity and the ASAM checker's issues (``bench/check_opendrive.py``): the
    checker's semantic rules only run on XSD-valid files, so both are reported."""
    found = {"xsd_valid": xsd_check(xodr, qc_python)["valid"], **asam_check(xodr, qc_python, work)}
    bad = not found["xsd_valid"] or found["errors"] or found["warnings"]
    return {**found, "problem": f"XSD valid {found['xsd_valid']}, {found['by_checker']}"
            if bad else None}


def carla_topology(xodr: Path) -> dict:
    """CARLA's lane graph: ``get_topology()`` plus lane changes both ways between
    neighbouring driving lanes of one road section that drive the same way (lane ids of one
    sign; road marks are not consulted), as tests/test_carla.py builds it. Reports strong
    connectivity, the share of ordered lane pairs and of ordered junction pairs (some lane of
    the first junction reaches some lane of the second) that are connected, and the road lane
    ends our file links onward where ``next()`` finds nothing (a car would stop there)."""
    import carla  # an optional reader: only this check fails without it

    text = xodr.read_text()
    m = carla.Map(xodr.parent.name, text)
    graph, junction_of = nx.DiGraph(), {}
    key = lambda w: (w.road_id, w.section_id, w.lane_id)
    for a, b in m.get_topology():
        graph.add_edge(key(a), key(b))
        junction_of.update({key(w): w.get_junction().id for w in (a, b) if w.is_junction})
    for road, section, lane in list(graph.nodes):
        beside = (road, section, lane + (1 if lane > 0 else -1))
        if beside in graph:
            graph.add_edge((road, section, lane), beside)
            graph.add_edge(beside, (road, section, lane))
    sccs = list(nx.strongly_connected_components(graph))
    dag = nx.condensation(graph, sccs)  # reachability over components, not lane by lane
    reach = {c: nx.descendants(dag, c) | {c} for c in dag.nodes}
    n = graph.number_of_nodes()
    pairs = sum(len(sccs[c]) * sum(len(sccs[d]) for d in reach[c]) for c in dag.nodes) - n
    junctions: dict[int, set] = {}
    for lane, j in junction_of.items():
        junctions.setdefault(j, set()).add(dag.graph["mapping"][lane])
    j_reach = {j: set().union(*(reach[c] for c in cs)) for j, cs in junctions.items()}
    nj = len(junctions)
    j_pairs = sum(bool(j_reach[a] & junctions[b]) for a in junctions for b in junctions if a != b)
    dead = unlinked = 0
    for road in etree.fromstring(text.encode()).iter("road"):
        if road.get("junction") != "-1":
            continue
        sections = road.findall("lanes/laneSection")
        for lane in (*sections[-1].iterfind("right/lane"), *sections[0].iterfind("left/lane")):
            lane_id = int(lane.get("id"))
            if lane.get("type") != "driving":
                continue
            if road.find("link/successor" if lane_id < 0 else "link/predecessor") is None:
                unlinked += 1
                continue
            s = float(road.get("length")) - END if lane_id < 0 else END
            end = m.get_waypoint_xodr(int(road.get("id")), lane_id, s)
            dead += end is None or not end.next(2 * END)
    found = {"lanes": n, "strongly_connected": len(sccs) == 1,
             "lane_reachability": pairs / (n * (n - 1)) if n > 1 else None, "junctions": nj,
             "junction_reachability": j_pairs / (nj * (nj - 1)) if nj > 1 else None,
             "dead_lane_ends": dead, "unlinked_lane_ends": unlinked}
    bad = len(sccs) != 1 or dead or unlinked or nj < 2
    return {**found, "problem": f"{len(sccs)} components, lane reachability "
            f"{found['lane_reachability'] or 0:.4f}, {nj} junctions, {dead} dead lane ends, "
            f"{unlinked} unlinked" if bad else None}


def pyxodr_load(xodr: Path) -> dict:
    """pyxodr builds every lane's centre line (it raises on arcs it cannot follow)."""
    from pyxodr.road_objects.network import RoadNetwork  # optional, as carla

    lanes = sum(len(lane.centre_line) >= 2 for road in RoadNetwork(str(xodr)).get_roads()
                for section in road.lane_sections for lane in section.lanes)
    return {"lanes": lanes, "problem": None}


def esmini_log(rc: int, out: str, work: Path) -> dict:
    """esmini's complaints: ``[error]``/``[warn]`` lines of its output and ``log.txt``, less
    the geoReference one (``+no_defs``) and the resource files (3D car models, traffic sign
    tables) that this headless build lacks ('not located')."""
    log = work / "log.txt"
    out += log.read_text(errors="replace") if log.exists() else ""
    lines = [ln.strip() for ln in out.splitlines()
             if "Unsupported geo reference" not in ln and "not located" not in ln]
    errors = [ln for ln in lines if re.search(r"\[(error|warn)\]", ln)]
    ends = sum("end of road" in ln.lower() for ln in lines)
    return {"rc": rc, "errors": len(errors), "end_of_road": ends,
            "problem": f"exit {rc}, {ends} end of road, {errors[:1]}"
            if rc or errors or ends else None}


def esmini_odrplot(xodr: Path, work: Path) -> dict:
    """``odrplot`` samples every lane of the map into ``track.csv``."""
    found = esmini_log(*sh([str(ESMINI / "odrplot"), str(xodr.resolve())], work), work)
    track = work / "track.csv"
    blocks = sum(ln.startswith("lane,") for ln in track.open()) if track.exists() else 0
    return {**found, "lane_blocks": blocks,
            "problem": found["problem"] or (None if blocks else "empty track.csv")}


XOSC = """<?xml version="1.0" encoding="UTF-8"?>
<OpenSCENARIO><FileHeader revMajor="1" revMinor="1" date="2025-01-01T00:00:00" description=""
 author="bench/readers.py"/><ParameterDeclarations/><CatalogLocations/>
<RoadNetwork><LogicFile filepath="{xodr}"/></RoadNetwork><Entities>{entities}</Entities>
<Storyboard><Init><Actions>{inits}</Actions></Init><StopTrigger><ConditionGroup><Condition
 name="end" delay="0" conditionEdge="rising"><ByValueCondition><SimulationTimeCondition
 value="{seconds}" rule="greaterThan"/></ByValueCondition></Condition></ConditionGroup>
</StopTrigger></Storyboard></OpenSCENARIO>"""
CAR = """<ScenarioObject name="{name}"><Vehicle name="car" vehicleCategory="car">
<ParameterDeclarations/><Performance maxSpeed="50" maxAcceleration="5" maxDeceleration="10"/>
<BoundingBox><Center x="1.4" y="0" z="0.75"/><Dimensions width="1.8" length="4.5" height="1.5"/>
</BoundingBox><Axles><FrontAxle maxSteering="0.5" wheelDiameter="0.6" trackWidth="1.6"
 positionX="2.8" positionZ="0.3"/><RearAxle maxSteering="0" wheelDiameter="0.6" trackWidth="1.6"
 positionX="0" positionZ="0.3"/></Axles><Properties/></Vehicle></ScenarioObject>"""
INIT = """<Private entityRef="{name}"><PrivateAction><TeleportAction><Position><LanePosition
 roadId="{road}" laneId="{lane}" s="{s}" offset="0"/></Position></TeleportAction></PrivateAction>
<PrivateAction><LongitudinalAction><SpeedAction><SpeedActionDynamics dynamicsShape="step"
 value="0" dynamicsDimension="time"/><SpeedActionTarget><AbsoluteTargetSpeed value="{speed}"/>
</SpeedActionTarget></SpeedAction></LongitudinalAction></PrivateAction></Private>"""


def esmini_run(xodr: Path, work: Path, cars: int = 8, seconds: float = 60.0,
               speed: float = 10.0) -> dict:
    """A headless OpenSCENARIO run: a car at ``speed`` 20 m before the end of the first
    right-hand driving lane of each of the ``cars`` longest roads outside junctions. esmini's
    default controller follows lanes through junctions (a random way, seeded) and stops
    silently at a lane without successor, so a broken link shows as a car that covered less
    than 90 % of ``speed * seconds`` (``min_path``, summed from ``--csv_logger`` positions)."""
    roads = [r for r in etree.parse(str(xodr)).getroot().iter("road") if r.get("junction") == "-1"]
    starts = []  # (name, road, lane, s)
    for road in sorted(roads, key=lambda r: -float(r.get("length")))[:cars]:
        lanes = [int(ln.get("id")) for ln in road.iterfind("lanes/laneSection/right/lane")
                 if ln.get("type") == "driving"]
        s = max(1.0, float(road.get("length")) - 20.0)
        starts += [(f"car{len(starts)}", road.get("id"), max(lanes), s)] if lanes else []
    (work / "run.xosc").write_text(XOSC.format(
        xodr=xodr.resolve(), seconds=seconds, entities="".join(CAR.format(name=c[0])
                                                               for c in starts),
        inits="".join(INIT.format(name=n, road=r, lane=ln, s=s, speed=speed)
                      for n, r, ln, s in starts)))
    found = esmini_log(*sh([str(ESMINI / "esmini"), "--headless", "--osc", "run.xosc", "--seed",
                            "1", "--fixed_timestep", "0.05", "--csv_logger", "run.csv"], work),
                       work)
    paths = [0.0] * len(starts)
    if (work / "run.csv").exists():
        lines = (work / "run.csv").read_text().splitlines()
        head = next(i for i, ln in enumerate(lines) if ln.startswith("Index"))
        rows = [ln.split(",") for ln in lines[head + 1:]]
        for k in range(len(starts)):  # columns: index, time, then 31 per car with x, y at 11, 12
            xy = [(float(r[2 + 31 * k + 11]), float(r[2 + 31 * k + 12])) for r in rows]
            paths[k] = sum(math.dist(p, q) for p, q in pairwise(xy))
    least = round(min(paths, default=0.0), 1)
    short = least < 0.9 * speed * seconds and f"a car drove {least} m of {speed * seconds:g}"
    return {**found, "cars": len(starts), "min_path": least,
            "problem": found["problem"] or short or None}


def lanelet_polygons(osm: Path) -> dict:
    """Lanelets whose outline (left bound, then the right bound reversed) is not a valid
    polygon per shapely: self-intersecting, as CommonRoad's converter reports them. Nodes are
    projected equirectangularly around the bounds' corner (maps are at most ~10 km)."""
    root = etree.parse(str(osm)).getroot()
    lat0, lon0 = (float(root.find("bounds").get(k)) for k in ("minlat", "minlon"))
    ky = 6371008.8 * math.pi / 180
    kx = ky * math.cos(math.radians(lat0))
    xy = {n.get("id"): ((float(n.get("lon")) - lon0) * kx, (float(n.get("lat")) - lat0) * ky)
          for n in root.iterfind("node")}
    ways = {w.get("id"): [xy[nd.get("ref")] for nd in w.iterfind("nd")]
            for w in root.iterfind("way")}
    total, bad, reasons = 0, [], Counter()
    for rel in root.iterfind("relation"):
        if rel.find("tag[@k='type'][@v='lanelet']") is None:
            continue
        total += 1
        role = {m.get("role"): ways[m.get("ref")] for m in rel.iterfind("member[@type='way']")}
        polygon = Polygon(role["left"] + role["right"][::-1])
        if not polygon.is_valid:
            tag = rel.find("tag[@k='roadweaver:lane']")
            bad.append(tag.get("v") if tag is not None else rel.get("id"))
            reasons[explain_validity(polygon).split("[")[0]] += 1
    return {"lanelets": total, "invalid": len(bad), "reasons": dict(reasons),
            "problem": f"{len(bad)} invalid polygons: {bad[:5]}" if bad else None}


#: run in the CommonRoad venv: map.xodr through commonroad-scenario-designer's converter, then
#: each lanelet's polygon checked by shapely; prints one JSON line
COMMONROAD_SCRIPT = """
import json, sys
from crdesigner.map_conversion.map_conversion_interface import opendrive_to_commonroad
lanelets = opendrive_to_commonroad(sys.argv[1]).lanelet_network.lanelets
bad = [l for l in lanelets if not l.polygon.shapely_object.is_valid]
print(json.dumps({"lanelets": len(lanelets), "invalid": len(bad),
                  "invalid_lengths": sorted(round(float(l.distance[-1]), 1) for l in bad)}))
"""


def commonroad(xodr: Path, cr_python: str, work: Path) -> dict:
    """commonroad-scenario-designer's OpenDRIVE conversion (in its own venv, ``cr_python``:
    its pins clash with ours): lanelets whose polygon self-intersects, and their lengths
    (7-10 m: U-turns at dead ends; longer: a road's lanes)."""
    rc, out = sh([cr_python, "-c", COMMONROAD_SCRIPT, str(xodr.resolve())], work)
    lines = [ln for ln in out.splitlines() if ln.startswith("{")]
    if rc or not lines:
        return {"failed": True, "problem": f"exit {rc}: {out.strip().splitlines()[-1:]}"}
    found = json.loads(lines[-1])
    return {**found, "problem": f"{found['invalid']} self-intersecting lanelets, lengths "
                                f"{found['invalid_lengths'][:8]}" if found["invalid"] else None}


def netconvert_reimport(xodr: Path, work: Path) -> dict:
    """``netconvert --opendrive-files``: a sharp-turn warning means it read a road end as a
    turn tighter than ~9 m radius. Warnings are counted by kind (ids and numbers blanked;
    each one, not netconvert's default summary after 5 of a kind)."""
    rc, out = sh([binary("netconvert"), "--opendrive-files", str(xodr.resolve()),
                  "-o", "reimport.net.xml", "--aggregate-warnings", "-1"], work, env=child_env())
    kinds = Counter(re.sub(r"-?\d+(\.\d+)?", "N", re.sub(r"'[^']*'", "'*'", ln[9:]))
                    for ln in out.splitlines() if ln.startswith("Warning: "))
    errors = [ln for ln in out.splitlines() if ln.startswith("Error:")]
    sharp = [ln[9:] for ln in out.splitlines() if "sharp turn" in ln]  # radius, edge = road
    return {"rc": rc, "warnings": dict(kinds), "sharp_turns": len(sharp),
            "problem": f"exit {rc}, {len(sharp)} sharp turns {sharp[:2]} {errors[:1]}"
            if rc or sharp else None}


def check_folder(folder: Path, qc_python: str | None, esmini_roads: int,
                 cr_python: str | None = None, cr_roads: int = 2000) -> dict:
    """Every reader on one scenario folder, each in a fresh temp dir; a reader that raises
    is recorded as failed, with the first line of its error as the problem. esmini is left
    out of maps with more than ``esmini_roads`` roads: it looks roads up by id with a linear
    scan, so its load time grows with the square of the road count (4700 roads: 90 s, 9300
    roads: 340-510 s here)."""
    xodr = folder / "map.xodr"
    roads = xodr.read_text().count("<road ")
    readers = {"asam": lambda w: asam(xodr, qc_python, w),
               "carla": lambda w: isolated(carla_topology, xodr),
               "pyxodr": lambda w: isolated(pyxodr_load, xodr),
               "odrplot": lambda w: esmini_odrplot(xodr, w),
               "esmini": lambda w: esmini_run(xodr, w),
               "lanelets": lambda w: lanelet_polygons(folder / "lanelet2_map.osm"),
               "netconvert": lambda w: netconvert_reimport(xodr, w),
               "commonroad": lambda w: commonroad(xodr, cr_python, w)}
    row: dict = {"map": folder.name}
    for name, reader in readers.items():
        if (name == "asam" and not qc_python) or (name == "commonroad" and not cr_python):
            continue
        if (name in ("odrplot", "esmini") and roads > esmini_roads) or (
                name == "commonroad" and roads > cr_roads):
            row[name] = {"skipped": f"{roads} roads", "problem": None, "seconds": 0.0}
            continue
        start = time.perf_counter()
        with tempfile.TemporaryDirectory(prefix="readers-") as tmp:
            try:
                row[name] = reader(Path(tmp))
            except ChildProcessError as err:  # already one line, from the child
                row[name] = {"failed": True, "problem": str(err)}
            except Exception as err:  # noqa: BLE001  (any reader's failure is a finding)
                row[name] = {"failed": True, "problem": first_line(err)}
        row[name]["seconds"] = round(time.perf_counter() - start, 2)
    return row


def summed(results: list[dict], *keys: str) -> str:
    """``key total`` for each key, over one reader's results."""
    return ", ".join(f"{k.replace('_', ' ')} {sum(r[k] for r in results)}" for k in keys)


def spread(results: list[dict], key: str) -> str:
    """``key min..max`` over one reader's results that have a value."""
    values = [r[key] for r in results if r[key] is not None]
    return f"{key.replace('_', ' ')} {min(values):.4f}..{max(values):.4f}" if values else ""


def kinds(results: list[dict], key: str) -> str:
    """The counters under ``key`` added up."""
    return str(dict(sum((Counter(r[key]) for r in results), Counter())))


SUMMARY = {  # reader -> its figures over the maps it read
    "asam": lambda ok: f"{summed(ok, 'xsd_valid', 'errors', 'warnings')} {kinds(ok, 'by_checker')}"
                       f", not completed {sorted({c for r in ok for c in r['not_completed']})}",
    "carla": lambda ok: ", ".join([summed(ok, "strongly_connected"),
                                   spread(ok, "lane_reachability"),
                                   spread(ok, "junction_reachability"),
                                   summed(ok, "dead_lane_ends", "unlinked_lane_ends")]),
    "pyxodr": lambda ok: summed(ok, "lanes"),
    "odrplot": lambda ok: summed(ok, "errors", "end_of_road"),
    "esmini": lambda ok: f"{summed(ok, 'errors', 'end_of_road')}, shortest car path "
                         f"{min(r['min_path'] for r in ok)} m",
    "lanelets": lambda ok: summed(ok, "invalid", "lanelets"),
    "netconvert": lambda ok: f"{summed(ok, 'sharp_turns')}, warnings {kinds(ok, 'warnings')}",
    "commonroad": lambda ok: summed(ok, "invalid", "lanelets"),
}


def totals(rows: list[dict]) -> list[str]:
    """Per reader: maps accepted and its figures over the maps, then every problem."""
    lines, problems = [f"maps {len(rows)}"], []
    for name, summary in SUMMARY.items():
        done = [r[name] for r in rows if name in r]
        problems += [f"  {r['map']} {name}: {r[name]['problem']}" for r in rows
                     if r.get(name, {}).get("problem")]
        ok = [r for r in done if "failed" not in r and "skipped" not in r]
        skipped = len(done) - len([r for r in done if "skipped" not in r])
        lines.append(f"{name}: accepted {sum(not r['problem'] for r in done) - skipped}/"
                     f"{len(done) - skipped}" + (f" ({skipped} skipped)" if skipped else "")
                     + (f", {summary(ok)}" if ok else "")
                     + f" ({sum(r['seconds'] for r in done):.0f} s)")
    return [*lines, "problems:" if problems else "problems: none", *problems]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("dirs", nargs="+", type=Path, help="scenario folders or folders of them")
    ap.add_argument("--qc-python", default=os.environ.get("ROADWEAVER_QC_PYTHON",
                                                          "/tmp/qcvenv/bin/python"))
    ap.add_argument("--asam-every", type=int, default=1, help="ASAM check on every N-th map")
    ap.add_argument("--cr-python", default=os.environ.get("ROADWEAVER_CR_PYTHON",
                                                          "/tmp/rd/crvenv/bin/python"),
                    help="python of a venv with commonroad-scenario-designer")
    ap.add_argument("--cr-every", type=int, default=1,
                    help="CommonRoad conversion on every N-th map (a 1 km map takes ~30 s)")
    ap.add_argument("--cr-roads", type=int, default=2000,
                    help="leave CommonRoad out of maps with more roads (2.5 km: over 5 min)")
    ap.add_argument("--esmini-roads", type=int, default=5000,
                    help="leave esmini out of maps with more roads (its load is quadratic)")
    args = ap.parse_args()
    qc = args.qc_python if Path(args.qc_python).exists() else None
    if not qc:
        print(f"note: no {args.qc_python}: XSD and ASAM checks skipped", file=sys.stderr)
    cr = args.cr_python if Path(args.cr_python).exists() else None
    if not cr:
        print(f"note: no {args.cr_python}: CommonRoad conversion skipped", file=sys.stderr)
    folders = sorted({p.parent for d in args.dirs for p in [d / "map.xodr", *d.rglob("*/map.xodr")]
                      if p.exists()})
    rows = []
    for index, folder in enumerate(folders):
        asam_now = index % max(args.asam_every, 1) == 0
        cr_now = index % max(args.cr_every, 1) == 0
        rows.append(check_folder(folder, qc if asam_now else None, args.esmini_roads,
                                 cr if cr_now else None, args.cr_roads))
        print(json.dumps(rows[-1]), flush=True)
    print("\n".join(totals(rows)), flush=True)


if __name__ == "__main__":
    main()
