"""Lanes per direction by road class on request (``--lanes``, issue 36 "options in SUMO's
words": netgenerate's ``-L/--lanenumber`` gives every edge one count; ours is per class).

The expansion (paper §III-C) keeps roads a clearance apart for their classes' lanes
(:mod:`roadweaver_sumo.clearance`). A road given more lanes is wider: where it would then come
within another road's clearance it keeps its class's lanes, as a turn bay is left out where
its wider road would (``hdmap.turn_bays``), so that asking for lanes never makes lanes overlap.
Fewer lanes than the class's are always given.
"""

from __future__ import annotations

import networkx as nx

from .. import clearance  # a module: clearance imports hdmap.lanes, which loads this package
from .lanes import LANE_CONFIGS


def give_lanes(G: nx.Graph, lanes: dict[str, int] | None) -> nx.Graph:
    """``G`` with edge attribute ``lanes`` on every road of a class in ``lanes`` (class -> lanes
    per direction) that differs from its class's count and keeps its clearance with it; ``G``
    itself where nothing is asked."""
    asked = {c: n for c, n in (lanes or {}).items() if n != LANE_CONFIGS[c].lanes}
    if not asked:
        return G
    G = G.copy()
    widened = set()
    for u, v, data in G.edges(data=True):
        if data["road_class"] in asked:
            data["lanes"] = asked[data["road_class"]]
            if data["lanes"] > LANE_CONFIGS[data["road_class"]].lanes:
                widened.add((min(u, v), max(u, v)))
    while widened:
        crowded = clearance.crowded(G, {edge: edge for edge in widened})
        if not crowded:
            break
        for u, v in crowded:
            del G.edges[u, v]["lanes"]
        widened -= crowded
    return G
