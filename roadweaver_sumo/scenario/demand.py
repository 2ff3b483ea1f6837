"""Traffic demand: an exact number of routable, seeded trips of a vehicle mix (issue 36), routed
into ``demand.rou.xml``.

``randomTrips.py`` draws origin/destination edges, but its vehicle count follows from
``--period`` (it can be off by one, and it drops pairs it could not place), and its own validation
routes every trip twice more. So we ask it for more trips than needed, without validation, route
them once with duarouter (``--ignore-errors`` drops the unroutable ones: that is the
validation), keep the first ``vehicles`` routes between distinct edges, and give them ids
``veh0..``, departures over [0, duration) (random, as real traffic arrives, or evenly spread)
and vehicle classes drawn from the mix. Routes do not depend on the departure time (static
free-flow weights), so re-timing keeps them valid; they are routed for cars, which every class
of the mix may drive where cars may (the lanes allow all classes). If too few trips were routable,
we sample again with a larger oversupply, deterministically. Every program runs inside the
scenario folder with relative paths, so the output is byte-identical for the same inputs.

Sampling choices (all passed to randomTrips):

* ``--length``: origins/destinations are weighted by edge length, so demand is spread evenly over
  the road surface instead of favouring short junction-dense edges;
* ``--min-distance``: origin and destination at least a fifth of the map diagonal apart (at most
  1 km), so trips cross a few junctions instead of hopping one block;
* ``--fringe-factor`` (1 unless asked): through traffic enters and leaves where roads run off
  an open map (nodes marked ``fringe="outer"``, ``--fringe-junctions``);
* ``departLane="best" departSpeed="max"``: cars enter on a lane that leads along their route, as
  drivers do, instead of all on the rightmost lane (which causes needless lane-change jams).

duarouter uses A* (same shortest paths as Dijkstra, ~2x faster on a 900-junction grid) on
``ROUTING_THREADS`` threads: each trip's route is a search of its own on static weights, so the
routes do not depend on the threads (tests compare). Routing is most of the demand's time on a
large map (a 10 km map: 6,250 A* searches, 17 s on one thread), so only the first trips, a few
more than the vehicles asked for, are routed; the rest only if too few of those were routable.
The kept routes are the first ones either way, so the file is the same.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import numpy as np
from lxml import etree

from ..errors import RoadweaverError
from ..spec import DEFAULT_VEHICLE_MIX, STAGE_DEMAND
from ..sumo_tools import binary, python_tool, run
from .xmlfile import write_xml

DEMAND_FILE = "demand.rou.xml"
# Temporary files, deleted before write_demand returns (also on failure).
_SAMPLE_TRIPS = "demand.sample.trips.tmp.xml"
_SAMPLE_ROUTES = "demand.sample.rou.tmp.xml"
_ROUTED_TRIPS = "demand.routed.trips.tmp.xml"

OVERSUPPLY = 1.25  # first request 25 % more trips than needed; doubled on each further attempt
#: Trips routed first, as a share of the vehicles (plus ROUTE_FIRST_EXTRA): on generated maps
#: about one trip in a thousand is unroutable or starts and ends on one edge.
ROUTE_FIRST_SHARE, ROUTE_FIRST_EXTRA = 1.02, 10
ROUTING_THREADS = 2
MAX_ATTEMPTS = 4
MIN_DISTANCE_SHARE = 0.2  # of the map diagonal
MIN_DISTANCE_CAP_M = 1000.0
VEHICLE_CLASS = "passenger"
TRIP_ATTRIBUTES = 'departLane="best" departSpeed="max"'
#: SUMO's drivers on a minor road creep towards the conflict point while a foe is still in the
#: junction (``jmAdvance``); a bus or truck turning through it fills more of the junction than
#: that point allows for, and the creeping car or bus was hit (4 bus-bus collisions in one of
#: 50 quality-sweep scenarios, 1 car-bus in the main job). Every type we write waits at the
#: stop line instead.
WAIT_AT_STOP_LINE = {"jmAdvance": "0"}


def write_demand(
    out_dir: Path, *, vehicles: int, duration: float, seed: int, net_file: str = "map.net.xml",
    vehicle_mix: dict[str, float] | None = None, departures: str = "random",
    fringe_factor: float = 1.0,
) -> Path:
    """Write ``out_dir/demand.rou.xml`` with exactly ``vehicles`` routed trips departing in
    [0, duration), of the SUMO vehicle classes of ``vehicle_mix`` (class -> share; default
    :data:`~roadweaver_sumo.spec.DEFAULT_VEHICLE_MIX`) at random or evenly spread times
    (``departures``), trips starting and ending where roads leave the map ``fringe_factor``
    times likelier (randomTrips' ``--fringe-factor`` on the nodes marked ``fringe="outer"``);
    raise RoadweaverError when the net cannot provide that many routable trips."""
    out_dir = Path(out_dir)
    if vehicles < 1 or duration <= 0:
        raise RoadweaverError(
            f"demand needs vehicles >= 1 and duration > 0, got {vehicles}, {duration}"
        )
    if not (out_dir / net_file).exists():
        raise RoadweaverError(f"demand: network {out_dir / net_file} not found")
    min_distance = _min_distance(out_dir / net_file)
    temporary = [_SAMPLE_TRIPS, _ROUTED_TRIPS, _SAMPLE_ROUTES]
    with _removed_afterwards(out_dir, temporary):
        routes = _sample_routes(out_dir, net_file, vehicles, duration, seed, min_distance,
                                fringe_factor)
    mix = DEFAULT_VEHICLE_MIX if vehicle_mix is None else vehicle_mix
    _assign(routes, duration, np.random.default_rng([seed, STAGE_DEMAND]), mix, departures)
    return write_xml(routes, out_dir / DEMAND_FILE)


def _min_distance(net_path: Path) -> float:
    return min(MIN_DISTANCE_SHARE * _net_diagonal(net_path), MIN_DISTANCE_CAP_M)


def _wanted(vehicles: int, attempt: int) -> int:
    return math.ceil(vehicles * OVERSUPPLY * 2**attempt)


def _sample_routes(
    out_dir: Path, net_file: str, vehicles: int, duration: float, seed: int, min_distance: float,
    fringe_factor: float = 1.0,
) -> etree._Element:
    """duarouter's ``<routes>`` cut down to its first ``vehicles`` routed cars between distinct
    edges, asking randomTrips for more (same seed, larger oversupply) until there are enough."""
    found = 0
    for attempt in range(MAX_ATTEMPTS):
        _random_trips(out_dir, net_file, _wanted(vehicles, attempt), duration, seed,
                      min_distance, fringe_factor)
        first = math.ceil(vehicles * ROUTE_FIRST_SHARE) + ROUTE_FIRST_EXTRA
        for trips in (first, None):
            root, routed, all_routed = _routed(out_dir, net_file, seed, trips)
            found = len(routed)
            if found >= vehicles:
                for vehicle in root.findall("vehicle"):
                    root.remove(vehicle)
                root.extend(routed[:vehicles])
                return root
            if all_routed:
                break
    raise RoadweaverError(
        f"demand: only {found} of {vehicles} trips are routable with origin and destination "
        f"at least {min_distance:.0f} m apart; is the network connected?"
    )


def _routed(out_dir: Path, net_file: str, seed: int, trips: int | None):
    """duarouter's ``<routes>`` for the first ``trips`` sampled trips (all of them with None),
    its vehicles between distinct edges in departure order, and whether every sampled trip
    was routed."""
    root = etree.parse(str(out_dir / _SAMPLE_TRIPS)).getroot()
    sampled = root.findall("trip")
    all_routed = trips is None or trips >= len(sampled)
    for trip in sampled[len(sampled) if all_routed else trips:]:
        root.remove(trip)
    etree.ElementTree(root).write(str(out_dir / _ROUTED_TRIPS), xml_declaration=True,
                                  encoding="UTF-8")
    _route(out_dir, net_file, seed)
    routes = etree.parse(str(out_dir / _SAMPLE_ROUTES)).getroot()
    return routes, [v for v in routes.findall("vehicle") if _distinct_ends(v)], all_routed


def _distinct_ends(vehicle: etree._Element) -> bool:
    edges = vehicle.find("route").get("edges").split()
    return edges[0] != edges[-1]


def _random_trips(
    out_dir: Path, net_file: str, count: int, duration: float, seed: int, min_distance: float,
    fringe_factor: float = 1.0, out: str = _SAMPLE_TRIPS,
) -> None:
    """Run randomTrips.py (seeded, unvalidated: duarouter validates next) for ~``count`` trips."""
    args = [
        *python_tool("randomTrips.py"),
        "-n", net_file, "-o", out, "--no-validate",
        "--seed", str(seed), "--begin", "0", "--end", repr(float(duration)),
        "--period", repr(duration / count),
        "--length", "--min-distance", f"{min_distance:.1f}",
        "--vehicle-class", VEHICLE_CLASS, "--edge-permission", VEHICLE_CLASS,
        "--trip-attributes", TRIP_ATTRIBUTES,
    ]  # fmt: skip
    if fringe_factor != 1.0:
        args += ["--fringe-factor", repr(float(fringe_factor)), "--fringe-junctions"]
    try:
        run(args, out_dir, "randomTrips.py")
    except RoadweaverError as exc:
        if fringe_factor == 1.0:
            raise
        raise RoadweaverError(f"--fringe-factor {fringe_factor:g}: randomTrips found no trip "
                              "between the map's border roads and the rest of it; the map has "
                              "too few roads away from its border for it (use 1)") from exc
    if not (out_dir / out).exists():
        raise RoadweaverError("demand: randomTrips.py wrote no trips; does the net allow cars?")


def _route(out_dir: Path, net_file: str, seed: int) -> None:
    """Route the trips to route; unroutable ones are dropped (``--ignore-errors``)."""
    args = [
        binary("duarouter"), "-n", net_file, "-r", _ROUTED_TRIPS, "-o", _SAMPLE_ROUTES,
        "--alternatives-output", "NUL", "--routing-algorithm", "astar", "--ignore-errors",
        "--routing-threads", str(ROUTING_THREADS),
        "--no-warnings", "--seed", str(seed), "--no-step-log",
    ]  # fmt: skip
    run(args, out_dir, "duarouter")


def _assign(routes: etree._Element, duration: float, rng: np.random.Generator,
            mix: dict[str, float], departures: str) -> None:
    """Vehicles renamed ``veh<i>``, given a vehicle class drawn from ``mix`` (a ``vType`` of
    that SUMO class, with SUMO's defaults for it: length, speed, acceleration, lane-change
    behaviour) and departing in order at uniform random times (as randomTrips'
    ``--random-depart`` draws them) or at ``i * duration / n``. A mix of cars alone keeps
    randomTrips' passenger type, as every demand of earlier versions did."""
    vehicles = routes.findall("vehicle")
    n = len(vehicles)  # each class's type: SUMO's defaults, waiting at the stop line
    times = np.sort(rng.uniform(0.0, duration, n)) if departures == "random" else \
        np.arange(n) * duration / n
    classes = sorted(name for name, share in mix.items() if share > 0)
    typed = classes != [VEHICLE_CLASS]
    if typed:
        shares = np.array([mix[name] for name in classes], dtype=float)
        drawn = rng.choice(len(classes), size=n, p=shares / shares.sum())
        for vtype in routes.findall("vType"):  # randomTrips' own passenger type
            routes.remove(vtype)
        for k, name in enumerate(classes):
            routes.insert(k, etree.Element("vType", id=name, vClass=name, **WAIT_AT_STOP_LINE))
    for i, vehicle in enumerate(vehicles):
        vehicle.set("id", f"veh{i}")
        vehicle.set("depart", f"{times[i]:.2f}")
        if typed:
            vehicle.set("type", classes[drawn[i]])


def _net_diagonal(net_path: Path) -> float:
    """Diagonal of the net's ``convBoundary`` in metres (read from the header, not the whole net)."""
    for _, loc in etree.iterparse(str(net_path), tag="location"):
        x0, y0, x1, y1 = (float(v) for v in loc.get("convBoundary").split(","))
        return math.hypot(x1 - x0, y1 - y0)
    raise RoadweaverError(f"{net_path} has no <location> element; is it a SUMO net?")


@contextmanager
def _removed_afterwards(folder: Path, names: list[str]) -> Iterator[None]:
    """Delete the named temporary files when the block ends, also when it fails."""
    try:
        yield
    finally:
        for name in names:
            (folder / name).unlink(missing_ok=True)
