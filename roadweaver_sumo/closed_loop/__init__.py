"""Closed-loop evaluation (issue 37): ego routes, a controller loop over libsumo, a driving
score. ``rw.closed_loop.run(scenario_dir, controller, route=K)`` drives one route."""

from .drive import naive_controller, observe, run
from .routes import pick_ego_routes, read_ego_routes
from .score import driving_score

__all__ = ["driving_score", "naive_controller", "observe", "pick_ego_routes",
           "read_ego_routes", "run"]
