"""Option texts of the command line read into the values a spec holds: a size, a geo origin
and lists of named numbers (``--vehicle-mix``, ``--speed``, ``--lanes``, ``--junction-mix``).
A text that does not read is a one-line error naming the form expected; whether the values are
allowed is the spec's to say (``spec.ScenarioSpec``)."""

from __future__ import annotations

import re

from .errors import RoadweaverError


def parse_geo_origin(text: str) -> tuple[float, float]:
    """``"48.137,11.575"`` -> (48.137, 11.575): latitude, longitude in degrees."""
    try:
        lat, lon = (float(v) for v in str(text).split(","))
    except ValueError:
        raise RoadweaverError(f"--geo-origin {text!r} is not LAT,LON in degrees, e.g. "
                              "52.52,13.405") from None
    return lat, lon


def parse_vehicle_mix(text: str) -> dict[str, float]:
    """``"passenger:0.9,truck:0.1"`` -> {"passenger": 0.9, "truck": 0.1}; checked by the spec."""
    return _named_numbers(text, "--vehicle-mix", ":", "class:share, e.g. truck:0.1")


def parse_speeds(text: str) -> dict[str, float]:
    """``"arterial=60,local=30"`` -> {"arterial": 60.0, "local": 30.0} km/h; checked by the
    spec."""
    return _named_numbers(text, "--speed", "=", "class=km/h, e.g. arterial=60")


def parse_lanes(text: str) -> dict[str, float]:
    """``"arterial=3,local=1"`` -> {"arterial": 3, "local": 1}: whole numbers as ints (so that
    spec.json writes 3, not 3.0), others left for the spec to refuse."""
    counts = _named_numbers(text, "--lanes", "=", "class=lanes, e.g. arterial=3")
    return {name: int(n) if n.is_integer() else n for name, n in counts.items()}


def parse_junction_mix(text: str) -> dict[str, float]:
    """``"traffic_light=0.2,allway_stop=0.3"`` -> shares; checked by the spec."""
    return _named_numbers(text, "--junction-mix", "=", "control=share, e.g. allway_stop=0.3")


def _named_numbers(text: str, option: str, sep: str, form: str) -> dict[str, float]:
    """Comma-separated ``name<sep>number`` items as {name: number}; a malformed item is a
    one-line error saying the ``form`` expected."""
    found = {}
    for item in str(text).split(","):
        name, _, value = item.strip().partition(sep)
        try:
            found[name] = float(value)
        except ValueError:
            raise RoadweaverError(f"{option}: {item.strip()!r} is not {form}") from None
    return found


def parse_size(text: str) -> tuple[float, float]:
    """``"2000"`` -> (2000, 2000); ``"3000x2000"`` -> (3000, 2000), metres."""
    match = re.fullmatch(r"\s*([0-9.eE+]+)\s*(?:[xX]\s*([0-9.eE+]+))?\s*", str(text))
    if not match:
        raise RoadweaverError(f"--size {text!r} is not a size; use e.g. 2000 or 3000x2000 (metres)")
    try:
        width = float(match.group(1))
        height = float(match.group(2)) if match.group(2) else width
    except ValueError:
        raise RoadweaverError(f"--size {text!r} is not a size; use e.g. 2000 or 3000x2000") from None
    return width, height
