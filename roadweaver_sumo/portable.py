"""Floats that come out the same on every x86-64 CPU, so that a map does too.

numpy picks its transcendental kernels (``sin``, ``cos``, ``arctan2``, ``exp``) by the CPU's
vector extensions, and BLAS its matrix kernels, so their results differ in the last bits from
one CPU model to another. Most of the generator does not care, but wherever it *chooses*
(the best of near-equal candidates, a ray's first hit, a rounding to the noding grid) a last
bit can tip the choice and the whole map after it changes. Rounding the few quantities that
every later choice reads, to far below anything that matters, turns last-bit differences into
exact ties broken the same way everywhere (DESIGN.md: "the same spec gives the same bytes on one
machine; across CPUs ... tolerances").
"""

from __future__ import annotations

import numpy as np

#: Decimals kept: direction cosines and field components are O(1); 1e-9 is far below any
#: angle the generator resolves, far above the 1e-16 of a last-bit difference.
DECIMALS = 9


#: Decimals kept of what float32 networks compute (the decoded road field): their kernels
#: differ in the 7th significant digit from one CPU to another.
FLOAT32_DECIMALS = 4


def portable(values, decimals: int = DECIMALS) -> np.ndarray:
    """``values`` as float64 rounded to ``decimals`` decimals (IEEE multiply, round and
    divide only: the same bits on every CPU)."""
    return np.round(np.asarray(values, dtype=np.float64), decimals)
