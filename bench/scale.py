"""Scale and speed (issue 5): stage times, peak memory, netgenerate at the same node count, and
quality side by side with netgenerate rand / grid / spider and a real OSM import.

Usage: python bench/scale.py [--sizes 2000,4000,10000] [--repeats 5,3,3] [--density 30]
                             [--skeleton procedural] [--osm FILE] [--json FILE]

Every generation runs in its own process. Its peak memory is the larger of its own ru_maxrss and
the sampled sum of proportional set sizes over it and its children (the forked map writers,
netconvert, duarouter), sampled in one more run of seed 0 whose times are not used: sampling
ten times a second takes a share of a core, and the timed runs (ours and netgenerate's) are
not sampled;
netgenerate --rand gets the iterations that give it our road-node count as ``evaluate``
counts them (one untimed calibration run per size);
"generation" is skeleton + expansion + hdmap + export + formats (our files written: the plain
XML, and OpenDRIVE and lanelet2 after netconvert), "total" adds netconvert and demand. Validation is not timed. Quality figures all come from ``evaluate``.
CPU contention (a training job, the load average) is recorded, since it inflates every time.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

STAGES = ("skeleton", "expansion", "hdmap", "export", "netconvert", "formats", "demand")
GENERATION = ("skeleton", "expansion", "hdmap", "export", "formats")
QUALITY = ("road_nodes", "density", "lcc_ratio", "dead_end_ratio", "cycle_ratio",
           "crossings_without_junction", "sharp_bends", "bearing_entropy", "orientation_order",
           "lane_reachability", "junction_reachability")
DEFAULT_OSM = Path("/work/shared/data/osm/bad-hersfeld-de.osm.gz")
#: netgenerate --rand: road nodes (``evaluate``) per iteration, a first guess; each size's
#: count is then matched to ours by one calibration run (:func:`rand_iterations`). (3,479
#: iterations give 3,109 road nodes, 140 give 129.)
RAND_NODES_PER_ITERATION = 0.89


def child(size: float, density: float, seed: int, skeleton: str, folder: Path) -> None:
    """One generation in this process: print stage times, peak RSS and road nodes as JSON."""
    from roadweaver_sumo.pipeline import build_scenario_files
    from roadweaver_sumo.spec import ScenarioSpec

    spec = ScenarioSpec(density=density, vehicles=500, width=size, height=size, seed=seed,
                        skeleton=skeleton)
    stages: dict[str, float] = {}
    generation = build_scenario_files(spec, folder, stages, lambda msg: None)
    peak_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(json.dumps({"stages": stages, "peak_self_mb": peak_mb,
                      "road_nodes": generation["road_graph"]["road_nodes"]}))


class TreePeak(threading.Thread):
    """Peak of the summed memory of process ``root`` and all its descendants (the forked map
    writers, netconvert, duarouter), sampled every 0.1 s from this process so the measured
    one is not slowed. Each process counts its proportional set size (PSS): a page a forked
    writer still shares with its parent counts half in each, so the sum is the memory the
    tree really holds (resident sizes would count every shared page twice)."""

    def __init__(self, root: int) -> None:
        super().__init__(daemon=True)
        self.root, self.peak_mb, self._done = root, 0.0, threading.Event()

    def run(self) -> None:
        while not self._done.wait(0.1):
            self.peak_mb = max(self.peak_mb, sum(_pss_mb(p) for p in _descendants(self.root)))

    def stop(self) -> None:
        self._done.set()
        self.join()


def _descendants(root: int) -> list[int]:
    parent = {}
    for entry in os.listdir("/proc"):
        if entry.isdigit():
            try:
                stat = Path(f"/proc/{entry}/stat").read_text()
                parent[int(entry)] = int(stat.rsplit(")", 1)[1].split()[1])
            except (OSError, IndexError, ValueError):
                continue
    found, frontier = [root], [root]
    while frontier:
        frontier = [pid for pid, ppid in parent.items() if ppid in frontier]
        found += frontier
    return found


def _pss_mb(pid: int) -> float:
    """Proportional set size (``/proc/PID/smaps_rollup``, Linux 4.14+); resident size where
    that file is missing."""
    try:
        for line in Path(f"/proc/{pid}/smaps_rollup").read_text().splitlines():
            if line.startswith("Pss:"):
                return int(line.split()[1]) / 1024
    except OSError:
        pass
    try:
        for line in Path(f"/proc/{pid}/status").read_text().splitlines():
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024
    except OSError:
        pass
    return 0.0


def run_child(size: float, density: float, seed: int, skeleton: str, folder: Path,
              sample_memory: bool = False) -> dict:
    """One generation in a child process; with ``sample_memory``, its process tree's memory is
    sampled meanwhile (:class:`TreePeak`), which slows it: its times are not for the table.
    (A learned 10 km map, seed 1, four alternating rounds: median 6.81 s sampled, 5.57 s not.)"""
    proc = subprocess.Popen([sys.executable, __file__, "--child", f"{size},{density},{seed}",
                             "--skeleton", skeleton, "--folder", str(folder)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)  # fmt: skip
    tree = TreePeak(proc.pid)
    if sample_memory:
        tree.start()
    out, err = proc.communicate()
    if sample_memory:
        tree.stop()
    if proc.returncode:
        raise subprocess.CalledProcessError(proc.returncode, proc.args, out, err)
    result = json.loads(out.strip().splitlines()[-1])
    result["peak_mb"] = max(result["peak_self_mb"], tree.peak_mb)
    return result


def contention() -> dict:
    """What else competes for the CPU: a running training job and the 1-minute load."""
    train = subprocess.run(["pgrep", "-f", "train "], capture_output=True, text=True,
                           check=False).stdout
    return {"training_running": bool(train.strip()), "load_1min": os.getloadavg()[0],
            "cpus": os.cpu_count()}


def sumo_binary(name: str) -> str:
    from roadweaver_sumo.sumo_tools import binary

    return binary(name)


def rand_iterations(road_nodes: int, out: Path) -> tuple[int, int]:
    """The ``--rand.iterations`` that give about ``road_nodes`` road nodes, as ``evaluate``
    counts them (netgenerate's own node count includes the nodes inside roads), and the
    count they gave: one untimed run at the first guess, scaled once by what it gave."""
    from roadweaver_sumo.validate.evaluate import evaluate_net

    guess = max(1, round(road_nodes / RAND_NODES_PER_ITERATION))
    netgenerate(["--rand", "--rand.iterations", str(guess)], out)
    got = evaluate_net(out)["road_nodes"]
    iterations = max(1, round(guess * road_nodes / max(got, 1)))
    netgenerate(["--rand", "--rand.iterations", str(iterations)], out)
    return iterations, evaluate_net(out)["road_nodes"]


def netgenerate(args: list[str], out: Path) -> float:
    """Run netgenerate; return its wall time (s)."""
    from roadweaver_sumo.sumo_tools import child_env

    start = time.perf_counter()
    subprocess.run([sumo_binary("netgenerate"), *args, "--seed", "1", "-o", str(out)],
                   env=child_env(), capture_output=True, check=True)  # fmt: skip
    return time.perf_counter() - start


def osm_import(osm: Path, folder: Path, side: float) -> Path:
    """The OSM file as a SUMO net (passenger roads), cut to a ``side`` square at its centre.
    ``.pbf`` is first converted with pyosmium (netconvert 1.28 cannot read it, NOTES.md)."""
    from roadweaver_sumo.sumo_tools import child_env

    if osm.suffix == ".pbf":
        import osmium

        xml = folder / "osm.osm"
        with osmium.SimpleWriter(str(xml)) as writer:
            for obj in osmium.FileProcessor(str(osm)):
                writer.add(obj)
        osm = xml
    options = ["--geometry.remove", "--junctions.join", "--tls.guess-signals",
               "--keep-edges.by-vclass", "passenger", "--remove-edges.isolated",
               "--no-turnarounds"]
    full = folder / "osm_full.net.xml"
    subprocess.run([sumo_binary("netconvert"), "--osm-files", str(osm), *options, "-o", str(full)],
                   env=child_env(), capture_output=True, check=True)  # fmt: skip
    from roadweaver_sumo.validate.netgraph import load_net

    x0, y0, x1, y1 = load_net(full).getBoundary()
    cx, cy, h = (x0 + x1) / 2, (y0 + y1) / 2, side / 2
    crop = folder / "osm.net.xml"
    subprocess.run([sumo_binary("netconvert"), "-s", str(full), "--keep-edges.in-boundary",
                    f"{cx - h},{cy - h},{cx + h},{cy + h}", "--remove-edges.isolated",
                    "-o", str(crop)], env=child_env(), capture_output=True, check=True)
    return crop


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", default="2000,4000,10000")
    ap.add_argument("--repeats", default="5,3,3",
                    help="runs per size (seeds 0..n-1), each followed by a netgenerate run")
    ap.add_argument("--density", type=float, default=30.0)
    ap.add_argument("--skeleton", default="procedural")
    ap.add_argument("--osm", type=Path, default=DEFAULT_OSM, help="OSM file for the real import")
    ap.add_argument("--json", type=Path, default=Path("bench/results/scale.json"))
    ap.add_argument("--child", help=argparse.SUPPRESS)
    ap.add_argument("--folder", type=Path, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        size, density, seed = args.child.split(",")
        child(float(size), float(density), int(seed), args.skeleton, args.folder)
        return
    with tempfile.TemporaryDirectory(prefix="rw-scale-") as work:  # 10 km maps: ~0.5 GB
        measure(args, Path(work))


def measure(args, work: Path) -> None:
    """Time every size, then compare quality at the first size; print a table, write JSON."""
    sizes = [float(s) for s in args.sizes.split(",")]
    repeats = [int(r) for r in args.repeats.split(",")]
    results = {"contention_before": contention(), "skeleton": args.skeleton,
               "density": args.density, "sizes": {}}
    print(f"contention: {results['contention_before']}")
    print("size_m " + " ".join(f"{s:>10s}" for s in STAGES)
          + "  generation  total  gen/km2  peak_MB  nodes  rand_nodes  netgenerate  ratio")
    for size, n in zip(sizes, repeats, strict=True):
        # Each of our runs is followed by a netgenerate run, so that a machine that slows down
        # during the bench slows both; the ratio is of the two medians.
        runs, rand_runs = [], []
        for seed in range(n):
            runs.append(run_child(size, args.density, seed, args.skeleton,
                                  work / f"ours-{size:.0f}-{seed}"))
            if seed == 0:
                iterations, rand_nodes = rand_iterations(runs[0]["road_nodes"],
                                                         work / f"rand-{size:.0f}.net.xml")
            rand_runs.append(netgenerate(["--rand", "--rand.iterations", str(iterations)],
                                         work / f"rand-{size:.0f}.net.xml"))
        memory = run_child(size, args.density, 0, args.skeleton, work / f"memory-{size:.0f}",
                           sample_memory=True)
        med = {s: statistics.median(r["stages"][s] for r in runs) for s in STAGES}
        gen = statistics.median(sum(r["stages"][s] for s in GENERATION) for r in runs)
        total = statistics.median(sum(r["stages"].values()) for r in runs)
        nodes = runs[0]["road_nodes"]
        rand_s = statistics.median(rand_runs)
        area = size * size / 1e6
        entry = {"median_s": med, "generation_s": gen, "total_s": total,
                 "generation_per_km2_s": gen / area, "peak_mb": max(memory["peak_mb"], *(r["peak_mb"] for r in runs)),
                 "road_nodes": nodes, "runs": runs, "netgenerate_rand_s": rand_s,
                 "netgenerate_rand_runs_s": rand_runs,
                 "netgenerate_rand_iterations": iterations,
                 "netgenerate_rand_road_nodes": rand_nodes,
                 "netgenerate_over_generation": rand_s / gen}
        results["sizes"][f"{size:.0f}"] = entry
        print(f"{size:6.0f} " + " ".join(f"{med[s]:10.3f}" for s in STAGES)
              + f"  {gen:10.3f} {total:6.2f}  {gen / area:7.4f}  {entry['peak_mb']:7.0f}"
              f"  {nodes:5d}  {rand_nodes:10d}  {rand_s:10.2f}  {rand_s / gen:5.2f}x", flush=True)
    base = results["sizes"][f"{sizes[0]:.0f}"]["generation_per_km2_s"]
    for size in sizes[1:]:
        ratio = results["sizes"][f"{size:.0f}"]["generation_per_km2_s"] / base
        results["sizes"][f"{size:.0f}"]["per_km2_vs_smallest"] = ratio
        print(f"generation time per km² at {size:.0f} m / at {sizes[0]:.0f} m: {ratio:.2f}x")
    results["quality"] = quality(args, sizes[0], work)
    results["contention_after"] = contention()
    print(f"contention: {results['contention_after']}")
    args.json.parent.mkdir(parents=True, exist_ok=True)
    args.json.write_text(json.dumps(results, indent=1) + "\n")


def quality(args, side: float, work: Path) -> dict:
    """``evaluate`` on ours and the alternatives at the first size and the same density."""
    from roadweaver_sumo.validate.evaluate import evaluate_net

    nodes = round(args.density * side * side / 1e6)
    per_side = max(2, round(nodes ** 0.5))
    arms = 8
    circles = max(1, round((nodes - 1) / arms))
    nets = {"ours": work / f"ours-{side:.0f}-0" / "map.net.xml"}
    nets["netgenerate rand"] = work / "q-rand.net.xml"
    netgenerate(["--rand", "--rand.iterations", str(round(nodes / RAND_NODES_PER_ITERATION))],
                nets["netgenerate rand"])
    nets["netgenerate grid"] = work / "q-grid.net.xml"
    netgenerate(["--grid", "--grid.number", str(per_side),
                 "--grid.length", f"{side / (per_side - 1):.1f}"], nets["netgenerate grid"])
    nets["netgenerate spider"] = work / "q-spider.net.xml"
    netgenerate(["--spider", "--spider.arm-number", str(arms), "--spider.circle-number",
                 str(circles), "--spider.space-radius", f"{side / 2 / circles:.1f}"],
                nets["netgenerate spider"])
    if args.osm and args.osm.is_file():
        nets[f"OSM {args.osm.name.split('.')[0]}"] = osm_import(args.osm, work, side)
    table = {}
    print(f"\nquality at {side:.0f} m, target density {args.density:g}/km² (evaluate):")
    print(f"{'net':24s} " + " ".join(f"{q[:12]:>12s}" for q in QUALITY))
    for name, path in nets.items():
        result = evaluate_net(path, (side * side / 1e6) if name == "ours" else None)
        table[name] = {q: result[q] for q in QUALITY} | {"area_km2": result["area_km2"],
                                                         "alignment_mean": result["alignment"]["mean"]}
        print(f"{name:24s} " + " ".join(f"{result[q]:12.4g}" for q in QUALITY))
    return table


if __name__ == "__main__":
    main()
