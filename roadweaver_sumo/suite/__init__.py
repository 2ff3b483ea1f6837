"""Scenario suites: a grid of specs built into one folder with a manifest, and checked later
against it (``make-suite``, ``check-suite``)."""

from .build import SuiteResult, make_suite
from .check import check_suite, environment_note
from .grid import SuiteSpec, parse_densities, parse_seeds, parse_styles
from .manifest import MANIFEST_FILE, read_manifest
from .progress import Progress

__all__ = [
    "MANIFEST_FILE",
    "Progress",
    "SuiteResult",
    "SuiteSpec",
    "check_suite",
    "environment_note",
    "make_suite",
    "parse_densities",
    "parse_seeds",
    "parse_styles",
    "read_manifest",
]
