"""The allocator setting: memory a generation frees is kept for its next arrays."""

from __future__ import annotations

import subprocess
import sys

import pytest

ROUNDS = """
import resource, sys
import numpy as np
from roadweaver_sumo.allocator import keep_freed_memory
if sys.argv[1] == "keep":
    assert keep_freed_memory()
for _ in range(3):
    before = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
    arrays = [np.ones(2 * 2**20) for _ in range(3)]  # three 16 MB arrays, every page touched
    del arrays
    print(resource.getrusage(resource.RUSAGE_SELF).ru_minflt - before)
"""


def _faults(mode: str) -> list[int]:
    out = subprocess.run([sys.executable, "-c", ROUNDS, mode], capture_output=True, text=True,
                         check=True).stdout
    return [int(line) for line in out.split()]


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="glibc only")
def test_freed_arrays_are_reused_without_page_faults():
    """Three 16 MB arrays made and freed, three times over in a fresh process: by default
    glibc gives their memory back to the kernel every round (their 12,288 pages fault again);
    after ``keep_freed_memory`` the later rounds reuse it."""
    kept, default = _faults("keep"), _faults("default")
    assert max(kept[1:]) < 100, kept
    assert min(default[1:]) > 500, default
