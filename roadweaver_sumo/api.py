"""The Python API: the command line's stages as functions that return objects.

``import roadweaver_sumo as rw`` gives these names (loaded on first use, so that importing the
package stays cheap)::

    spec = rw.ScenarioSpec(density=30, vehicles=500, seed=1)
    hd = rw.generate_map(spec)             # HDMap; hd.graph is the road graph (networkx)
    files = rw.write_map(hd, "out/map")    # plain XML, map.xodr, lanelet2_map.osm, map.net.xml
    scenario = rw.make_scenario(spec, "out/scenario")   # the folder make-scenario writes
    figures = rw.evaluate(scenario.net)    # our metrics of any SUMO net
    city = rw.measure_city("my-town.osm.pbf")  # then ScenarioSpec(..., like=city): a map like it
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

from .hdmap.model import HDMap
from .spec import ScenarioSpec


@dataclass(frozen=True)
class Report:
    """A scenario's ``report.json``: the verdict, the failed thresholds and every figure."""

    passed: bool
    failures: list[str]
    figures: dict = field(repr=False)

    def __getitem__(self, dotted: str):
        """A figure by its dotted name, e.g. ``report["net.lane_reachability"]``."""
        value = self.figures
        for part in dotted.split("."):
            value = value[part]
        return value


@dataclass(frozen=True)
class Scenario:
    """A scenario folder (the output contract of ``make-scenario``) and its report."""

    folder: Path
    spec: ScenarioSpec
    report: Report | None  # None when built without validation

    @property
    def sumocfg(self) -> Path:
        return self.folder / "scenario.sumocfg"

    @property
    def net(self) -> Path:
        return self.folder / "map.net.xml"

    @property
    def opendrive(self) -> Path:
        return self.folder / "map.xodr"

    @property
    def lanelet2(self) -> Path:
        return self.folder / "lanelet2_map.osm"

    @property
    def demand(self) -> Path:
        return self.folder / "demand.rou.xml"


def generate_map(spec: ScenarioSpec) -> HDMap:
    """The lane-level HD map of ``spec`` (skeleton, expansion, HD map; paper §III).

    Parameters
    ----------
    spec : ScenarioSpec
        What to generate; only the map fields (size, density, style, skeleton, seed, geo
        origin, priors, ``like``: :func:`measure_city`) matter here.

    Returns
    -------
    HDMap
        Roads, junctions and lanes; ``.graph`` is the road graph as a ``networkx.Graph``
        (node attribute ``xy``, edge attributes ``coords`` and ``road_class``).
    """
    from .expand import expand_skeleton
    from .hdmap import build_hdmap_for
    from .skeleton import make_skeleton

    if spec.like:
        from .like import closest_map

        graph = closest_map(spec)[1]
    else:
        graph = expand_skeleton(spec, make_skeleton(spec))
    return build_hdmap_for(graph, spec)


def write_map(hdmap: HDMap, folder: str | Path, template: str = "urban") -> dict[str, Path]:
    """Write ``hdmap`` into ``folder`` in every format: SUMO plain XML, ``map.net.xml``
    (netconvert with the packaged ``template``, written beside it as ``netconvert.netccfg``),
    then ``map.xodr`` (OpenDRIVE 1.7) and ``lanelet2_map.osm`` with the right of way SUMO
    decided (the connectors of ``hdmap`` carry it afterwards).

    Returns
    -------
    dict
        Paths by format: ``plain``, ``opendrive``, ``lanelet2``, ``sumo``.
    """
    from .export.map_files import write_map_files

    return write_map_files(hdmap, Path(folder), template)


def make_scenario(spec: ScenarioSpec, folder: str | Path, *, force: bool = False,
                  validate: bool = True) -> Scenario:
    """Build the scenario folder of ``spec`` as ``roadweaver-sumo make-scenario`` does.

    An existing ``folder`` is replaced only with ``force``; with ``validate`` the libsumo run
    and the checks fill ``Scenario.report`` (``report.passed``, ``report.failures``).
    """
    from .pipeline import make_scenario as build

    result = build(spec, Path(folder), force=force, validate=validate)
    report = None
    if result.report is not None:
        report = Report(result.report["passed"], list(result.report["failures"]), result.report)
    return Scenario(result.out_dir, spec, report)


def evaluate(net_path: str | Path, area_km2: float | None = None) -> dict:
    """Our metrics (DESIGN.md "Metrics") of any SUMO network, by the code that judges ours;
    the area is the net's ``convBoundary`` unless given (km²)."""
    from .validate.evaluate import evaluate_net

    return json.loads(json.dumps(evaluate_net(Path(net_path), area_km2)))
