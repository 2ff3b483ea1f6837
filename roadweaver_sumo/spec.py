"""The scenario specification: everything needed to regenerate a scenario folder byte for byte."""

from __future__ import annotations

import copy
import json
import math
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from . import __version__
from .errors import RoadweaverError

STYLES = ("grid", "radial", "organic", "mixed")
#: "open": roads run off the map edge, as in a map cut out of a town; "ring": a ring road
#: just inside the border closes the map (``expand.boundary``).
BOUNDARIES = ("open", "ring")
LEGACY_BOUNDARY = "ring"  # of a spec or suite written before there was a choice
TOWN_MARGIN = 150.0  # metres of the town an open map is cut out of, beyond each side
SKELETONS = ("learned", "procedural")
#: regional traffic rules, which choose each junction's control (``hdmap.control``)
RULES = ("de", "us", "priority")
DEFAULT_RULES = "de"
LEGACY_RULES = "priority"  # of a spec or suite written before there was a choice
#: junction controls a --junction-mix may ask for shares of (SUMO node types, ``hdmap.control``)
MIX_CONTROLS = ("traffic_light", "priority", "priority_stop", "right_before_left", "allway_stop")
DEFAULT_ONE_WAY_SHARE = 0.2
DEFAULT_PERSONS = 100  # on a map with sidewalks, unless --persons says otherwise
DEFAULT_BUS_LINES, MAX_BUS_LINES = 1, 4
#: SUMO vehicle classes a demand may mix (each gets SUMO's default vType of its class), and
#: the default mix: shares of the trips (``scenario.demand``)
VEHICLE_CLASSES = ("passenger", "truck", "bus", "motorcycle", "bicycle", "delivery")
#: Trucks and bicycles only on request: at a tight right-before-left junction SUMO lets a car
#: or a creeping bicycle go while a turning truck's body still fills the junction (a junction
#: collision in about one of 50 town scenarios with 5 % trucks).
DEFAULT_VEHICLE_MIX = {"passenger": 0.9, "motorcycle": 0.05, "bicycle": 0.05}
LEGACY_VEHICLE_MIX = {"passenger": 1.0}
MAX_FRINGE_FACTOR = 1000.0
DEPARTURES = ("random", "even")  # uniform random times (randomTrips --random-depart), evenly
LEGACY_DEPARTURES = "even"
#: Choices added after the first suites were kept, at the values every spec had before them:
#: spec.json and manifests leave these values unsaid, and reading supplies them, so that a
#: suite built then rebuilds to the same bytes.
UNSAID = {"rules": LEGACY_RULES, "vehicle_mix": LEGACY_VEHICLE_MIX,
          "departures": LEGACY_DEPARTURES, "fringe_factor": 1.0, "one_way_share": 0.0,
          "sidewalks": False, "persons": 0, "bus_lines": 0, "speeds": {}, "roundabouts": 0,
          "junction_mix": {}, "lanes": {}}
LEGACY = {"boundary": LEGACY_BOUNDARY, **UNSAID}  # spec.json leaves the ring unsaid too
MAX_SIDE_M = 50_000.0
MIN_SIDE_M = 200.0
MAX_VEHICLES = 1_000_000
MAX_DENSITY = 400.0  # road nodes per km²
MIN_ROAD_NODES = 4
MIN_DURATION_S, MAX_DURATION_S = 1.0, 604_800.0  # a week of demand
#: SUMO's tools take a seed that fits a signed 32-bit int (duarouter fails above it); the spec's
#: seed goes to randomTrips, duarouter and the sumocfg unchanged.
MAX_SEED = 2**31 - 1
MAX_WORKERS = 256  # parallel scenarios of a suite
MAX_EGO_ROUTES = 100
#: the road classes, highest first (``roadgraph``; ``hdmap.lanes.LANE_CONFIGS`` configures
#: them), and the speed limits one may give them
ROAD_CLASSES = ("arterial", "collector", "local")
MIN_SPEED_KMH, MAX_SPEED_KMH = 5.0, 130.0
MAX_LANES = 4  # per direction, by road class (--lanes)
DEFAULT_ROUNDABOUTS, MAX_ROUNDABOUTS = 1, 1000
DEFAULT_EGO_LENGTH_M, MIN_EGO_LENGTH_M, MAX_EGO_LENGTH_M = 5000.0, 200.0, 100_000.0
DEFAULT_GEO_ORIGIN = (48.137, 11.575)  # lat, lon: only a label for the local metric frame
#: The structural priors a user may set (``--gridness`` ...), with their ranges as
#: ``data.condition`` measures them; bearing entropy in nats, at most ln 36 (36 bins).
PRIOR_RANGES = {"gridness": (0.0, 1.0), "radialness": (-1.0, 1.0),
                "organicness": (0.0, 1.0), "bearing_entropy": (0.0, round(math.log(36), 3))}

# Stage ids for np.random.default_rng([seed, STAGE]): each stage draws from its own stream, so
# changing one stage never shifts the random numbers of another.
STAGE_SKELETON, STAGE_GROWTH, STAGE_FILL, STAGE_DEMAND, STAGE_PERSONS = 1, 2, 4, 5, 6
STAGE_CROSSROADS = 7


@dataclass(frozen=True)
class ScenarioSpec:
    """What the user asked for. ``width``/``height`` in metres, ``density`` in road nodes per km²."""

    density: float
    vehicles: int
    width: float = 2000.0
    height: float = 2000.0
    seed: int = 0
    style: str = "mixed"
    skeleton: str = "learned"
    boundary: str = "open"
    #: regional traffic rules: junction control (``hdmap.control``)
    rules: str = DEFAULT_RULES
    #: share of the local street length made one-way, in alternating pairs (``hdmap.one_way``)
    one_way_share: float = DEFAULT_ONE_WAY_SHARE
    #: a sidewalk beside every driving direction, crossings at junctions (``hdmap.lanes``,
    #: ``export.sumo_plain.crossings``)
    sidewalks: bool = True
    #: speed limits in km/h by road class, where not the class's own (``hdmap.lanes``)
    speeds: dict = field(default_factory=dict)
    #: junction control -> share of the junctions of three or more arms (``hdmap.control``)
    junction_mix: dict = field(default_factory=dict)
    #: lanes per direction by road class, where not the class's own (``hdmap.lane_counts``)
    lanes: dict = field(default_factory=dict)
    #: up to this many junctions made roundabouts (``hdmap.roundabouts``)
    roundabouts: int = DEFAULT_ROUNDABOUTS
    duration: float = 3600.0
    #: vehicle class -> share of the trips; departure times random or evenly spread
    vehicle_mix: dict = field(default_factory=lambda: dict(DEFAULT_VEHICLE_MIX))
    departures: str = "random"
    #: pedestrians walking over the duration (``scenario.persons``); needs sidewalks. None:
    #: :data:`DEFAULT_PERSONS` on a map with sidewalks, none on one without
    persons: int | None = None
    #: bus lines across the map with stops (``scenario.bus_lines``). None:
    #: :data:`DEFAULT_BUS_LINES` where the map's main roads have room for it, none where not
    bus_lines: int | None = None
    #: randomTrips' --fringe-factor: how much likelier trips start and end where roads leave
    #: the map (1: as likely as anywhere else of the same length)
    fringe_factor: float = 1.0
    geo_origin: tuple[float, float] = DEFAULT_GEO_ORIGIN
    version: str = field(default=__version__)
    #: structural priors of the learned model's condition, None: the style's (or the city's)
    gridness: float | None = None
    radialness: float | None = None
    organicness: float | None = None
    bearing_entropy: float | None = None
    #: "a map like this city" (``like.measure_city``): its name, density, structural priors and
    #: statistics, kept here so that the spec regenerates the map without the city's file
    like: dict | None = None
    #: long routes for an ego vehicle (``closed_loop.routes``), 0: none
    ego_routes: int = 0
    ego_length: float = DEFAULT_EGO_LENGTH_M

    def __post_init__(self) -> None:
        _check_positive_number("density", self.density)
        if self.density > MAX_DENSITY:
            raise RoadweaverError(
                f"--density {self.density:g} is above {MAX_DENSITY:g} road nodes/km²")
        if isinstance(self.vehicles, bool) or not isinstance(self.vehicles, int):
            raise RoadweaverError(f"--vehicles must be a whole number, got {self.vehicles!r}")
        if not 1 <= self.vehicles <= MAX_VEHICLES:
            raise RoadweaverError(f"--vehicles must be 1..{MAX_VEHICLES}, got {self.vehicles}")
        for name in ("width", "height"):
            side = getattr(self, name)
            _check_positive_number(f"map {name}", side)
            if not MIN_SIDE_M <= side <= MAX_SIDE_M:
                raise RoadweaverError(
                    f"map {name} {side:g} m is outside {MIN_SIDE_M:g}..{MAX_SIDE_M:g} m"
                )
        if self.style not in STYLES:
            raise RoadweaverError(f"unknown style {self.style!r}; choose one of {', '.join(STYLES)}")
        if self.skeleton not in SKELETONS:
            raise RoadweaverError(
                f"unknown skeleton {self.skeleton!r}; choose one of {', '.join(SKELETONS)}"
            )
        if self.boundary not in BOUNDARIES:
            raise RoadweaverError(
                f"unknown boundary {self.boundary!r}; choose one of {', '.join(BOUNDARIES)}")
        if self.rules not in RULES:
            raise RoadweaverError(f"unknown rules {self.rules!r}; choose one of {', '.join(RULES)}")
        _check_number("--one-way-share", self.one_way_share)
        if not 0 <= self.one_way_share <= 1:
            raise RoadweaverError(f"--one-way-share must be 0..1, got {self.one_way_share:g}")
        if not isinstance(self.sidewalks, bool):
            raise RoadweaverError(f"sidewalks must be true or false, got {self.sidewalks!r}")
        if self.persons is None:
            object.__setattr__(self, "persons", DEFAULT_PERSONS if self.sidewalks else 0)
        if isinstance(self.persons, bool) or not isinstance(self.persons, int) or not (
                0 <= self.persons <= MAX_VEHICLES):
            raise RoadweaverError(f"--persons must be a whole number 0..{MAX_VEHICLES}, got "
                                  f"{self.persons!r}")
        if self.persons and not self.sidewalks:
            raise RoadweaverError("--persons needs sidewalks to walk on: leave out --no-sidewalks")
        if self.bus_lines is not None and (
                isinstance(self.bus_lines, bool) or not isinstance(self.bus_lines, int)
                or not 0 <= self.bus_lines <= MAX_BUS_LINES):
            raise RoadweaverError(f"--bus-lines must be a whole number 0..{MAX_BUS_LINES}, got "
                                  f"{self.bus_lines!r}")
        _check_vehicle_mix(self.vehicle_mix)
        _check_speeds(self.speeds)
        _check_junction_mix(self.junction_mix)
        _check_named_numbers(self.lanes, "--lanes", "road class", ROAD_CLASSES, (1, MAX_LANES))
        if any(isinstance(n, float) for n in self.lanes.values()):
            raise RoadweaverError("--lanes: lane counts are whole numbers, e.g. arterial=3")
        if isinstance(self.roundabouts, bool) or not isinstance(self.roundabouts, int) or not (
                0 <= self.roundabouts <= MAX_ROUNDABOUTS):
            raise RoadweaverError(f"--roundabouts must be a whole number 0..{MAX_ROUNDABOUTS}, "
                                  f"got {self.roundabouts!r}")
        if self.departures not in DEPARTURES:
            raise RoadweaverError(f"unknown departures {self.departures!r}; choose one of "
                                  f"{', '.join(DEPARTURES)}")
        _check_number("--fringe-factor", self.fringe_factor)
        if not 0 <= self.fringe_factor <= MAX_FRINGE_FACTOR:
            raise RoadweaverError(f"--fringe-factor must be 0..{MAX_FRINGE_FACTOR:g}, got "
                                  f"{self.fringe_factor:g}")
        _check_geo_origin(self.geo_origin)
        _check_seed("--seed", self.seed)
        for name, (low, high) in PRIOR_RANGES.items():
            value = getattr(self, name)
            if value is not None:
                _check_number(f"--{name.replace('_', '-')}", value)
                if not low <= value <= high:
                    raise RoadweaverError(f"--{name.replace('_', '-')} must be {low:g}..{high:g}, "
                                          f"got {value:g}")
        if self.priors and self.skeleton != "learned":
            raise RoadweaverError("--gridness, --radialness, --organicness and --bearing-entropy "
                                  "condition the learned skeleton; drop them or use "
                                  "--skeleton learned")
        if self.like is not None:
            _check_like(self.like)
        if isinstance(self.ego_routes, bool) or not isinstance(self.ego_routes, int) or \
                not 0 <= self.ego_routes <= MAX_EGO_ROUTES:
            raise RoadweaverError(f"--ego-routes must be a whole number 0..{MAX_EGO_ROUTES}, "
                                  f"got {self.ego_routes!r}")
        _check_number("--ego-length", self.ego_length)
        if not MIN_EGO_LENGTH_M <= self.ego_length <= MAX_EGO_LENGTH_M:
            raise RoadweaverError(f"--ego-length must be {MIN_EGO_LENGTH_M:g}.."
                                  f"{MAX_EGO_LENGTH_M:g} m, got {self.ego_length:g}")
        _check_positive_number("--duration", self.duration)
        if not MIN_DURATION_S <= self.duration <= MAX_DURATION_S:
            raise RoadweaverError(f"--duration must be {MIN_DURATION_S:g}..{MAX_DURATION_S:g} s "
                                  f"(a week), got {self.duration:g}")
        nodes = self.density * self.area_km2
        if nodes < MIN_ROAD_NODES:
            raise RoadweaverError(
                f"a {self.width:g} x {self.height:g} m map at {self.density:g} road nodes/km² "
                f"holds only {nodes:.1f} road nodes; ask for at least {MIN_ROAD_NODES} "
                "(a larger --size or a higher --density)"
            )

    def town(self) -> ScenarioSpec:
        """The spec of the larger town an open map is cut out of (``expand.boundary``):
        :data:`TOWN_MARGIN` more on every side; a ring map is its own town. Not checked again:
        the town of a map of the largest size is larger than a user may ask for."""
        if self.boundary == "ring":
            return self
        town = copy.copy(self)
        object.__setattr__(town, "width", self.width + 2 * TOWN_MARGIN)
        object.__setattr__(town, "height", self.height + 2 * TOWN_MARGIN)
        return town

    @property
    def priors(self) -> dict[str, float]:
        """The structural priors the user set, by name."""
        return {k: getattr(self, k) for k in PRIOR_RANGES if getattr(self, k) is not None}

    @property
    def area_km2(self) -> float:
        return self.width * self.height / 1e6

    @property
    def target_road_nodes(self) -> int:
        return round(self.density * self.area_km2)

    @property
    def name(self) -> str:
        """Folder name that tells the scenarios of a suite apart at a glance."""
        look = f"like-{self.like['name']}" if self.like else self.style
        return (f"{look}-d{self.density:g}-{self.width:g}x{self.height:g}-s{self.seed}"
                f"-v{self.vehicles}")

    @property
    def netconvert_template(self) -> str:
        """Sparse maps are suburban (priority junctions); denser ones urban (traffic lights)."""
        return "urban" if self.density >= 20 else "suburban"

    @property
    def traffic_lights(self) -> bool:
        """Urban maps signalise arterial crossings; suburban ones keep priority junctions."""
        return self.netconvert_template == "urban"

    def rng(self, stage: int) -> np.random.Generator:
        return np.random.default_rng([self.seed, stage])

    def to_json(self) -> str:
        """The spec as ``spec.json`` writes it: the :data:`LEGACY` values left unsaid."""
        data = asdict(self)
        data["geo_origin"] = list(self.geo_origin)
        for name, value in LEGACY.items():
            if data[name] == value:
                del data[name]
        for name in (*PRIOR_RANGES, "like"):  # unset: left out, as in specs written before
            if data[name] is None:
                del data[name]
        if not self.ego_routes:
            del data["ego_routes"], data["ego_length"]
        return json.dumps(data, indent=2, sort_keys=True) + "\n"

    @classmethod
    def from_json_file(cls, path: Path) -> ScenarioSpec:
        try:
            data = json.loads(Path(path).read_text(encoding="utf-8"))
        except (OSError, json.JSONDecodeError) as exc:
            raise RoadweaverError(f"cannot read spec {path}: {exc}") from None
        return cls.from_dict(data)

    @classmethod
    def from_dict(cls, data: dict) -> ScenarioSpec:
        """The spec of a parsed ``spec.json`` or manifest entry: fields this version does not
        know are ignored, a missing boundary, rule set, vehicle mix or departure choice is the
        value every spec had before the choice."""
        data = {**LEGACY, **data}
        data["geo_origin"] = tuple(data.get("geo_origin", DEFAULT_GEO_ORIGIN))
        return cls(**{k: v for k, v in data.items() if k in cls.__dataclass_fields__})


def _check_geo_origin(origin) -> None:
    if not isinstance(origin, (tuple, list)) or len(origin) != 2:
        raise RoadweaverError(f"--geo-origin must be (latitude, longitude), got {origin!r}")
    lat, lon = origin
    for name, value, limit in (("latitude", lat, 85.0), ("longitude", lon, 180.0)):
        _check_number(f"--geo-origin {name}", value)
        if not -limit <= value <= limit:
            raise RoadweaverError(f"--geo-origin: {name} {value:g} is outside "
                                  f"-{limit:g}..{limit:g} degrees")


def _check_speeds(speeds) -> None:
    _check_named_numbers(speeds, "--speed", "road class", ROAD_CLASSES,
                         (MIN_SPEED_KMH, MAX_SPEED_KMH), " km/h")


def _check_junction_mix(mix) -> None:
    _check_named_numbers(mix, "--junction-mix", "junction control", MIX_CONTROLS, (0.0, 1.0))
    if sum(mix.values()) > 1 + 1e-9:
        raise RoadweaverError(f"--junction-mix: the shares add up to {sum(mix.values()):g}, "
                              "more than 1")


def _check_named_numbers(values, option: str, what: str, names: tuple[str, ...],
                         limits: tuple[float, float], unit: str = "") -> None:
    """A {name: number} option: every name one of ``names``, every number within ``limits``."""
    if not isinstance(values, dict):
        raise RoadweaverError(f"{option} must map each {what} to a number")
    low, high = limits
    for name, value in values.items():
        if name not in names:
            raise RoadweaverError(f"{option}: unknown {what} {name!r}; choose from "
                                  f"{', '.join(names)}")
        _check_number(f"{option} {name}", value)
        if not low <= value <= high:
            raise RoadweaverError(f"{option} {name} must be {low:g}..{high:g}{unit}, got "
                                  f"{value:g}")


def _check_vehicle_mix(mix) -> None:
    if not isinstance(mix, dict) or not mix:
        raise RoadweaverError("--vehicle-mix must name at least one vehicle class")
    for name, share in mix.items():
        if name not in VEHICLE_CLASSES:
            raise RoadweaverError(f"--vehicle-mix: unknown vehicle class {name!r}; choose from "
                                  f"{', '.join(VEHICLE_CLASSES)}")
        if isinstance(share, bool) or not isinstance(share, (int, float)) or \
                not math.isfinite(share) or share < 0:
            raise RoadweaverError(f"--vehicle-mix: the share of {name} must be a number >= 0")
    if not sum(mix.values()) > 0:
        raise RoadweaverError("--vehicle-mix: the shares add up to 0")


def _check_seed(name: str, seed) -> int:
    """``seed`` if it is a whole number 0..MAX_SEED (what SUMO's tools accept), else a
    one-line error naming the option."""
    if isinstance(seed, bool) or not isinstance(seed, int) or not 0 <= seed <= MAX_SEED:
        raise RoadweaverError(f"{name} must be a whole number 0..{MAX_SEED}, got {seed!r}")
    return seed


def _check_like(like) -> None:
    """A ``like`` entry of a spec (``like.measure_city``), which a hand-edited spec.json may
    have broken: a one-line error naming what is wrong."""
    if not isinstance(like, dict) or not {"name", "density", "priors", "statistics"} <= set(like):
        raise RoadweaverError("spec field 'like' must hold name, density, priors and statistics")
    if not set(like["priors"]) <= set(PRIOR_RANGES):
        raise RoadweaverError(f"spec field 'like' names priors other than {', '.join(PRIOR_RANGES)}")
    values = [like["density"], *like["priors"].values(), *like["statistics"].values()]
    if not isinstance(like["name"], str) or not all(
            isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)
            for v in values):
        raise RoadweaverError("spec field 'like' holds a value that is not a finite number")


def _check_number(name: str, value) -> None:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise RoadweaverError(f"{name} must be a finite number, got {value!r}")


def _check_positive_number(name: str, value) -> None:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise RoadweaverError(f"{name} must be a number, got {value!r}")
    if not math.isfinite(value) or value <= 0:
        raise RoadweaverError(f"{name} must be > 0 and finite, got {value:g}")
