"""Walking demand (issue 36, "road users"): an exact number of seeded pedestrians on the
sidewalks, crossing junctions on SUMO's crossings and walking areas, in ``persons.rou.xml``.

A rule regression suite needs people at the crossings: a driver model that does not yield to
a pedestrian on a zebra crossing, or a light whose pedestrian phase changed, must show up in
the figures. As for the vehicles (``scenario.demand``), randomTrips draws the walks
(``--pedestrians``, length-weighted, ``MIN_WALK_M`` to ``MAX_WALK_M`` apart: a walk to a
shop or a stop, not across town) and duarouter routes them over sidewalks, crossings and
walking areas. A walk starts and ends at a random point of its street (a door), as people's
do: one that starts at the street's end steps onto a crossing at once, in front of cars that
had no one to expect (in a 50-map sweep with 100 walkers each, walks from street ends gave
twice as many maps with a vehicle-person collision as walks from doors). Pedestrians cross
only at junctions, so on a map of long blocks two points 500 m apart can be kilometres apart
on foot; walks longer than ``MAX_ROUTE_M`` are dropped, so every walk ends well within the
simulation's hour after the last departure. We ask for more than needed, keep the first
``persons`` and give them ids ``ped0..`` and departures over
[0, duration) (random or evenly spread, as the vehicles'). Runs inside the scenario folder
with relative paths: the same inputs give the same bytes.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from lxml import etree

from ..errors import RoadweaverError
from ..spec import STAGE_PERSONS
from ..sumo_tools import binary, python_tool, run
from .xmlfile import write_xml

PERSONS_FILE = "persons.rou.xml"
_SAMPLE, _ROUTED = "persons.sample.tmp.xml", "persons.routed.tmp.xml"
MIN_WALK_M, MAX_WALK_M = 100.0, 1000.0  # straight-line distance of the walk's two edges
MAX_ROUTE_M = 2500.0  # the walk along its edges: 32 min at SUMO's 1.3 m/s
#: The walkers' vType: SUMO's pedestrian but 1 m long (SUMO's 0.215 m is a body's depth).
#: SUMO's drivers take a walker on a crossing for gone once the walker's back has passed the
#: car's side as if the car crossed square; a car turning across the crossing at an angle
#: then started while its corner still reached the walker. A 1 m walker (the room a driver
#: leaves behind a person) keeps them waiting until the walker is clear: on 50 maps x 6
#: simulation seeds with 100 walkers, runs with a vehicle-person collision 18 of 300 -> 3.
WALKER_TYPE = {"id": "walker", "vClass": "pedestrian", "length": "1.0"}
OVERSUPPLY, MAX_ATTEMPTS = 1.25, 4


def write_persons(out_dir: Path, *, persons: int, duration: float, seed: int,
                  departures: str = "random", net_file: str = "map.net.xml") -> Path:
    """Write ``out_dir/persons.rou.xml`` with exactly ``persons`` routable walks departing in
    [0, duration); raise RoadweaverError if the net has no sidewalks for that many."""
    out_dir = Path(out_dir)
    try:
        walkers = _sample(out_dir, net_file, persons, duration, seed)
    finally:
        for name in (_SAMPLE, _ROUTED):
            (out_dir / name).unlink(missing_ok=True)
    rng = np.random.default_rng([seed, STAGE_PERSONS])
    times = np.sort(rng.uniform(0.0, duration, persons)) if departures == "random" else \
        np.arange(persons) * duration / persons
    root = etree.Element("routes")
    etree.SubElement(root, "vType", WALKER_TYPE)
    for i, person in enumerate(walkers):
        person.set("id", f"ped{i}")
        person.set("type", WALKER_TYPE["id"])
        person.set("depart", f"{times[i]:.2f}")
        root.append(person)
    return write_xml(root, out_dir / PERSONS_FILE)


def _sample(out_dir: Path, net_file: str, persons: int, duration: float,
            seed: int) -> list[etree._Element]:
    """The first ``persons`` routed walks of randomTrips no longer than ``MAX_ROUTE_M``,
    asking for more until enough."""
    length = _edge_lengths(out_dir / net_file)
    found = 0
    for attempt in range(MAX_ATTEMPTS):
        wanted = math.ceil(persons * OVERSUPPLY * 2**attempt)
        args = [*python_tool("randomTrips.py"), "-n", net_file, "-o", _SAMPLE, "--pedestrians",
                "--random-departpos", "--random-arrivalpos",
                "--no-validate",
                "--seed", str(seed), "--begin", "0", "--end", repr(float(duration)),
                "--period", repr(duration / wanted), "--length",
                "--min-distance", repr(MIN_WALK_M), "--max-distance", repr(MAX_WALK_M)]
        run(args, out_dir, "randomTrips.py --pedestrians")
        if not (out_dir / _SAMPLE).exists():
            break
        run([binary("duarouter"), "-n", net_file, "-r", _SAMPLE, "-o", _ROUTED,
             "--alternatives-output", "NUL", "--ignore-errors", "--no-warnings", "--no-step-log", "--seed", str(seed)],
            out_dir, "duarouter (walks)")
        sampled = [person for person in etree.parse(str(out_dir / _ROUTED)).getroot()
                   .iter("person") if sum(length[e] for e in person.find("walk").get(
                       "edges").split()) <= MAX_ROUTE_M]
        found = len(sampled)
        if found >= persons:
            return sampled[:persons]
    raise RoadweaverError(f"persons: only {found} of {persons} walks are routable; does the "
                          "map have sidewalks (--sidewalks)?")


def _edge_lengths(net_path: Path) -> dict[str, float]:
    """Length of every edge of the net (its first lane's), read without loading the net."""
    lengths = {}
    for _, edge in etree.iterparse(str(net_path), tag="edge"):
        lane = edge.find("lane")
        if lane is not None:
            lengths[edge.get("id")] = float(lane.get("length"))
        edge.clear()
    return lengths
