"""MaskGIT-style masked transformer over the VQ-VAE token grid, conditioned on c by AdaLN.

Every block modulates its two layer norms with a scale, a shift and a residual gate computed
from the condition embedding (adaLN-Zero, Peebles & Xie 2023), so c reaches every layer rather
than only the input. Training masks a cosine-scheduled share of positions; sampling starts from
an all-masked grid (or one with some positions fixed, for in-painting) and, over a few steps,
keeps the most confident predictions (Chang et al. 2022). With ``guidance`` > 0 the logits are
pushed away from the unconditional prediction (classifier-free guidance), which sharpens what
the condition asks for.

The ``groups`` tokens of one position are strongly dependent (given the first, the second has
3.6 nats of entropy instead of 6.0 on the training tiles), so they are predicted as a chain,
not independently: the head of group g also sees the embedded tokens of groups < g at the same
position (the true ones in training, the sampled ones in decoding). Independent draws would
pair codes that never occur together and decode to broken patches.
"""

from __future__ import annotations

import math

import torch
import torch.nn.functional as F
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

    @torch.no_grad()
    def sample(self, cond: torch.Tensor, generator: torch.Generator, *, steps: int = 8,
               known: torch.Tensor | None = None, known_mask: torch.Tensor | None = None,
               temperature: float = 1.0, guidance: float = 1.0) -> torch.Tensor:
        """Iterative confidence-based decoding. ``cond`` (B, 11) standardised. ``known`` (B, n, G)
        tokens fixed where ``known_mask`` (B, n) is True (in-painting context). Returns (B, n, G).

        At step t the share cos(π t / 2T) of the still-unknown positions stays masked; the
        positions whose sampled tokens have the highest log-probability (plus annealed Gumbel
        noise, as in MaskGIT) are kept.
        """
        B = cond.shape[0]
        n, G = self.cfg.grid ** 2, self.cfg.groups
        tokens = torch.zeros(B, n, G, dtype=torch.long)
        fixed = torch.zeros(B, n, dtype=torch.bool)
        if known is not None:
            tokens = torch.where(known_mask[..., None], known, tokens)
            fixed = known_mask.clone()
        unknown0 = (~fixed).sum(dim=1)  # positions to generate, per row
        masked = ~fixed
        drop_all = torch.ones(B, dtype=torch.bool)
        for t in range(steps):
            if guidance > 0:  # conditional and unconditional rows in one batch
                h = self.trunk(tokens.repeat(2, 1, 1), masked.repeat(2, 1), cond.repeat(2, 1),
                               torch.cat([~drop_all, drop_all]))
                h_cond, h_free = h[:B][masked], h[B:][masked]
            else:
                h_cond, h_free = self.trunk(tokens, masked, cond)[masked], None
            choice, logp = self._sample_masked(h_cond, h_free, generator, guidance, temperature)
            conf = torch.zeros(B, n)
            conf[masked] = logp
            ratio = math.cos(0.5 * math.pi * (t + 1) / steps)
            keep_masked = torch.floor(unknown0.float() * ratio).long()  # per row
            anneal = 1.0 - (t + 1) / steps
            noise = -torch.log(-torch.log(torch.rand(B, n, generator=generator).clamp_(1e-9, 1 - 1e-9)))
            score = torch.where(masked, conf + 2.0 * anneal * noise, torch.full_like(conf, math.inf))
            order = score.argsort(dim=1)  # lowest first
            rank = order.argsort(dim=1)
            still = rank < keep_masked[:, None]
            newly = masked & ~still
            sampled = tokens.clone()
            sampled[masked] = choice
            tokens = torch.where(newly[..., None], sampled, tokens)
            masked = still & masked
        return tokens

    def _sample_masked(self, h_cond: torch.Tensor, h_free: torch.Tensor | None,
                       generator: torch.Generator, guidance: float, temperature: float):
        """Tokens (m, G) for the m masked positions with trunk features ``h_cond`` (and
        ``h_free`` without the condition, for guidance), and their summed log-probability (m,).

        Only masked positions are drawn: the others are context and keep their tokens, and in
        an in-painting window they are most of it. Each group is one categorical draw (inverse
        CDF of one uniform number), the same distribution as Gumbel-max at a 512th of the
        random numbers."""
        m, G = h_cond.shape[0], self.cfg.groups
        choice = torch.zeros(m, G, dtype=torch.long)
        conf = torch.zeros(m)
        for gi in range(G):  # the chain: group gi given the groups sampled before it
            logits = self.group_logits(h_cond, gi, choice[:, :gi])
            if h_free is not None:
                free = self.group_logits(h_free, gi, choice[:, :gi])
                logits = logits + guidance * (logits - free)
            logp = F.log_softmax(logits / max(temperature, 1e-4), dim=-1)
            cdf = logp.exp().cumsum(dim=-1)
            u = torch.rand(m, 1, generator=generator) * cdf[:, -1:]
            drawn = torch.searchsorted(cdf, u, right=True).clamp_(max=logp.shape[-1] - 1)
            choice[:, gi] = drawn[:, 0]
            conf += logp.gather(-1, drawn)[:, 0]
        return choice, conf
