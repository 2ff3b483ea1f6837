"""roadweaver-sumo: lane-level road networks generated from scratch, as validated SUMO scenarios."""

__version__ = "0.1.0"
