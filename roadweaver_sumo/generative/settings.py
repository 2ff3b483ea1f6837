"""Model shapes and training settings, free of torch so the command line can show them.

The defaults are the settings of the shipped weights (``weights/MODEL_CARD.md``): sized so that
both models train on 2 CPU cores in about 40 minutes together.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass


@dataclass(frozen=True)
class VQVAEConfig:
    width: int = 32  # channels at the first (64 x 64) level; doubled per level
    codebook_size: int = 512
    groups: int = 3  # codes per position (held-out road IoU 0.81; 2 codes, 1,200 steps: 0.78)
    code_dim: int = 32
    beta: float = 0.25  # commitment weight

    def to_dict(self) -> dict:
        return asdict(self)


@dataclass(frozen=True)
class MaskGITConfig:
    dim: int = 128
    depth: int = 4  # v4: 6 blocks of 4 heads (v3) sampled half as fast, held-out loss 4.384
    heads: int = 2  # (here 4.367): the transformer's time is mostly per-head attention
    codebook_size: int = 512
    groups: int = 3
    grid: int = 16
    dropout: float = 0.1

    def to_dict(self) -> dict:
        return asdict(self)


@dataclass(frozen=True)
class TrainSettings:
    steps: int
    batch: int
    lr: float
    seed: int = 0
    crop: int = 0  # VQ-VAE: train on random crops of this many pixels (0 = whole tiles)
    threads: int = 2
    eval_every: int = 500


VQVAE_CONFIG = VQVAEConfig()
MASKGIT_CONFIG = MaskGITConfig()
VQVAE_SETTINGS = TrainSettings(steps=2400, batch=16, lr=1e-3, crop=64, eval_every=100)
MASKGIT_SETTINGS = TrainSettings(steps=1200, batch=32, lr=1e-3, eval_every=100)
#: Guidance distillation fine-tunes a trained transformer: a few hundred steps at a lower rate
#: (the shipped one's held-out cross-entropy to its guided teacher levelled off by step 300).
DISTIL_SETTINGS = TrainSettings(steps=400, batch=32, lr=3e-4, eval_every=50)
