"""Green waves (issue 36, "junction control"): the offsets of the fixed-time lights
coordinated along the routes the traffic takes, in ``tls_offsets.add.xml``.

Every light netconvert builds starts its cycle at 0 s, so a car that got green at one light
meets the next at a random point of its cycle: nothing a driving stack would meet on a real
arterial, where lights along a corridor are timed so that a platoon keeps green. SUMO's
``tlsCoordinator.py`` does that timing: from the routes of the demand it finds the pairs of
lights that traffic passes one after the other and sets each light's offset so that green
follows the travel time between them (Greenshields free flow). The lights keep fixed-time
programs: vehicle-actuated ones (shorter phases where an arterial meets a collector) let a
car turn left while a bus still cleared the junction, a collision in one of 50 sweep
scenarios.
"""

from __future__ import annotations

from pathlib import Path

from lxml import etree

from ..sumo_tools import python_tool, run, strip_generated_comment
from .demand import DEMAND_FILE

OFFSETS_FILE = "tls_offsets.add.xml"


def coordinate_lights(folder: Path, net_file: str = "map.net.xml") -> dict:
    """Write ``folder/tls_offsets.add.xml`` (a coordinated offset per traffic light) from the
    net and the demand in ``folder``; return the lights by program type and how many got an
    offset. No file where the net has fewer than two lights."""
    folder = Path(folder)
    programs = {}
    for _, logic in etree.iterparse(str(folder / net_file), tag="tlLogic"):
        programs[logic.get("id")] = logic.get("type")
        logic.clear()
    figures = {kind: sum(1 for t in programs.values() if t == kind)
               for kind in sorted(set(programs.values()))}
    if len(programs) < 2:
        return {"programs": figures, "coordinated": 0}
    run([*python_tool("tlsCoordinator.py"), "-n", net_file, "-r", DEMAND_FILE,
         "-o", OFFSETS_FILE], folder, "tlsCoordinator.py")
    strip_generated_comment(folder / OFFSETS_FILE)
    offsets = etree.parse(str(folder / OFFSETS_FILE)).getroot().findall("tlLogic")
    return {"programs": figures, "coordinated": len(offsets)}
