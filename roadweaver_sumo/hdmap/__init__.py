"""Stage 3: lane-level HD map construction (paper Algorithm 1).

``build_hdmap(G)`` turns a RoadGraph into an :class:`HDMap` (roads, lanes, junction connectors
and the directed lane graph); ``hdmap_metrics(hdmap)`` measures lane reachability, strong
connectivity and endpoint alignment.
"""

from .build import build_hdmap, build_hdmap_for
from .lanes import LANE_CONFIGS, LaneConfig
from .model import HDMap, Junction, Lane, LaneSection, Road, edge_id, road_lane_id
from .topology import hdmap_metrics, lane_reachability

__all__ = [
    "LANE_CONFIGS",
    "HDMap",
    "Junction",
    "Lane",
    "LaneConfig",
    "LaneSection",
    "Road",
    "build_hdmap",
    "build_hdmap_for",
    "edge_id",
    "hdmap_metrics",
    "lane_reachability",
    "road_lane_id",
]
