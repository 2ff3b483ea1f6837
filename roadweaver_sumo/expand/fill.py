"""Density control (paper §III-C): fill the largest empty blocks with local roads until the
target is met.

Density is a closed loop (DESIGN.md): each round splits the largest block (a face of the planar
graph) with a local road traced through the same tensor field from the block's interior to its
boundary on both sides (:mod:`.chords`). A road across a face adds exactly its two T-junctions.
Some roads instead continue a side street across the block from a T-junction on its edge: that
T becomes a crossroads, as real streets run on through junctions (real tiles have 21 % four-way
junctions 100 m inside the tile; without continuations the fill makes T-junctions only), and the
road adds one node. The T may be one a road across the neighbouring block made after this block
was cut. The node count moves in steps of one or two, so it overshoots the target by at most
one. When there are too many road nodes, local roads that are not bridges are removed, those
whose removal leaves no corner first (:func:`prune_to_density`).
"""

from __future__ import annotations

import heapq
import math
from collections.abc import Callable
from functools import partial

import networkx as nx
import numpy as np
import shapely
from shapely.geometry import Polygon

from ..metrics import road_node_count
from ..roadgraph import edge_length, edge_list
from ..tensor_field import TensorField
from .block_split import split_face
from .chord_insert import insert_chord
from .chords import continuation_chord, scattered_chord, split_chord, straight_chord
from .edge_index import EdgeIndex
from .junction_angles import departure_angles
from .node_points import NodePoints
from .planar import road_lines

CONTINUE_SHARE = 0.5  # share of blocks first offered a continuation of a side street
#: Two roads left at a node run straight on when they deviate from a line by at most this,
#: measured BEND_PROBE_M out from the node.
BEND_TOL_DEG, BEND_PROBE_M = 30.0, 20.0


def faces(G: nx.Graph) -> list[Polygon]:
    """Bounded faces (blocks) of the planar road graph."""
    lines = road_lines(edge_list(G))  # one shapely call for all roads
    return [p for p in shapely.get_parts(shapely.polygonize(lines)) if p.area > 1.0]


def fill_to_density(
    G: nx.Graph,
    target: int,
    field: TensorField,
    rng: np.random.Generator,
    min_edge: float,
    min_angle: float,
    stub: float = 0.0,
    weight: Callable[[Polygon], float] | None = None,
) -> None:
    """Split blocks, largest first (and the blocks their splits make), until
    ``road_node_count(G) >= target`` or no block can be split, counting the road nodes as the
    clean-up will leave them (``stub``: see :func:`counted_change`)."""
    need = target - road_node_count(G)
    weight = weight or (lambda face: 1.0)
    heap = [(-f.area * weight(f), k, f)
            for k, f in enumerate(sorted(faces(G), key=lambda f: f.bounds))]
    heapq.heapify(heap)
    counter = len(heap)
    index = EdgeIndex(G)
    nodes = NodePoints(G)
    count = 0
    while heap and count < need:
        _, _, face = heapq.heappop(heap)
        ends = None
        makers = [partial(split_chord, roads=index), partial(straight_chord, roads=index),
                  partial(scattered_chord, roads=index)]
        if rng.random() < CONTINUE_SHARE:
            makers.insert(0, continuation_chord)
        for make_chord in makers:
            chord = make_chord(face, nodes, field, rng, min_edge, min_angle)
            if chord is not None:
                start = nodes.at(chord[0])
                ends = insert_chord(G, chord, min_edge, index, start_node=start)
                nodes.update()  # a refused chord may still have split a road at its first end
            if ends is not None:
                break
        if ends is None:
            continue
        # The other nodes a chord may create (a shape node, a split point before the chord
        # reaches it) have degree 2: not counted.
        count += sum(counted_change(G, n, stub) for n in ends)
        for part in split_face(face, chord, ends, index):
            heapq.heappush(heap, (-part.area * weight(part), counter, part))
            counter += 1


def counted_change(G: nx.Graph, end, stub: float) -> int:
    """How a chord ending at node ``end`` changes the road-node count, as the clean-up after
    the fill will leave it. The chord adds one to the node's degree. Where it cut a dead-end
    road less than ``stub`` from its end, the clean-up prunes that tip, a counted dead end, and
    the node keeps one road fewer: a junction on a road again, not counted. (Counting such ends
    as new junctions lost 3.5 % of a learned 10 km map's road nodes to the clean-up, and a
    second density round had to make them up.)"""
    degree = G.degree(end)
    tips = sum(1 for w in G.neighbors(end)
               if G.degree(w) == 1 and edge_length(G, end, w) < stub)
    return ((degree - tips) != 2) - ((degree - 1) != 2) - tips


def stub_loss(G: nx.Graph, stub: float) -> int:
    """The road nodes the clean-up's stub pruning will remove: every dead-end road shorter than
    ``stub`` (its end, a counted dead end) and, where that leaves two roads at the junction it
    hangs from, that junction too (see :func:`counted_change`)."""
    loss = 0
    for n in G.nodes:
        degree = G.degree(n)
        if degree < 2:
            continue
        tips = sum(1 for w in G.neighbors(n)
                   if G.degree(w) == 1 and edge_length(G, n, w) < stub)
        loss += tips + (degree != 2) - ((degree - tips) != 2) if tips else 0
    return loss


def prune_to_density(G: nx.Graph, target: int, stub: float = 0.0,
                     spare: Callable[[int, int], bool] | None = None) -> None:
    """Remove non-bridge local roads while above ``target`` + 1 road nodes (counted as the
    clean-up will leave them: :func:`stub_loss`). ``spare(u, v)`` says whether the map holds
    together without road u-v (default: it is not a bridge of ``G``).

    Roads whose removal leaves no bend go first (:func:`pruning_order`): the clean-up joins
    the two roads left at a former T-junction into one, and where they met at a right angle
    that road has a corner. Pruning shortest first made such corners the commonest bend of
    our maps (issue 35: learned maps turned 3.4 rad/km, real tiles 2.3, and the excess was
    corners). A road's order is taken again when its turn comes, since removing a neighbour
    may have changed it; removing a road only lowers degrees and only turns roads into
    bridges, so a road that cannot go now never can."""
    count = road_node_count(G) - stub_loss(G, stub)
    spare = spare or partial(on_cycle, G)
    heap = [(pruning_order(G, u, v), u, v) for u, v in G.edges
            if G.edges[u, v]["road_class"] != "arterial"]
    heapq.heapify(heap)
    while heap and count > target + 1:
        order, u, v = heapq.heappop(heap)
        if G.degree(u) < 3 or G.degree(v) < 3 or not spare(u, v):
            continue
        now = pruning_order(G, u, v)
        if now != order:
            heapq.heappush(heap, (now, u, v))
            continue
        G.remove_edge(u, v)
        count += sum((G.degree(n) != 2) - (G.degree(n) + 1 != 2) for n in (u, v))


def pruning_order(G: nx.Graph, u, v) -> tuple[int, int, float]:
    """Sort key of road u-v among the roads to prune: how many bends its removal leaves at
    its ends (:func:`bend_left`), how many crossroads it turns into T-junctions, then the
    longest first: removing short roads first left real towns' short links out (learned maps'
    shortest tenth of roads began at 49 m, real tiles' at 33 m)."""
    bends = int(bend_left(G, u, v)) + int(bend_left(G, v, u))
    crossroads = int(G.degree(u) == 4) + int(G.degree(v) == 4)
    return bends, crossroads, -edge_length(G, u, v)


def bend_left(G: nx.Graph, n, gone) -> bool:
    """Whether node ``n`` is left with two roads that do not run straight on (within
    :data:`BEND_TOL_DEG`) once its road to ``gone`` is removed."""
    if G.degree(n) != 3:
        return False
    a, b = (angle for angle, w in departure_angles(G, n, BEND_PROBE_M) if w != gone)
    return abs((a - b) % (2 * math.pi) - math.pi) > math.radians(BEND_TOL_DEG)


def on_cycle(G: nx.Graph, u, v) -> bool:
    """Whether u and v stay connected without the road u-v (it is not a bridge): a
    bidirectional breadth-first search, which stays local around a road on a small cycle."""
    seen = ({u}, {v})
    fronts = ([u], [v])
    while fronts[0] and fronts[1]:
        side = 0 if len(fronts[0]) <= len(fronts[1]) else 1
        nxt = []
        for a in fronts[side]:
            for b in G.neighbors(a):
                if {a, b} == {u, v}:
                    continue
                if b in seen[1 - side]:
                    return True
                if b not in seen[side]:
                    seen[side].add(b)
                    nxt.append(b)
        fronts[side][:] = nxt
    return False
