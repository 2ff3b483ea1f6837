"""Checkpoint files: the weights plus a JSON record of how they were trained.

A checkpoint is a numpy ``.npz`` archive: every weight as float16 (half the size; the shipped
pair stays well under 20 MB) under ``state/<name>``, and the record as JSON text under ``meta``.
Reading it needs numpy only, so sampling maps needs no torch (``inference.py``), and
``np.load(allow_pickle=False)`` never unpickles anything, so a checkpoint from elsewhere cannot
run code. torch is imported only to turn a checkpoint into a trainable module.
"""

from __future__ import annotations

import json
import os
import zipfile
from pathlib import Path

import numpy as np

from ..errors import RoadweaverError
from ..staging import remove_stale

WEIGHTS_DIR = Path(__file__).parent / "weights"
SHIPPED_VQVAE = WEIGHTS_DIR / "vqvae.npz"
SHIPPED_MASKGIT = WEIGHTS_DIR / "maskgit.npz"
STATE_PREFIX = "state/"


def save_checkpoint(path: Path, state: dict, meta: dict) -> None:
    """Write ``state`` (torch tensors or arrays) atomically: a hidden ``.NAME.partial-PID``
    file, then a rename, so a killed run leaves no half checkpoint under the real name, and
    the next save to the same path removes what a killed run left."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    remove_stale(path)
    arrays = {}
    for name, value in state.items():
        array = value.detach().cpu().numpy() if hasattr(value, "detach") else np.asarray(value)
        arrays[STATE_PREFIX + name] = (array.astype(np.float16)
                                       if np.issubdtype(array.dtype, np.floating) else array)
    arrays["meta"] = np.array(json.dumps(meta, sort_keys=True))
    tmp = path.with_name(f".{path.name}.partial-{os.getpid()}")
    with open(tmp, "wb") as out:  # a file object: np.savez would append ".npz" to a name
        np.savez(out, **arrays)
    os.replace(tmp, path)


def read_checkpoint(path: Path, kind: str) -> tuple[dict[str, np.ndarray], dict]:
    """The weights (floats as float32) and the training record of a ``kind`` checkpoint."""
    path = Path(path)
    if not path.is_file():
        raise RoadweaverError(f"checkpoint {path} not found")
    try:
        with np.load(path, allow_pickle=False) as archive:
            meta = json.loads(str(archive["meta"]))
            state = {name[len(STATE_PREFIX):]: archive[name] for name in archive.files
                     if name.startswith(STATE_PREFIX)}
    except (OSError, ValueError, KeyError, zipfile.BadZipFile) as exc:
        raise RoadweaverError(f"{path} is not a roadweaver-sumo checkpoint ({exc})") from None
    if meta.get("kind") != kind:
        raise RoadweaverError(f"{path} holds a {meta.get('kind')!r} model, expected {kind!r}")
    return {k: v.astype(np.float32) if np.issubdtype(v.dtype, np.floating) else v
            for k, v in state.items()}, meta


def load_vqvae(path: Path = SHIPPED_VQVAE):
    """The checkpoint as a torch ``VQVAE`` module (for training and evaluation) and its record."""
    from .settings import VQVAEConfig
    from .vqvae import VQVAE

    return _load_module(path, "vqvae", lambda config: VQVAE(VQVAEConfig(**config)))


def load_maskgit(path: Path = SHIPPED_MASKGIT):
    """The checkpoint as a torch ``MaskGIT`` module and its record."""
    from .maskgit import MaskGIT
    from .settings import MaskGITConfig

    return _load_module(path, "maskgit", lambda config: MaskGIT(MaskGITConfig(**config)))


def _load_module(path: Path, kind: str, build):
    """The module ``build(config)`` in eval mode with the checkpoint's weights, and its record;
    a checkpoint of another architecture is a one-line error."""
    import torch

    state, meta = read_checkpoint(path, kind)
    model = build(meta["config"])
    try:
        model.load_state_dict({k: torch.from_numpy(v) for k, v in state.items()})
    except RuntimeError:
        raise RoadweaverError(f"{path} does not fit this version's {type(model).__name__} "
                              "(trained by another version?): train it again") from None
    return model.eval(), meta
