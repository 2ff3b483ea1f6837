"""Python's cycle collector paused while many long-lived objects are built.

Generating a map and reading a SUMO net back with sumolib both allocate millions of small
objects that live to the end (graph attributes, polylines, lanes; sumolib's edges, lanes and
connections). The collector, triggered by allocation counts, walks all of them again and again,
a large share of the time these steps take on a large map. They make almost no reference cycles
that matter; reference counting frees everything else as before, and the collector catches any
cycles once it runs again.
"""

from __future__ import annotations

import gc
from collections.abc import Iterator
from contextlib import contextmanager


@contextmanager
def cyclic_gc_paused() -> Iterator[None]:
    """The cycle collector off inside the block, back on after it (also after an error) unless
    the caller had switched it off already."""
    was_enabled = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if was_enabled:
            gc.enable()
