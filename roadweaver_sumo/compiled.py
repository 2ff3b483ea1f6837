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
F8_2D_ANY = F8[:, :]  # any layout: reversed or sliced views of coordinate arrays
B1, U1 = nb.boolean, nb.uint8
B1_1D, B1_2D, U1_1D = B1[::1], B1[:, ::1], U1[::1]
U1_1D_CONST = nb.types.Array(U1, 1, "C", readonly=True)  # a module-level array, read-only
F4 = nb.float32
F4_1D, F4_2D, F4_3D = F4[::1], F4[:, ::1], F4[:, :, ::1]


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
