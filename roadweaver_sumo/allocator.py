"""glibc's allocator told to keep the memory a map generation frees, for its next arrays.

A map allocates and frees arrays of 0.1-50 MB thousands of times (the transformer's passes on
two threads, the decoder's layers, the raster fields). By default glibc hands such a block back
to the kernel when it is freed (above its mmap threshold, which starts at 128 kB and rises only
as large blocks are freed, and by trimming the heaps of the worker threads), and the next array
gets fresh pages, each costing a page fault on first touch: about 4 µs on these virtual
machines, where a learned 10 km map took 100,000-120,000 faults in its skeleton stage. Fixed
thresholds at the largest values glibc's own adjustment reaches (32 MiB to map a block of its
own, twice that to trim) keep the freed memory for reuse. The command line sets them when it
starts (``cli.main``), before any map; a program that imports the package may call
:func:`keep_freed_memory` itself. Learned 10 km maps, seeds 0-2, four alternating rounds:
generation 0.28 s faster (median of the twelve pairs; 10 of 12 faster), the skeleton stage
0.26 s.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import sys

M_TRIM_THRESHOLD, M_MMAP_THRESHOLD = -1, -3  # glibc's malloc.h
MMAP_THRESHOLD = 32 * 2**20  # glibc's DEFAULT_MMAP_THRESHOLD_MAX on 64-bit systems
TRIM_THRESHOLD = 2 * MMAP_THRESHOLD  # what glibc's adjustment sets with the mmap threshold


def keep_freed_memory() -> bool:
    """Set the thresholds in this process (and the children it forks later); False where the C
    library is not glibc (mallopt then does not exist or means something else)."""
    if not sys.platform.startswith("linux"):
        return False
    try:
        libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6")
        libc.gnu_get_libc_version  # noqa: B018 - only glibc has it
    except (OSError, AttributeError):
        return False
    return bool(libc.mallopt(M_MMAP_THRESHOLD, MMAP_THRESHOLD)
                and libc.mallopt(M_TRIM_THRESHOLD, TRIM_THRESHOLD))
