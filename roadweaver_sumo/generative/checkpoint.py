"""Checkpoint files: a state dict plus a JSON record of how it was trained.

Weights are stored as float16 (half the size; the shipped pair stays well under 20 MB) and
loaded back as float32. ``torch.load(weights_only=True)`` never unpickles code, so a checkpoint
from elsewhere cannot run anything.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import torch

from ..errors import RoadweaverError
from .maskgit import MaskGIT, MaskGITConfig
from .vqvae import VQVAE, VQVAEConfig

WEIGHTS_DIR = Path(__file__).parent / "weights"
SHIPPED_VQVAE = WEIGHTS_DIR / "vqvae.pt"
SHIPPED_MASKGIT = WEIGHTS_DIR / "maskgit.pt"


def save_checkpoint(path: Path, state: dict, meta: dict) -> None:
    """Write atomically (temp file, then rename) so a killed run leaves no half checkpoint."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    half = {k: v.half() if v.is_floating_point() else v for k, v in state.items()}
    tmp = path.with_name(path.name + ".tmp")
    torch.save({"state": half, "meta": json.dumps(meta, sort_keys=True)}, tmp)
    os.replace(tmp, path)


def read_checkpoint(path: Path, kind: str) -> tuple[dict, dict]:
    path = Path(path)
    if not path.is_file():
        raise RoadweaverError(f"checkpoint {path} not found")
    try:
        blob = torch.load(path, map_location="cpu", weights_only=True)
        meta = json.loads(blob["meta"])
        state = {k: v.float() if v.is_floating_point() else v for k, v in blob["state"].items()}
    except Exception as exc:  # noqa: BLE001 - any unreadable file is the same user error
        raise RoadweaverError(f"{path} is not a roadweaver-sumo checkpoint ({exc})") from None
    if meta.get("kind") != kind:
        raise RoadweaverError(f"{path} holds a {meta.get('kind')!r} model, expected {kind!r}")
    return state, meta


def load_vqvae(path: Path = SHIPPED_VQVAE) -> tuple[VQVAE, dict]:
    state, meta = read_checkpoint(path, "vqvae")
    model = VQVAE(VQVAEConfig(**meta["config"]))
    _load_state(model, state, path)
    return model.eval(), meta


def load_maskgit(path: Path = SHIPPED_MASKGIT) -> tuple[MaskGIT, dict]:
    state, meta = read_checkpoint(path, "maskgit")
    model = MaskGIT(MaskGITConfig(**meta["config"]))
    _load_state(model, state, path)
    return model.eval(), meta


def _load_state(model: torch.nn.Module, state: dict, path: Path) -> None:
    """Weights into the model; a checkpoint of another architecture is a one-line error."""
    try:
        model.load_state_dict(state)
    except RuntimeError:
        raise RoadweaverError(f"{path} does not fit this version's {type(model).__name__} "
                              "(trained by another version?): train it again") from None
