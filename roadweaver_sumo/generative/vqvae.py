"""VQ-VAE over the 6-channel road field F (paper §III-B): F -> a grid of discrete tokens -> F.

The encoder downsamples by 8 (a 128 x 128 tile becomes 16 x 16 positions, one per 125 m). Each
position is quantised by ``groups`` independent codebooks (product quantisation): one code of K
cannot describe the one-pixel road lines crossing an 8 x 8 patch precisely enough, two codes of
K give K² combinations at the cost of one more token per position for the transformer.
Everything is convolutional, so a token canvas of any size decodes in one pass without seams.
"""

from __future__ import annotations

import torch
import torch.nn.functional as F
from torch import nn

from .settings import VQVAE_CONFIG, VQVAEConfig

#: Input scaling: orientation channels span [-1, 1], the others [0, 1].
N_CHANNELS = 6
ROAD, COS2, SIN2, JUNCTION, ENDPOINT, DISTANCE = range(6)


class ResBlock(nn.Module):
    def __init__(self, ch: int):
        super().__init__()
        self.body = nn.Sequential(nn.GroupNorm(8, ch), nn.SiLU(), nn.Conv2d(ch, ch, 3, padding=1),
                                  nn.GroupNorm(8, ch), nn.SiLU(), nn.Conv2d(ch, ch, 3, padding=1))

    def forward(self, x):
        return x + self.body(x)


class Encoder(nn.Module):
    def __init__(self, cfg: VQVAEConfig):
        super().__init__()
        w = cfg.width
        self.net = nn.Sequential(
            nn.Conv2d(N_CHANNELS, w, 4, stride=2, padding=1), ResBlock(w),
            nn.Conv2d(w, 2 * w, 4, stride=2, padding=1), ResBlock(2 * w),
            nn.Conv2d(2 * w, 4 * w, 4, stride=2, padding=1), ResBlock(4 * w), ResBlock(4 * w),
            nn.GroupNorm(8, 4 * w), nn.SiLU(), nn.Conv2d(4 * w, cfg.groups * cfg.code_dim, 1),
        )

    def forward(self, x):
        return self.net(x)


class Decoder(nn.Module):
    def __init__(self, cfg: VQVAEConfig):
        super().__init__()
        w = cfg.width
        self.net = nn.Sequential(
            nn.Conv2d(cfg.groups * cfg.code_dim, 4 * w, 3, padding=1),
            ResBlock(4 * w), ResBlock(4 * w),
            nn.ConvTranspose2d(4 * w, 2 * w, 4, stride=2, padding=1), ResBlock(2 * w),
            nn.ConvTranspose2d(2 * w, w, 4, stride=2, padding=1), ResBlock(w),
            nn.ConvTranspose2d(w, w, 4, stride=2, padding=1),
            nn.SiLU(), nn.Conv2d(w, N_CHANNELS, 3, padding=1),
        )

    def forward(self, z):
        return self.net(z)


class GroupedQuantizer(nn.Module):
    """``groups`` codebooks of ``codebook_size`` unit vectors; nearest-code lookup per group
    with a straight-through gradient, plus the VQ-VAE codebook and commitment losses.

    Encoder outputs and codes are compared on the unit sphere (cosine distance, as in
    ViT-VQGAN): the lookup cannot be won by a code's length, so far more of each codebook
    stays in use.
    """

    def __init__(self, cfg: VQVAEConfig):
        super().__init__()
        self.cfg = cfg
        self.codebooks = nn.Parameter(torch.randn(cfg.groups, cfg.codebook_size, cfg.code_dim))

    def split(self, z: torch.Tensor) -> torch.Tensor:
        """(B, G*D, H, W) -> unit vectors (B, H, W, G, D)."""
        B, _, H, W = z.shape
        zs = z.permute(0, 2, 3, 1).reshape(B, H, W, self.cfg.groups, self.cfg.code_dim)
        return F.normalize(zs, dim=-1)

    def unquantised(self, z: torch.Tensor) -> torch.Tensor:
        """Encoder output on the unit sphere per group, in the decoder's layout (warm start)."""
        B, _, H, W = z.shape
        return self.split(z).reshape(B, H, W, -1).permute(0, 3, 1, 2)

    def codes(self) -> torch.Tensor:
        return F.normalize(self.codebooks, dim=-1)

    def indices(self, z: torch.Tensor) -> torch.Tensor:
        """Token ids (B, H, W, G) of encoder output z: the code of highest cosine."""
        zs = self.split(z).unsqueeze(-2)  # (B, H, W, G, 1, D)
        return (zs @ self.codes().transpose(1, 2)).squeeze(-2).argmax(-1)

    def lookup(self, idx: torch.Tensor) -> torch.Tensor:
        """Token ids (B, H, W, G) -> quantised latent (B, G*D, H, W)."""
        g = torch.arange(self.cfg.groups, device=idx.device)
        q = self.codes()[g, idx]  # (B, H, W, G, D)
        B, H, W = idx.shape[:3]
        return q.reshape(B, H, W, -1).permute(0, 3, 1, 2)

    def forward(self, z: torch.Tensor):
        idx = self.indices(z)
        q = self.lookup(idx)
        zn = self.unquantised(z)
        codebook_loss = F.mse_loss(q, zn.detach())
        commitment = F.mse_loss(zn, q.detach())
        q_st = zn + (q - zn).detach()
        return q_st, idx, codebook_loss, self.cfg.beta * commitment


class VQVAE(nn.Module):
    def __init__(self, cfg: VQVAEConfig = VQVAE_CONFIG):
        super().__init__()
        self.cfg = cfg
        self.encoder = Encoder(cfg)
        self.quantizer = GroupedQuantizer(cfg)
        self.decoder = Decoder(cfg)

    def forward(self, x):
        z = self.encoder(x)
        q, idx, codebook_loss, commitment = self.quantizer(z)
        return self.decoder(q), idx, codebook_loss, commitment

    @torch.no_grad()
    def encode(self, x: torch.Tensor) -> torch.Tensor:
        """Fields (B, 6, H, W) -> tokens (B, H/8, W/8, G)."""
        return self.quantizer.indices(self.encoder(x))

    @torch.no_grad()
    def decode(self, idx: torch.Tensor) -> torch.Tensor:
        """Tokens (B, h, w, G) -> field (B, 6, 8h, 8w) in the value ranges of F."""
        return to_field(self.decoder(self.quantizer.lookup(idx)))


def to_field(logits: torch.Tensor) -> torch.Tensor:
    """Decoder output -> F: sigmoid for the [0, 1] channels, tanh for the orientation pair."""
    out = torch.sigmoid(logits)
    out[:, COS2:SIN2 + 1] = torch.tanh(logits[:, COS2:SIN2 + 1])
    return out


def reconstruction_loss(logits: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
    """Binary cross-entropy on the probability-like channels (road, junction, endpoint,
    distance) and squared error on the orientation pair. Road pixels are a fifth of a tile and
    one pixel wide, so they are weighted up: a decoder that blurs them away must pay for it."""
    probs = [ROAD, JUNCTION, ENDPOINT, DISTANCE]
    bce = F.binary_cross_entropy_with_logits(logits[:, probs], target[:, probs], reduction="none")
    weight = torch.ones_like(bce)
    weight[:, 0] += 4.0 * target[:, ROAD]
    weight[:, 1] += 4.0 * target[:, JUNCTION]
    weight[:, 2] += 4.0 * target[:, ENDPOINT]
    orient = F.mse_loss(torch.tanh(logits[:, COS2:SIN2 + 1]), target[:, COS2:SIN2 + 1])
    return (weight * bce).mean() + 4.0 * orient


def road_iou(pred: torch.Tensor, target: torch.Tensor, threshold: float = 0.5) -> float:
    """Intersection over union of road pixels (road channel >= threshold) over a batch."""
    p, t = pred[:, ROAD] >= threshold, target[:, ROAD] >= threshold
    union = (p | t).sum().item()
    return (p & t).sum().item() / union if union else 1.0
