"""A suite is a grid of scenario specs: densities x styles x seeds at one size, demand and skeleton.

Every value is checked here, before any work starts, so that a typo in the 300th combination is a
one-line error at once rather than a failure after an hour of building.
"""

from __future__ import annotations

import math
import re
from dataclasses import asdict, dataclass, field, fields

from ..errors import RoadweaverError
from ..spec import (
    DEFAULT_EGO_LENGTH_M,
    LEGACY,
    LEGACY_DEPARTURES,
    LEGACY_RULES,
    LEGACY_VEHICLE_MIX,
    UNSAID,
    ScenarioSpec,
)
from .coverage import parse_min_coverage

MAX_SCENARIOS = 10_000  # a larger grid is almost certainly a typo such as --seeds 0-99999


@dataclass(frozen=True)
class SuiteSpec:
    """The grid of a suite; ``scenarios()`` lists it densities first, then styles, then seeds."""

    densities: tuple[float, ...]
    styles: tuple[str, ...]
    seeds: tuple[int, ...]
    width: float = 2000.0
    height: float = 2000.0
    vehicles: int = 500
    duration: float = 3600.0
    skeleton: str = "procedural"
    boundary: str = "ring"
    rules: str = LEGACY_RULES
    one_way_share: float = 0.0
    sidewalks: bool = False
    speeds: dict = field(default_factory=dict)
    junction_mix: dict = field(default_factory=dict)
    lanes: dict = field(default_factory=dict)
    roundabouts: int = 0
    persons: int = 0
    bus_lines: int = 0
    vehicle_mix: dict = field(default_factory=lambda: dict(LEGACY_VEHICLE_MIX))
    departures: str = LEGACY_DEPARTURES
    fringe_factor: float = 1.0
    ego_routes: int = 0
    ego_length: float = DEFAULT_EGO_LENGTH_M
    #: every scenario holds at least this many of each rule situation (``suite.coverage``)
    min_coverage: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        _normalise(self)
        if not isinstance(self.min_coverage, dict):
            raise RoadweaverError("min_coverage must map rule situations to counts")
        if self.min_coverage:  # checked as the command line's text is
            parse_min_coverage(",".join(f"{k}={v}" for k, v in self.min_coverage.items()))
        for name in ("densities", "styles", "seeds"):
            values = getattr(self, name)
            if not isinstance(values, tuple) or not values:
                raise RoadweaverError(f"--{name} must list at least one value")
            if len(set(values)) != len(values):
                raise RoadweaverError(f"--{name} lists a value twice: {_first_repeat(values)}")
        count = len(self.densities) * len(self.styles) * len(self.seeds)
        if count > MAX_SCENARIOS:
            raise RoadweaverError(f"the suite has {count} scenarios; at most {MAX_SCENARIOS}")
        names = [spec.name for spec in self.scenarios()]  # validates every spec
        if len(set(names)) != len(names):
            raise RoadweaverError(
                f"two densities give the same scenario name {_first_repeat(names)!r}; "
                "use densities that differ in the first 6 digits"
            )

    def scenarios(self) -> list[ScenarioSpec]:
        """One spec per (density, style, seed); every other field is the same for all."""
        shared = {f.name: getattr(self, f.name) for f in fields(self)
                  if f.name not in ("densities", "styles", "seeds", "min_coverage")}
        return [ScenarioSpec(density=d, style=style, seed=s,
                             **shared | {"vehicle_mix": dict(self.vehicle_mix),
                                         "speeds": dict(self.speeds),
                                         "junction_mix": dict(self.junction_mix),
                                         "lanes": dict(self.lanes)})
                for d in self.densities for style in self.styles for s in self.seeds]

    def to_dict(self) -> dict:
        """The fields, lists for tuples; the :data:`~roadweaver_sumo.spec.UNSAID` values left
        out, and the ego route fields unless the suite has some, so that manifests of suites
        without them read as before."""
        data = asdict(self)
        for name, value in UNSAID.items():
            if data[name] == value:
                del data[name]
        if not self.ego_routes:
            del data["ego_routes"], data["ego_length"]
        if not self.min_coverage:
            del data["min_coverage"]
        return {k: list(v) if isinstance(v, tuple) else v for k, v in data.items()}

    @classmethod
    def from_dict(cls, data) -> SuiteSpec:
        """The suite of a manifest; a damaged one is a one-line error naming the field."""
        if not isinstance(data, dict):
            raise RoadweaverError("manifest: 'suite' must be an object")
        known = set(cls.__dataclass_fields__)
        unknown = sorted(set(data) - known)
        if unknown:
            raise RoadweaverError(f"manifest: unknown suite field {unknown[0]!r}")
        values = {**LEGACY, **data}
        for name in ("densities", "styles", "seeds"):
            if not isinstance(values.get(name), list):
                raise RoadweaverError(f"manifest: suite field {name!r} must be a list")
            values[name] = tuple(values[name])
        try:
            return cls(**values)
        except TypeError as exc:
            raise RoadweaverError(f"manifest: bad suite: {exc}") from None


def _normalise(suite: SuiteSpec) -> None:
    """Whole numbers given for float fields become floats (10 -> 10.0): spec.json, report.json
    and the manifest then read the same whether the suite came from the CLI or from Python."""

    def as_float(value):
        is_number = isinstance(value, (int, float)) and not isinstance(value, bool)
        return float(value) if is_number else value  # anything else: ScenarioSpec says why

    for name in ("width", "height", "duration", "ego_length", "fringe_factor", "one_way_share"):
        object.__setattr__(suite, name, as_float(getattr(suite, name)))
    if isinstance(suite.densities, tuple):
        object.__setattr__(suite, "densities", tuple(as_float(d) for d in suite.densities))


def parse_densities(text: str) -> tuple[float, ...]:
    """``"10,20,30"`` -> (10.0, 20.0, 30.0) road nodes per km²."""
    values = []
    for item in _items(text, "--densities"):
        try:
            value = float(item)
        except ValueError:
            raise RoadweaverError(f"--densities: {item!r} is not a number") from None
        if not math.isfinite(value) or value <= 0:
            raise RoadweaverError(f"--densities: {item!r} must be a number > 0")
        values.append(value)
    return tuple(values)


def parse_styles(text: str) -> tuple[str, ...]:
    """``"grid,organic"`` -> ("grid", "organic"); the names are checked by ``ScenarioSpec``."""
    return tuple(_items(text, "--styles"))


def parse_seeds(text: str) -> tuple[int, ...]:
    """``"0-9"``, ``"0,3,7"`` or ``"0-3,10"`` -> the seeds in the order given."""
    seeds: list[int] = []
    for item in _items(text, "--seeds"):
        match = re.fullmatch(r"(\d+)(?:-(\d+))?", item)
        if not match:
            raise RoadweaverError(f"--seeds: {item!r} is not a seed (0) or a range (0-9)")
        lo, hi = int(match.group(1)), int(match.group(2) or match.group(1))
        if hi < lo:
            raise RoadweaverError(f"--seeds: range {item!r} runs backwards")
        if hi - lo + 1 + len(seeds) > MAX_SCENARIOS:
            raise RoadweaverError(f"--seeds {text!r} lists more than {MAX_SCENARIOS} seeds")
        seeds.extend(range(lo, hi + 1))
    return tuple(seeds)


def _items(text: str, option: str) -> list[str]:
    items = [item.strip() for item in str(text).split(",")]
    if not any(items):
        raise RoadweaverError(f"{option} must list at least one value")
    if not all(items):
        raise RoadweaverError(f"{option} {text!r} has an empty item")
    return items


def _first_repeat(values) -> object:
    seen = set()
    for value in values:
        if value in seen:
            return value
        seen.add(value)
    return None
