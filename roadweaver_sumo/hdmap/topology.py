"""The directed lane graph: successor links, topology repair and lane-level metrics (paper
Algorithm 1: AddSuccessorLinks, RepairTopology; metrics as defined in DESIGN.md).

Reachability lets vehicles follow successor links and change between neighbour lanes of the
same driving direction. Strong connectivity is computed on a sparse matrix (scipy), and
reachability from the condensation of the strongly connected components, never all-pairs search.
"""

from __future__ import annotations

import networkx as nx
import numpy as np
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import connected_components

from .junctions import add_connectors
from .model import DIRECTIONS, HDMap, Lane


def link_connector(hd: HDMap, connector: Lane) -> None:
    """Record ``connector`` as successor of its incoming and predecessor of its outgoing lane."""
    for pred in connector.predecessors:
        hd.lanes[pred].successors.append(connector.id)
    for succ in connector.successors:
        hd.lanes[succ].predecessors.append(connector.id)


def _sort_links(hd: HDMap) -> None:
    """Sort every successor and predecessor list, so output never depends on build order."""
    for lane in hd.lanes.values():
        lane.successors.sort()
        lane.predecessors.sort()


def add_successor_links(hd: HDMap) -> None:
    """Link every connector into the lane graph."""
    for connector in hd.connectors():
        link_connector(hd, connector)
    _sort_links(hd)


def lane_graph(hd: HDMap) -> tuple[list[str], csr_matrix]:
    """Lane ids (sorted) and the adjacency matrix of successor and lane-change links."""
    ids = sorted(hd.lanes)
    index = {lane_id: i for i, lane_id in enumerate(ids)}
    targets = [[*lane.successors, *filter(None, (lane.left_neighbour, lane.right_neighbour))]
               for lane in map(hd.lanes.__getitem__, ids)]
    src = np.repeat(np.arange(len(ids)), list(map(len, targets)))
    dst = [index[t] for lane_targets in targets for t in lane_targets]
    data = np.ones(len(src), dtype=np.int8)
    return ids, csr_matrix((data, (src, dst)), shape=(len(ids), len(ids)))


def _components(hd: HDMap) -> tuple[list[str], int, np.ndarray, np.ndarray]:
    """Lane ids, number of strong components, each lane's component label and the
    condensation's edges as (k, 2) label pairs."""
    ids, graph = lane_graph(hd)
    n_comp, labels = connected_components(graph, directed=True, connection="strong")
    coo = graph.tocoo()
    a, b = labels[coo.row], labels[coo.col]
    cross = a != b
    return ids, n_comp, labels, np.unique(np.column_stack([a[cross], b[cross]]), axis=0)


def _add_uturn(hd: HDMap, node: int, in_id: str, out_id: str) -> None:
    """Add and link one U-turn connector at ``node``, keeping the link lists it joins sorted
    (as ``add_successor_links`` left them all)."""
    for connector in add_connectors(hd, [(node, in_id, out_id, "uturn")]):
        link_connector(hd, connector)
        hd.lanes[in_id].successors.sort()
        hd.lanes[out_id].predecessors.sort()


def _uturns_for_closed_components(hd: HDMap) -> int:
    """Add one U-turn connector out of every sink and into every source component of the lane
    graph, where a road's two directions fall into different components. Returns how many."""
    ids, n_comp, labels, edges = _components(hd)
    if n_comp <= 1:
        return 0
    comp = dict(zip(ids, labels.tolist(), strict=True))
    sinks = set(range(n_comp)) - set(edges[:, 0].tolist())
    sources = set(range(n_comp)) - set(edges[:, 1].tolist())
    added = 0

    def uturn(node: int, in_id: str, out_id: str) -> None:
        nonlocal added
        _add_uturn(hd, node, in_id, out_id)
        sinks.discard(comp[in_id])  # the new link leaves this component...
        sources.discard(comp[out_id])  # ...and enters that one
        added += 1

    for rid in sorted(hd.roads):
        road = hd.roads[rid]
        if road.one_way:  # no reverse to turn into
            continue
        for direction, reverse in zip(DIRECTIONS, DIRECTIONS[::-1], strict=True):
            here, back = road.lanes(direction)[-1], road.lanes(reverse)[-1]  # leftmost lanes
            if comp[here] == comp[back]:
                continue
            if comp[here] in sinks:
                uturn(road.ends_at(direction), here, back)
            if comp[here] in sources:
                uturn(road.starts_at(direction), back, here)
    return added


def repair_topology(hd: HDMap) -> int:
    """Make the lane graph strongly connected with as few U-turns as needed (RepairTopology).

    With every non-U-turn movement built and turnarounds at dead ends, only graphs made of a
    single ring (no junction of degree >= 3) need this; each round adds U-turns where a road's
    two directions lie in different closed components. Returns the number of U-turns added.
    """
    total = 0
    for _ in range(2 * len(hd.roads) + 1):
        added = _uturns_for_closed_components(hd)
        if not added:
            break
        total += added
    return total


def lane_reachability(hd: HDMap) -> float:
    """Share of ordered pairs (u, v), u != v, of road lanes with a drivable directed path.

    Paths may run through connectors and change between same-direction neighbour lanes.
    """
    return _reachability(hd, *_components(hd))


def _reachability(hd: HDMap, ids, n_comp, labels, edges) -> float:
    """Each component's reachable road lanes are a bitset (Python int) OR-ed along the
    condensation DAG in reverse topological order."""
    is_road = np.array([hd.lanes[i].kind == "road" for i in ids])
    n = int(is_road.sum())
    if n < 2 or n_comp == 1:
        return 1.0
    sizes = np.bincount(labels[is_road], minlength=n_comp)
    starts = np.concatenate([[0], np.cumsum(sizes)[:-1]])  # road lanes numbered by component
    dag = nx.DiGraph()
    dag.add_nodes_from(range(n_comp))
    dag.add_edges_from(edges.tolist())
    reach = [0] * n_comp
    for c in reversed(list(nx.topological_sort(dag))):
        bits = ((1 << int(sizes[c])) - 1) << int(starts[c])
        for succ in dag.successors(c):
            bits |= reach[succ]
        reach[c] = bits
    pairs = sum(int(sizes[c]) * (reach[c].bit_count() - 1) for c in range(n_comp) if sizes[c])
    return pairs / (n * (n - 1))


def alignment_errors(hd: HDMap) -> np.ndarray:
    """Distance (m) between each lane's end and the start of every successor."""
    ends, starts = [], []
    for lane in hd.lanes.values():
        for succ in lane.successors:
            ends.append(lane.centre[-1])
            starts.append(hd.lanes[succ].centre[0])
    if not ends:
        return np.zeros(0)
    return np.linalg.norm(np.array(ends) - np.array(starts), axis=1)


def hdmap_metrics(hd: HDMap) -> dict:
    """Lane-level metrics of an HD map.

    ``lane_count`` counts road lanes and ``connector_count`` junction connector lanes;
    ``lane_reachability`` is over ordered pairs of road lanes; ``strongly_connected`` is for
    the whole lane graph; ``alignment_*_m`` summarise the distance between every lane's end
    and each successor's start (mean / p95 / max, metres).
    """
    errors = alignment_errors(hd)
    errors = errors if len(errors) else np.zeros(1)
    components = _components(hd)
    return {
        "lane_count": sum(1 for lane in hd.lanes.values() if lane.kind == "road"),
        "connector_count": sum(1 for lane in hd.lanes.values() if lane.kind == "connector"),
        "lane_reachability": _reachability(hd, *components),
        "strongly_connected": bool(components[1] == 1),
        "alignment_mean_m": float(errors.mean()),
        "alignment_p95_m": float(np.percentile(errors, 95)),
        "alignment_max_m": float(errors.max()),
    }
