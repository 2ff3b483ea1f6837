"""Stage 1: the skeleton of principal roads, learned (default) or procedural."""

from ..errors import RoadweaverError
from ..spec import ScenarioSpec
from .model import Skeleton
from .procedural import procedural_skeleton


def make_skeleton(spec: ScenarioSpec) -> Skeleton:
    """The skeleton of the town the map is cut out of (``ScenarioSpec.town``)."""
    spec = spec.town()
    if spec.skeleton == "learned":
        from .learned import learned_skeleton

        return learned_skeleton(spec)
    if spec.skeleton == "procedural":
        return procedural_skeleton(spec)
    raise RoadweaverError(f"unknown skeleton {spec.skeleton!r}")


__all__ = ["Skeleton", "make_skeleton"]
