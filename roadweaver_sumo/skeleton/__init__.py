"""Stage 1: the skeleton of principal roads, learned (default) or procedural."""

import warnings

from ..errors import RoadweaverError
from ..spec import ScenarioSpec
from .model import Skeleton
from .procedural import procedural_skeleton


class TorchMissingWarning(UserWarning):
    """The learned skeleton was asked for but torch is not installed."""


def torch_available() -> bool:
    try:
        import torch  # noqa: F401
    except ImportError:
        return False
    return True


def skeleton_generator(spec: ScenarioSpec) -> str:
    """The generator that will actually run: ``learned`` falls back to ``procedural``, with a
    warning, only when torch is missing."""
    if spec.skeleton == "learned" and not torch_available():
        warnings.warn("torch is not installed, so the procedural skeleton is used instead of "
                      "the learned one (pip install 'roadweaver-sumo[learned]')",
                      TorchMissingWarning, stacklevel=2)
        return "procedural"
    return spec.skeleton


def make_skeleton(spec: ScenarioSpec) -> Skeleton:
    generator = skeleton_generator(spec)
    if generator == "learned":
        from .learned import learned_skeleton

        return learned_skeleton(spec)
    if generator == "procedural":
        return procedural_skeleton(spec)
    raise RoadweaverError(f"unknown skeleton {spec.skeleton!r}")


__all__ = ["Skeleton", "TorchMissingWarning", "make_skeleton", "skeleton_generator"]
