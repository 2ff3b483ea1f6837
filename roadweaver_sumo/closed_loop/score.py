"""The driving score of a closed-loop run (issue 37), in the spirit of CARLA Leaderboard's:
route completion times a penalty factor per infraction.

Factors follow the Leaderboard (collision with a person 0.50, with a vehicle 0.60, red light
0.70, stop sign 0.80, agent blocked 0.70); speeding, which the Leaderboard does not score, costs
0.90 per episode above the limit, and leaving the route ends the run with factor 0.70 (the
Leaderboard ends it too). Every infraction names its time, place and the rule element.
"""

from __future__ import annotations

import math

PENALTY = {"collision_person": 0.50, "collision": 0.60, "red_light": 0.70, "stop_sign": 0.80,
           "blocked": 0.70, "off_route": 0.70, "speeding": 0.90, "teleport": 0.70}
#: speeding is over the limit by more than this share plus SPEED_MARGIN_MS, for at least
#: SPEEDING_MIN_S (a stack that holds the limit is never caught by rounding)
SPEED_TOLERANCE, SPEED_MARGIN_MS, SPEEDING_MIN_S = 0.10, 0.5, 1.0


def driving_score(route_completion: float, infractions: list[dict]) -> dict:
    """``route_completion`` (0-1) x the product of the infractions' penalty factors, with every
    factor given."""
    factor = math.prod(PENALTY[i["type"]] for i in infractions)
    counts: dict[str, int] = {}
    for i in infractions:
        counts[i["type"]] = counts.get(i["type"], 0) + 1
    return {"route_completion": round(route_completion, 4), "penalty": round(factor, 6),
            "score": round(route_completion * factor, 4), "infraction_counts": counts,
            "penalty_factors": PENALTY}


def over_limit(speed: float, limit: float) -> bool:
    return speed > limit * (1 + SPEED_TOLERANCE) + SPEED_MARGIN_MS
