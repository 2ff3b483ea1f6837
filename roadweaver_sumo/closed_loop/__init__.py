"""Closed-loop evaluation (issue 37): ego routes, a controller loop over libsumo or TraCI, a
driving score, and a controller over a whole suite. ``rw.closed_loop.run(scenario_dir,
controller, route=K)`` drives one route; ``drive_suite(suite_dir, controller)`` every route of
a suite, ``compare_scores(old, new)`` says what changed."""

from .drive import naive_controller, observe, run
from .routes import pick_ego_routes, read_ego_routes
from .score import driving_score
from .suite_drive import compare_scores, drive_suite

__all__ = ["compare_scores", "drive_suite", "driving_score", "naive_controller", "observe",
           "pick_ego_routes", "read_ego_routes", "run"]
