"""Sweeping the nodes of the road graph until a clean-up pass settles (paper §III-C).

Passes such as dropping a road at a too sharp junction or pruning a stub decide a node from its
own roads alone, so after the first sweep only the nodes whose roads changed need another look.
"""

from __future__ import annotations

import heapq


def sweep_nodes(nodes, visit) -> None:
    """Visit ``nodes`` in order, and again every node that ``visit`` (which returns the nodes
    whose roads it changed) touches: later in the same sweep if it comes after the node
    visited, else in the next sweep; until a sweep touches no node it already passed."""
    todo = sorted(nodes)  # a sorted list is a heap
    while todo:
        queued, again = set(todo), set()
        while todo:
            n = heapq.heappop(todo)
            for m in visit(n):
                if m <= n:
                    again.add(m)  # already visited in this sweep: the next one
                elif m not in queued:
                    heapq.heappush(todo, m)
                    queued.add(m)
        todo = sorted(again)
