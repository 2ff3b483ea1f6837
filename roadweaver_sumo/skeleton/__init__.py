"""Stage 1: the skeleton of principal roads (procedural now; the learned model plugs in here)."""

from ..errors import RoadweaverError
from ..spec import ScenarioSpec
from .model import Skeleton
from .procedural import procedural_skeleton


def make_skeleton(spec: ScenarioSpec) -> Skeleton:
    if spec.skeleton == "procedural":
        return procedural_skeleton(spec)
    raise RoadweaverError(f"unknown skeleton {spec.skeleton!r}")


__all__ = ["Skeleton", "make_skeleton"]
