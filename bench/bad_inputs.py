"""Run 110 bad inputs through the real command line, each in a subprocess, and count tracebacks,
exit codes, one-line errors and slow refusals.

Every case is a mistake a user can make (a value out of range, a wrong file, a damaged folder);
the contract is exit code 2, one line on stderr starting ``roadweaver-sumo: error:``, no
traceback, and a refusal within seconds (bad input is checked before any work starts). The
fixtures (a small scenario, an OSM town, a prepared dataset) are built first, in a temporary
folder that is also each case's working directory.

Usage: ``python bench/bad_inputs.py [--timeout 60] [--show-all]``
"""

from __future__ import annotations

import argparse
import math
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from collections import Counter
from pathlib import Path

CLI = str(Path(sys.executable).with_name("roadweaver-sumo"))
PREFIX = "roadweaver-sumo: error:"
SLOW_S = 5.0
M_PER_DEG = 6_371_008.8 * math.pi / 180


def town_osm(path: Path) -> None:
    """A 6 x 6 grid of residential streets 100 m apart, as OpenStreetMap XML."""
    lines = ['<?xml version="1.0"?>', '<osm version="0.6" generator="bench">']
    for i in range(6):
        for j in range(6):
            lat = 48.0 + 100.0 * j / M_PER_DEG
            lon = 11.0 + 100.0 * i / (M_PER_DEG * math.cos(math.radians(48.0)))
            lines.append(f'<node id="{10 * i + j + 1}" lat="{lat:.8f}" lon="{lon:.8f}" '
                         'version="1"/>')
    way = 1
    for k in range(6):
        for refs in ([10 * i + k + 1 for i in range(6)], [10 * k + j + 1 for j in range(6)]):
            nds = "".join(f'<nd ref="{r}"/>' for r in refs)
            lines.append(f'<way id="{way}" version="1">{nds}'
                         '<tag k="highway" v="residential"/></way>')
            way += 1
    lines.append("</osm>")
    path.write_text("\n".join(lines))


def fixtures(root: Path) -> dict[str, str]:
    """Files and folders the cases refer to, by name."""
    f = {k: str(root / k) for k in ("scn", "osm", "ds", "a-file", "a-dir", "empty-dir")}
    (root / "a-file").write_text("not a folder\n")
    (root / "a-dir").mkdir()
    (root / "empty-dir").mkdir()
    town_osm(root / "town.osm")
    f["town"] = str(root / "town.osm")
    (root / "broken.osm").write_text("<osm><node id=")
    f["broken"] = str(root / "broken.osm")
    (root / "roads.txt").write_text("not osm")
    f["txt"] = str(root / "roads.txt")
    subprocess.run([CLI, "make-scenario", "--size", "1000", "--density", "20", "--vehicles",
                    "30", "--duration", "600", "--out", f["scn"]], check=True,
                   capture_output=True)
    f["net"] = str(root / "scn" / "map.net.xml")
    f["cfg"] = str(root / "scn" / "scenario.sumocfg")
    for name, report in (("corrupt-report", '{"generation": '), ("number-report", "123")):
        shutil.copytree(f["scn"], root / name)
        (root / name / "report.json").write_text(report)
        f[name] = str(root / name)
    shutil.copytree(f["scn"], root / "no-net")
    (root / "no-net" / "map.net.xml").unlink()
    f["no-net"] = str(root / "no-net")
    shutil.copytree(f["scn"], root / "bad-cfg")
    (root / "bad-cfg" / "scenario.sumocfg").write_text("<configuration><input")
    f["bad-cfg"] = str(root / "bad-cfg")
    (root / "empty.net.xml").write_text("")
    f["empty-net"] = str(root / "empty.net.xml")
    (root / "suite-bad").mkdir()
    (root / "suite-bad" / "manifest.json").write_text("{not json")
    f["suite-bad"] = str(root / "suite-bad")
    subprocess.run([CLI, "data", "prepare", "--osm", f["town"], "--out", f["ds"],
                    "--tile", "300", "--size", "32"], check=True, capture_output=True)
    return f


def cases(f: dict[str, str]) -> list[list[str]]:
    """110 bad command lines."""
    make = ["make-scenario", "--size", "1000", "--density", "20", "--vehicles", "30",
            "--out", "new-scn"]

    def m(*change: str) -> list[str]:
        argv = list(make)
        for option, value in zip(change[::2], change[1::2]):
            if option in argv:
                argv[argv.index(option) + 1] = value
            else:
                argv += [option, value]
        return argv

    prep = ["data", "prepare", "--osm", f["town"], "--out", "new-ds", "--tile", "300",
            "--size", "32"]

    def p(*change: str) -> list[str]:
        argv = list(prep)
        for option, value in zip(change[::2], change[1::2]):
            argv[argv.index(option) + 1] = value
        return argv

    vq = ["train", "vqvae", "--data", f["ds"], "--out", "new.npz", "--steps", "1"]
    suite = ["make-suite", "--densities", "20", "--size", "1000", "--vehicles", "30",
             "--out", "new-suite"]
    return [
        # make-scenario: numbers out of range or not numbers
        *(m("--density", v) for v in ("0", "-3", "nan", "inf", "1e999", "abc", "401")),
        *(m("--vehicles", v) for v in ("0", "-1", "1000001", "2.5", "1e3")),
        *(m("--size", v) for v in ("0", "50", "60000", "big", "1000x", "nan", "inf", "1000x50")),
        *(m("--seed", v) for v in ("-5", "2147483648", "99999999999999999999")),
        m("--style", "wavy"), m("--skeleton", "magic"),
        *(m("--duration", v) for v in ("0", "nan", "inf", "1e12", "604801")),
        m("--density", "5", "--size", "500"),
        m("--out", f["a-file"]), m("--out", f["a-file"] + "/sub"), m("--out", f["scn"]),
        [*make, "--colour", "red"], ["make-scenario"], ["make-scenario", "--density", "20"],
        [*make, "--density"],
        # validate
        ["validate", "nowhere"], ["validate", f["a-file"]], ["validate", f["empty-dir"]],
        ["validate", f["corrupt-report"]], ["validate", f["number-report"]],
        ["validate", f["no-net"]], ["validate", f["bad-cfg"]], ["validate", "--json", "nowhere"],
        ["validate"],
        # evaluate
        ["evaluate", "nowhere.net.xml"], ["evaluate", f["town"]], ["evaluate", f["a-dir"]],
        ["evaluate", f["cfg"]], ["evaluate", f["empty-net"]],
        *(["evaluate", f["net"], "--area-km2", v] for v in ("inf", "0", "-1", "nan")),
        # data prepare
        *(p("--tile", v) for v in ("nan", "inf", "1", "0", "1e9")),
        *(p("--size", v) for v in ("100000", "4", "0")),
        *([*prep, "--seed", v] for v in ("-5", "2147483648")),
        p("--osm", "missing.osm"), p("--osm", f["a-dir"]), p("--osm", f["broken"]),
        p("--osm", f["txt"]), p("--out", f["a-file"]), p("--out", f["ds"]),
        ["data", "prepare", "--out", "new-ds"], ["data"],
        # train
        ["train"], ["train", "vqvae", "--data", "nowhere", "--out", "new.npz"],
        [*vq, "--out", f["a-dir"], "--force"], [*vq, "--out", f["a-file"]],
        [*vq, "--steps", "0"], [*vq, "--steps", "1e12"],
        [*vq, "--steps", "1000000000000"], [*vq, "--batch", "0"], [*vq, "--batch", "100000"],
        [*vq, "--lr", "0"], [*vq, "--lr", "nan"], [*vq, "--lr", "inf"],
        [*vq, "--seed", "-1"], [*vq, "--seed", "2147483648"],
        ["train", "maskgit", "--data", f["ds"], "--out", "new.npz"],
        ["train", "maskgit", "--data", f["ds"], "--vqvae", "missing.npz", "--out", "new.npz"],
        ["train", "distil", "--data", f["ds"], "--vqvae", f["town"], "--teacher", "missing.npz",
         "--out", "new.npz"],
        ["train", "vqvae", "--data", f["a-file"], "--out", "new.npz"],
        # make-suite
        [*suite, "--densities", ""], [*suite, "--seeds", "2147483648"],
        [*suite, "--duration", "1e12"], [*suite, "--workers", "0"],
        [*suite, "--engine", "spark"], [*suite, "--vehicles", "0"], [*suite, "--size", "1e999"],
        [*suite, "--out", f["a-file"]],
        # check-suite and render
        ["check-suite", "nowhere"], ["check-suite", f["suite-bad"]],
        ["check-suite", f["empty-dir"], "--workers", "-1"], ["check-suite", f["scn"]],
        ["render", "nowhere"], ["render", f["empty-dir"]], ["render", f["corrupt-report"]],
        # the command itself
        ["frobnicate"], [], ["--density", "20"],
    ]


def run_case(argv: list[str], cwd: Path, timeout: float) -> dict:
    start = time.monotonic()
    proc = subprocess.Popen([CLI, *argv], cwd=cwd, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, start_new_session=True)
    try:
        _, err = proc.communicate(timeout=timeout)
        code = proc.returncode
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)  # the case's whole session: it ran too long
        _, err = proc.communicate()
        code = "timeout"
    lines = [ln for ln in err.splitlines() if ln.strip()]
    return {
        "argv": argv, "code": code, "seconds": time.monotonic() - start,
        "traceback": "Traceback" in err,
        "one_line": len(lines) == 1 and lines[0].startswith(PREFIX),
        "message": lines[-1][:140] if lines else "",
    }


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--timeout", type=float, default=60.0, help="seconds per case")
    parser.add_argument("--show-all", action="store_true", help="print every case")
    args = parser.parse_args()
    root = Path(tempfile.mkdtemp(prefix="roadweaver-bad-inputs-"))
    try:
        f = fixtures(root)
        todo = cases(f)
        rows = []
        for argv in todo:
            work = root / "work"
            work.mkdir()
            rows.append(run_case(argv, work, args.timeout))
            shutil.rmtree(work)
            row = rows[-1]
            good = row["code"] == 2 and row["one_line"] and not row["traceback"]
            if args.show_all or not good or row["seconds"] > SLOW_S:
                print(f"{row['code']!s:>7} {row['seconds']:6.1f} s  "
                      f"{' '.join(a.replace(str(root) + os.sep, '') for a in argv)[:90]}\n"
                      f"{'':17}{row['message']}", flush=True)
    finally:
        shutil.rmtree(root, ignore_errors=True)
    codes = Counter(str(r["code"]) for r in rows)
    print(f"\n{len(rows)} bad inputs: {sum(r['traceback'] for r in rows)} tracebacks; exit codes "
          + ", ".join(f"{c}: {n}" for c, n in sorted(codes.items()))
          + f"; one-line errors {sum(r['one_line'] for r in rows)}; slower than {SLOW_S:g} s "
          f"{sum(r['seconds'] > SLOW_S for r in rows)}; longest {max(r['seconds'] for r in rows):.1f} s")
    return 0 if all(r["code"] == 2 and r["one_line"] and not r["traceback"] for r in rows) else 1


if __name__ == "__main__":
    sys.exit(main())
