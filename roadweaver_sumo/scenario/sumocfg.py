"""The scenario's ``scenario.sumocfg``: one file that ``sumo -c`` / ``sumo-gui -c`` runs as is.

Paths inside are relative; SUMO resolves them against the configuration file's own folder, so the
scenario runs from any working directory and the folder can be moved or zipped.
"""

from __future__ import annotations

from pathlib import Path

from lxml import etree

from ..errors import RoadweaverError
from .bus_lines import ROUTES_FILE as BUS_ROUTES_FILE
from .bus_lines import STOPS_FILE as BUS_STOPS_FILE
from .demand import DEMAND_FILE
from .persons import PERSONS_FILE
from .signal_plans import OFFSETS_FILE
from .xmlfile import write_xml

SUMOCFG_FILE = "scenario.sumocfg"
NET_FILE = "map.net.xml"
# The simulation runs this long after the last departure so that late cars can arrive: an hour
# covers a drive across any map we generate (18 km at a congested 5 m/s). Runs stop as soon as
# every car has arrived, so the margin costs nothing on a healthy scenario.
END_MARGIN_S = 3600.0
TIME_TO_TELEPORT_S = 300

_SCHEMA = "http://sumo.dlr.de/xsd/sumoConfiguration.xsd"
_XSI = "http://www.w3.org/2001/XMLSchema-instance"


def end_time(duration: float) -> float:
    """The configured simulation end for a demand spread over [0, duration)."""
    return float(duration) + END_MARGIN_S


def write_sumocfg(out_dir: Path, *, duration: float, seed: int, persons: bool = False,
                  buses: bool = False, coordinated: bool = False) -> Path:
    """Write ``out_dir/scenario.sumocfg`` (deterministic bytes) and return its path.

    Collisions only warn (and are counted in the statistics) so a validation run sees all of
    them; junction collisions are checked too, because that is where bad geometry shows (and
    where cars meet pedestrians on crossings). ``persons``: the walks of ``persons.rou.xml``
    are loaded too; ``buses``: the bus lines and their stops; ``coordinated``: the lights'
    green-wave offsets.
    """
    if duration <= 0:
        raise RoadweaverError(f"sumocfg: duration must be > 0 s, got {duration}")
    additional = ",".join([BUS_STOPS_FILE] * buses + [OFFSETS_FILE] * coordinated)
    sections = {
        "input": {"net-file": NET_FILE,
                  "route-files": ",".join([DEMAND_FILE] + [PERSONS_FILE] * persons
                                          + [BUS_ROUTES_FILE] * buses),
                  **({"additional-files": additional} if additional else {})},
        "time": {"begin": "0", "end": _number(end_time(duration))},
        "processing": {
            "time-to-teleport": str(TIME_TO_TELEPORT_S),
            "collision.action": "warn",
            "collision.check-junctions": "true",
        },
        "random_number": {"seed": str(int(seed))},
        "report": {"no-step-log": "true"},
    }
    root = etree.Element("configuration", nsmap={"xsi": _XSI})
    root.set(f"{{{_XSI}}}noNamespaceSchemaLocation", _SCHEMA)
    for section, options in sections.items():
        element = etree.SubElement(root, section)
        for name, value in options.items():
            etree.SubElement(element, name, value=value)
    return write_xml(root, Path(out_dir) / SUMOCFG_FILE)


def _number(value: float) -> str:
    """``3600`` rather than ``3600.0`` when whole: what a user would type."""
    return str(int(value)) if float(value).is_integer() else repr(float(value))
