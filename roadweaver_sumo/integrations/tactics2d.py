"""Load our lanelet2 ``lanelet2_map.osm`` into Tactics2D (PyPI ``tactics2d``, GPL-3.0) with lane topology.

Tactics2D's ``OSMParser(lanelet2=True)`` reads lanelets, lines and regulatory elements but fills
no successor, predecessor or neighbour sets, so its ``Router`` has nothing to plan on (NOTES.md).
:func:`load_tactics2d_map` parses the file and then adds the lane graph: from the HD map when one
is given, otherwise from the file's own lanelet2 topology (shared end/start nodes for
successors, shared boundary ways for neighbours), which the writer builds from the same HD map.
The two agree by construction (tests/test_lanelet2.py checks the file side).

Traps handled here: ``Lane.add_related_lane`` silently ignores an ``int`` id (lanelet ids are
ints), so ids go in as lists; without a projection the parser uses a flat-earth approximation
around the first node, so we pass the writer's transverse Mercator explicitly.
``Router.plan`` builds its routing graph anew on every call (seconds on a 2 km map):
:func:`plan_routes` plans many tasks on one graph.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING
from unittest import mock

from ..export.lanelet2 import LANE_TAG
from ..hdmap.model import HDMap
from ..spec import ScenarioSpec
from ..validate.lanelet2_check import osm_lane_relations

if TYPE_CHECKING:
    from tactics2d.map.element import Map
    from tactics2d.routing import Route, Router

MAP_FILE = "lanelet2_map.osm"
SPEC_FILE = "spec.json"


def load_tactics2d_map(source: str | Path, hd: HDMap | None = None,
                       origin: tuple[float, float] | None = None) -> Map:
    """Parse a scenario folder's ``lanelet2_map.osm`` (or that file itself) into a Tactics2D ``Map``
    whose lanes carry successor, predecessor and left/right neighbour sets, so that
    ``tactics2d.routing.Router`` plans on it.

    ``origin`` (lat, lon) of the local frame comes from ``hd``, else this argument, else the
    ``spec.json`` next to the map; local coordinates then equal the HD map's, in metres."""
    try:
        from tactics2d.map.parser import OSMParser
    except ImportError:
        raise ImportError("load_tactics2d_map needs Tactics2D: pip install tactics2d "
                          "(GPL-3.0; see docs/lanelet2.md for a separate venv)") from None
    osm = Path(source) / MAP_FILE if Path(source).is_dir() else Path(source)
    origin = _origin(osm, hd, origin)
    lat, lon = origin
    configs = {"project_rule": {"proj": "tmerc", "lat_0": lat, "lon_0": lon, "k": 1,
                                "x_0": 0, "y_0": 0, "ellps": "WGS84"},
               "gps_origin": (lon, lat)}
    map_ = OSMParser(lanelet2=True).parse(str(osm), configs=configs)
    relations = hd_lane_relations(hd) if hd is not None else osm_lane_relations(osm)
    add_lane_relations(map_, relations)
    return map_


def _origin(osm: Path, hd: HDMap | None, origin) -> tuple[float, float]:
    if hd is not None and hd.geo_origin is not None:
        return tuple(hd.geo_origin)
    if origin is not None:
        return tuple(origin)
    spec = osm.parent / SPEC_FILE
    if spec.exists():
        return tuple(ScenarioSpec.from_json_file(spec).geo_origin)
    raise ValueError(f"no geo origin for {osm}: pass hd or origin=(lat, lon), or keep "
                     f"{SPEC_FILE} next to it")


def hd_lane_relations(hd: HDMap) -> dict[str, dict[str, list[str]]]:
    """The HD map's lane graph, per lane id: successors, predecessors, left and right."""
    return {lane.id: {"successors": sorted(lane.successors),
                      "predecessors": sorted(lane.predecessors),
                      "left": [lane.left_neighbour] if lane.left_neighbour else [],
                      "right": [lane.right_neighbour] if lane.right_neighbour else []}
            for lane in hd.lanes.values()}


def add_lane_relations(map_: Map, relations: dict[str, dict[str, list[str]]]) -> None:
    """Fill the Tactics2D lanes' relation sets from ``relations`` (keyed by our lane ids, which
    each lanelet carries in its ``roadweaver:lane`` tag)."""
    from tactics2d.map.element import LaneRelationship

    kinds = {"successors": LaneRelationship.SUCCESSOR,
             "predecessors": LaneRelationship.PREDECESSOR,
             "left": LaneRelationship.LEFT_NEIGHBOR, "right": LaneRelationship.RIGHT_NEIGHBOR}
    t2d_id = {lane.custom_tags.get(LANE_TAG): lid for lid, lane in map_.lanes.items()
              if lane.custom_tags}
    missing = sorted(set(relations) - set(t2d_id))
    if missing or len(t2d_id) != len(relations):
        raise ValueError(f"the map has {len(t2d_id)} tagged lanes for {len(relations)} lanes of "
                         f"the lane graph (missing e.g. {missing[:3]}): not the same map?")
    for lane_id, related in relations.items():
        lane = map_.lanes[t2d_id[lane_id]]
        for key, kind in kinds.items():
            # a list: add_related_lane drops a bare int id without a word
            lane.add_related_lane([t2d_id[other] for other in related[key]], kind)


def plan_routes(map_: Map, tasks: Sequence[tuple[Sequence[float], Sequence[float]]],
                router: Router | None = None) -> list[Route]:
    """``router.plan(map_, start, goal)`` for every ``(start, goal)`` task, on one graph.

    ``Router.plan`` rebuilds its routing graph (``GraphBuilder.build``) on every call, which
    dominates its time on 2 km maps. Here the first call builds it with the router's own
    settings and the later calls reuse it; everything else is Tactics2D's own ``Router.plan``.
    """
    from tactics2d.routing import Router
    from tactics2d.routing.graph_builder import GraphBuilder

    router = Router() if router is None else router
    build, built = GraphBuilder.build, []

    def build_once(builder, graph_map):
        if graph_map is not map_:
            return build(builder, graph_map)
        if not built:
            built.append(build(builder, graph_map))
        return built[0]

    with mock.patch.object(GraphBuilder, "build", build_once):
        return [router.plan(map_, start, goal) for start, goal in tasks]
