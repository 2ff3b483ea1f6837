"""numba-compiled functions, cached on disk where possible.

Every compiled function has an explicit signature, so numba compiles it (or, after the first
run, loads it from its cache) when its module is imported, as a C extension is loaded, rather
than inside the first map's generation. The cache goes next to the package or, where that is
read-only, into the user's cache directory; where neither can be written (a read-only
container, say), numba refuses to cache at all, and the function is then compiled afresh in
every process (a few seconds) instead of failing the import.
"""

from __future__ import annotations

import numba as nb
from numba import njit

F8, I8 = nb.float64, nb.int64
F8_1D, F8_2D, I8_1D, I8_2D = F8[::1], F8[:, ::1], I8[::1], I8[:, ::1]


def compiled(signature, **options):
    """``numba.njit(signature, cache=True, **options)``, or uncached where no cache can be
    written."""

    def decorate(function):
        try:
            return njit(signature, cache=True, **options)(function)
        except RuntimeError as error:  # "cannot cache function ...: no locator available"
            if "cannot cache" not in str(error):
                raise
            return njit(signature, **options)(function)

    return decorate
