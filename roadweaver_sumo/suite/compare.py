"""Compare two builds of one scenario file with tolerances: real drift or floating-point noise?

The same spec gives the same bytes on one machine. On another CPU, numpy's and BLAS's kernels
round differently in the last bits, and numbers written with many decimals (OpenDRIVE lengths
and headings, lanelet2 latitudes) differ in their last digits although the map is the same. So
a file whose bytes differ is compared as text with its numbers taken out: anything but numbers
must be equal, and each number within :func:`tolerance` of its counterpart. A picture is
compared pixel by pixel.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import NamedTuple

import numpy as np

#: Numbers within 0.1 mm or a relative 1e-7, whichever is larger (coordinates, lengths and
#: offsets in metres, headings in radians). lanelet2_map.osm holds degrees: within 1e-9° (0.1 mm).
ABS_TOL, REL_TOL, DEGREE_TOL = 1e-4, 1e-7, 1e-9
#: A preview may differ in this share of its pixels (antialiasing of a line moved by noise).
PIXEL_SHARE = 0.002

_NUMBER = re.compile(r"[-+]?(?:\d+\.\d*|\.\d+|\d+)(?:[eE][-+]?\d+)?")


class Comparison(NamedTuple):
    same: bool  # within tolerance
    detail: str  # where the first real difference is, or the largest deviation in noise


def compare_files(new: Path, old: Path) -> Comparison:
    """Whether ``new`` equals ``old`` up to floating-point noise, and how it differs."""
    new, old = Path(new), Path(old)
    if new.suffix == ".png":
        return _compare_pictures(new, old)
    try:
        a, b = new.read_text(encoding="utf-8"), old.read_text(encoding="utf-8")
    except UnicodeDecodeError:
        return Comparison(new.read_bytes() == old.read_bytes(), "binary file differs")
    if new.name.endswith(".osm"):
        return compare_texts(a, b, DEGREE_TOL, 0.0)
    return compare_texts(a, b)


def compare_texts(new: str, old: str, abs_tol: float = ABS_TOL,
                  rel_tol: float = REL_TOL) -> Comparison:
    """Line by line: the text between numbers equal, the numbers within tolerance."""
    new_lines, old_lines = new.splitlines(), old.splitlines()
    if len(new_lines) != len(old_lines):
        return Comparison(False, f"{len(new_lines)} lines, before {len(old_lines)}")
    worst = 0.0
    for number, (a, b) in enumerate(zip(new_lines, old_lines, strict=True), start=1):
        if a == b:
            continue
        if _NUMBER.sub("#", a) != _NUMBER.sub("#", b):
            return Comparison(False, f"line {number}: {_clip(a)} (before: {_clip(b)})")
        words_a, words_b = _NUMBER.findall(a), _NUMBER.findall(b)
        x, y = np.array(words_a, dtype=float), np.array(words_b, dtype=float)
        deviation = np.abs(x - y)
        limit = np.maximum(abs_tol, rel_tol * np.maximum(np.abs(x), np.abs(y)))
        if (deviation > limit).any():
            k = int(np.argmax(deviation - limit))
            return Comparison(False, f"line {number}: {words_a[k]} against {words_b[k]}, beyond the "
                                     f"tolerance {limit[k]:.1e}: {_clip(a)}")
        worst = max(worst, float(deviation.max()))
    return Comparison(True, f"numbers differ by at most {worst:.1e}")


def _compare_pictures(new: Path, old: Path) -> Comparison:
    from matplotlib.image import imread

    a, b = imread(new), imread(old)
    if a.shape != b.shape:
        return Comparison(False, f"picture of {a.shape[1]}x{a.shape[0]} pixels, before "
                                 f"{b.shape[1]}x{b.shape[0]}")
    share = float(np.any(np.abs(a - b) > 1 / 255, axis=-1).mean())
    return Comparison(share <= PIXEL_SHARE, f"{100 * share:.2f} % of the pixels differ")


def _clip(line: str, width: int = 100) -> str:
    line = line.strip()
    return line if len(line) <= width else line[: width - 3] + "..."


#: Figures of report.json are rounded to 6 decimals; noise may tip the last one.
FIGURE_TOL = 2e-6


def same_figure(a, b) -> bool:
    """Two report figures equal up to the last rounded decimal (booleans and strings exactly)."""
    if isinstance(a, bool) or isinstance(b, bool):
        return a is b
    if not (isinstance(a, (int, float)) and isinstance(b, (int, float))):
        return a == b
    return abs(a - b) <= max(FIGURE_TOL, FIGURE_TOL * max(abs(a), abs(b)))
