"""The lane-level HD map: plain dataclasses that every exporter reads (paper Algorithm 1 output M).

Conventions shared by all exporters, so that none of them re-derives topology:

* A *road* is one RoadGraph edge. Its reference line is the full centreline from ``from_node`` to
  ``to_node``; its single lane section covers the part between the two junction trims.
* A road has two *driving directions*, written ``f`` (along the reference line) and ``b``
  (against it); ``edge_id(road, "f")`` is ``"r7_f"``, the SUMO edge id of that direction.
* Lanes are right-hand traffic: ``f`` lanes lie right of the reference line, ``b`` lanes left of it.
  Within a direction, index 0 is the rightmost (outermost) lane, like SUMO's lane index: the
  sidewalk where the road has one (driving lanes 1..n), else the outermost driving lane; a road
  lane's id is ``"<edge id>_<index>"``, which is also its SUMO lane id.
* Every polyline (lane centre and boundaries) runs in the lane's driving direction.
* Junction *connector lanes* (``"j12_3"``) join one incoming lane's end to one outgoing lane's
  start; they are lanes of the same directed lane graph (successor / predecessor links).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

MOVEMENTS = ("right", "straight", "left", "uturn")
DIRECTIONS = ("f", "b")


def edge_id(road: int, direction: str) -> str:
    """Id of one driving direction of a road, e.g. ``"r7_f"`` (also the SUMO edge id)."""
    return f"r{road}_{direction}"


def road_lane_id(road: int, direction: str, index: int) -> str:
    """Id of a road lane, e.g. ``"r7_f_0"`` (also the SUMO lane id)."""
    return f"{edge_id(road, direction)}_{index}"


@dataclass
class Lane:
    """One lane of the directed lane graph: a road lane or a junction connector lane.

    ``width`` is the width at the lane's start and ``end_width`` at its end (equal on road lanes;
    a connector blends the widths of the two lanes it joins). Neighbour links join lanes of the
    same driving direction only (lane changes); ``left``/``right`` are the boundary polylines.
    """

    id: str
    kind: str  # "road" or "connector"
    road_class: str
    width: float
    end_width: float
    speed: float  # m/s
    centre: np.ndarray  # (n, 2) in driving direction
    left: np.ndarray  # (n, 2) left boundary
    right: np.ndarray  # (n, 2) right boundary
    road: int | None = None  # road lanes: road id
    direction: str | None = None  # road lanes: "f" or "b"
    index: int = 0  # road lanes: 0 = rightmost lane of its direction
    junction: int | None = None  # connectors: node id
    movement: str | None = None  # connectors: one of MOVEMENTS
    bezier: np.ndarray | None = None  # connectors: (4, 2) cubic Bezier control points
    #: U-turn connectors: their half circle (one ``reference.Piece``), instead of ``bezier``
    plan: list | None = None
    successors: list[str] = field(default_factory=list)
    predecessors: list[str] = field(default_factory=list)
    left_neighbour: str | None = None
    right_neighbour: str | None = None
    #: connectors, once SUMO has built the net (``hdmap.right_of_way``): SUMO's link state
    #: letter, the traffic light controlling the link, the connectors it must yield to
    link_state: str | None = None
    traffic_light: str | None = None
    yields_to: list[str] = field(default_factory=list)

    @property
    def edge(self) -> str | None:
        """The driving direction (SUMO edge id) of a road lane, ``None`` for connectors."""
        return None if self.road is None else edge_id(self.road, self.direction)


@dataclass
class LaneSection:
    """Part ``[s_start, s_end]`` of a road's reference line that carries lanes (paper: lane
    section). Lane ids are listed rightmost first for each driving direction."""

    s_start: float
    s_end: float
    forward: list[str]
    backward: list[str]


@dataclass
class Road:
    """One road between two junctions, with its class-derived lane configuration."""

    id: int
    from_node: int
    to_node: int
    centreline: np.ndarray  # (n, 2) reference line, from_node -> to_node
    road_class: str
    priority: int
    speed: float
    lane_width: float
    #: driving lanes per direction (its class's, or ``--lanes``'), before a turn bay's
    lane_count: int
    sections: list[LaneSection]
    #: one-way roads (``hdmap.one_way``) run along their reference line: ``f`` lanes only,
    #: centred on it
    one_way: bool = False
    #: m; 0: no sidewalks. A sidewalk lies right of each driving direction (``HDMap.sidewalks``)
    sidewalk_width: float = 0.0
    #: the driving direction (``f`` or ``b``) that ends in a left-turn bay: one lane more than
    #: its class, the leftmost turning left at the light it arrives at (``hdmap.turn_bays``)
    bay: str | None = None
    #: lines and arcs of the reference line within the lane section (``hdmap.reference``)
    plan: list = field(default_factory=list)
    #: ``plan`` sampled: the points the lanes are offset from and their unit tangents
    reference: tuple[np.ndarray, np.ndarray] | None = None

    def lanes(self, direction: str) -> list[str]:
        """Lane ids of one driving direction, rightmost first (single lane section)."""
        section = self.sections[0]
        return section.forward if direction == "f" else section.backward

    def ends_at(self, direction: str) -> int:
        """The node a driving direction arrives at."""
        return self.to_node if direction == "f" else self.from_node

    def starts_at(self, direction: str) -> int:
        """The node a driving direction leaves from."""
        return self.from_node if direction == "f" else self.to_node


@dataclass
class Junction:
    """A RoadGraph node: its position, control type, trims and connector lanes."""

    id: int
    xy: tuple[float, float]
    type: str  # one of control.CONTROLS (SUMO's node types)
    trims: dict[int, float]  # road id -> how far from the centre its lanes end
    roads: list[int]  # incident roads, sorted
    connectors: list[str] = field(default_factory=list)
    #: where a turn bay opens (``hdmap.turn_bays``): the through lanes move aside in here
    taper: bool = False
    #: a roundabout's ring node (``hdmap.roundabouts``): the id of the junction it replaced
    roundabout: int | None = None

    @property
    def radius(self) -> float:
        """The largest trim: no lane of the junction's roads ends further out."""
        return max(self.trims.values())


@dataclass
class HDMap:
    """Roads, junctions and the directed lane graph (all lanes, keyed by id)."""

    width: float
    height: float
    roads: dict[int, Road] = field(default_factory=dict)
    junctions: dict[int, Junction] = field(default_factory=dict)
    lanes: dict[str, Lane] = field(default_factory=dict)
    #: sidewalks (``kind="sidewalk"``, index 0 of their direction), apart from the lane graph
    #: of vehicles: pedestrians cross junctions on SUMO's crossings and walking areas
    sidewalks: dict[str, Lane] = field(default_factory=dict)
    #: pedestrian crossings as SUMO built them (``hdmap.crossings``), once through netconvert
    crosswalks: list = field(default_factory=list)
    #: walking area -> the sidewalk and crossing ends it joins (``hdmap.crossings``)
    walking_areas: dict = field(default_factory=dict)
    geo_origin: tuple[float, float] | None = None  # (lat, lon) of the local origin (0, 0)
    graph: Any = field(default=None, repr=False)  # the RoadGraph (networkx) it was built from

    def road_lanes(self) -> list[Lane]:
        """Road lanes (not connectors), in id order."""
        return [self.lanes[k] for k in sorted(self.lanes) if self.lanes[k].kind == "road"]

    def connectors(self) -> list[Lane]:
        """Connector lanes, in junction order."""
        return [self.lanes[c] for j in sorted(self.junctions) for c in self.junctions[j].connectors]
