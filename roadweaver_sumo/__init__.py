"""roadweaver-sumo: lane-level road networks generated from scratch, as validated SUMO scenarios.

``import roadweaver_sumo as rw``: ``rw.ScenarioSpec``, ``rw.generate_map``, ``rw.write_map``,
``rw.make_scenario``, ``rw.evaluate``, ``rw.measure_city`` (see :mod:`roadweaver_sumo.api`),
``rw.closed_loop.run``. They are imported on first use, so that the command line starts
without loading what it does not run.
"""

__version__ = "0.1.0"

_API = {"ScenarioSpec": "spec", "HDMap": "hdmap.model", "Scenario": "api", "Report": "api",
        "generate_map": "api", "write_map": "api", "make_scenario": "api", "evaluate": "api",
        "measure_city": "like"}
__all__ = ["HDMap", "Report", "Scenario", "ScenarioSpec", "__version__", "closed_loop",
           "evaluate", "generate_map", "make_scenario", "measure_city", "write_map"]


def __getattr__(name: str):
    from importlib import import_module

    if name == "closed_loop":
        return import_module(".closed_loop", __name__)
    if name not in _API:
        raise AttributeError(f"module 'roadweaver_sumo' has no attribute {name!r}")
    return getattr(import_module(f".{_API[name]}", __name__), name)
