"""MaskGIT-style masked transformer over the VQ-VAE token grid, conditioned on c by AdaLN.

Every block modulates its two layer norms with a scale, a shift and a residual gate computed
from the condition embedding (adaLN-Zero, Peebles & Xie 2023), so c reaches every layer rather
than only the input. Training masks a cosine-scheduled share of positions; sampling starts from
an all-masked grid (or one with some positions fixed, for in-painting) and, over a few steps,
keeps the most confident predictions (Chang et al. 2022). With ``guidance`` > 0 the logits are
pushed away from the unconditional prediction (classifier-free guidance), which sharpens what
the condition asks for. This module trains; maps are sampled by the same arithmetic in numpy
(``inference.MaskGITSampler``), which needs no torch.

The ``groups`` tokens of one position are strongly dependent (given the first, the second has
3.6 nats of entropy instead of 6.0 on the training tiles), so they are predicted as a chain,
not independently: the head of group g also sees the embedded tokens of groups < g at the same
position (the true ones in training, the sampled ones in decoding). Independent draws would
pair codes that never occur together and decode to broken patches.
"""

from __future__ import annotations

import math

import torch
from torch import nn

from .settings import MASKGIT_CONFIG, MaskGITConfig

N_CONDITION = 11


def cosine_mask_ratio(r: torch.Tensor) -> torch.Tensor:
    """Share of masked positions at progress r in [0, 1): cos(π r / 2) (MaskGIT's schedule)."""
    return torch.cos(0.5 * math.pi * r)


class AdaLNBlock(nn.Module):
    def __init__(self, cfg: MaskGITConfig):
        super().__init__()
        d = cfg.dim
        self.norm1 = nn.LayerNorm(d, elementwise_affine=False)
        self.attn = nn.MultiheadAttention(d, cfg.heads, dropout=cfg.dropout, batch_first=True)
        self.norm2 = nn.LayerNorm(d, elementwise_affine=False)
        self.mlp = nn.Sequential(nn.Linear(d, 4 * d), nn.GELU(), nn.Dropout(cfg.dropout),
                                 nn.Linear(4 * d, d))
        self.modulation = nn.Linear(d, 6 * d)
        nn.init.zeros_(self.modulation.weight)  # adaLN-Zero: each block starts as identity
        nn.init.zeros_(self.modulation.bias)

    def forward(self, x: torch.Tensor, c: torch.Tensor) -> torch.Tensor:
        s1, b1, g1, s2, b2, g2 = self.modulation(c).unsqueeze(1).chunk(6, dim=-1)
        h = self.norm1(x) * (1 + s1) + b1
        x = x + g1 * self.attn(h, h, h, need_weights=False)[0]
        h = self.norm2(x) * (1 + s2) + b2
        return x + g2 * self.mlp(h)


class MaskGIT(nn.Module):
    def __init__(self, cfg: MaskGITConfig = MASKGIT_CONFIG):
        super().__init__()
        self.cfg = cfg
        d, G, K = cfg.dim, cfg.groups, cfg.codebook_size
        self.token_embed = nn.ModuleList(nn.Embedding(K, d) for _ in range(G))
        self.mask_embed = nn.Parameter(torch.zeros(d))
        self.row_embed = nn.Parameter(torch.randn(cfg.grid, d) * 0.02)
        self.col_embed = nn.Parameter(torch.randn(cfg.grid, d) * 0.02)
        self.cond_mlp = nn.Sequential(nn.Linear(N_CONDITION, d), nn.SiLU(), nn.Linear(d, d))
        self.null_cond = nn.Parameter(torch.zeros(d))
        self.blocks = nn.ModuleList(AdaLNBlock(cfg) for _ in range(cfg.depth))
        self.final_norm = nn.LayerNorm(d, elementwise_affine=False)
        self.final_mod = nn.Linear(d, 2 * d)
        nn.init.zeros_(self.final_mod.weight)
        nn.init.zeros_(self.final_mod.bias)
        self.chain_embed = nn.ModuleList(nn.Embedding(K, d) for _ in range(G - 1))
        self.heads = nn.ModuleList(nn.Linear(d, K) for _ in range(G))

    def condition(self, cond: torch.Tensor, drop: torch.Tensor | None = None) -> torch.Tensor:
        """Standardised c (B, 11) -> embedding (B, dim); dropped rows get the null embedding."""
        e = self.cond_mlp(cond)
        if drop is not None:
            e = torch.where(drop[:, None], self.null_cond.expand_as(e), e)
        return e

    def forward(self, tokens: torch.Tensor, mask: torch.Tensor, cond: torch.Tensor,
                drop: torch.Tensor | None = None) -> torch.Tensor:
        """tokens (B, n, G) with n = grid², mask (B, n) True where hidden -> logits (B, n, G, K),
        group g's logits given the true tokens of groups < g (teacher forcing)."""
        h = self.trunk(tokens, mask, cond, drop)
        return torch.stack([self.group_logits(h, gi, tokens[..., :gi])
                            for gi in range(self.cfg.groups)], dim=2)

    def group_logits(self, h: torch.Tensor, gi: int, earlier: torch.Tensor) -> torch.Tensor:
        """Logits (B, n, K) of group ``gi`` from trunk features h and the tokens (B, n, gi) of
        the groups before it at the same positions."""
        for gj in range(gi):
            h = h + self.chain_embed[gj](earlier[..., gj])
        return self.heads[gi](h)

    def trunk(self, tokens: torch.Tensor, mask: torch.Tensor, cond: torch.Tensor,
              drop: torch.Tensor | None = None) -> torch.Tensor:
        """Transformer features (B, n, dim) of every position."""
        n = tokens.shape[1]
        x = sum(emb(tokens[..., gi]) for gi, emb in enumerate(self.token_embed))
        x = torch.where(mask[..., None], self.mask_embed.expand_as(x), x)
        pos = (self.row_embed[:, None, :] + self.col_embed[None, :, :]).reshape(-1, self.cfg.dim)
        x = x + pos[:n]
        c = self.condition(cond, drop)
        for block in self.blocks:
            x = block(x, c)
        scale, shift = self.final_mod(c).unsqueeze(1).chunk(2, dim=-1)
        return self.final_norm(x) * (1 + scale) + shift
