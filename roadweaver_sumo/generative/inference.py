"""The trained models' forward passes in numpy, for sampling maps without torch.

torch is needed to train the models, not to use them: a map needs only the transformer's
decoding steps and the VQ-VAE's decoder, which are a few matrix products, layer norms and
convolutions. Doing them in numpy spares every ``make-scenario`` the ~1 s import of torch (on a
2 km map that was most of the skeleton's time) and users the ~700 MB install.

The arithmetic follows the torch modules in ``maskgit.py`` and ``vqvae.py`` operation for
operation, in float32, so the results agree with theirs to float rounding; tests compare both.
Random numbers come from :class:`TorchUniform`, the same stream as ``torch.rand`` under
``torch.Generator().manual_seed(seed)``, so a seed samples the same tokens as it did with torch
(only a draw that falls within rounding of a category border can differ).
"""

from __future__ import annotations

import math
from functools import partial

import numpy as np
from scipy.special import erf, expit

from .settings import MaskGITConfig, VQVAEConfig

F32 = np.float32
LAYER_NORM_EPS = 1e-5
_SQRT_HALF = 1.0 / math.sqrt(2.0)
#: A row of a matrix product comes out of OpenBLAS bitwise the same whatever the other rows,
#: except in products of very few rows (other kernels, other summation order): features of
#: fewer rows than this are taken from the full trunk, so that asking for some rows never
#: changes their bits (tests compare).
MIN_ROWS = 16


class TorchUniform:
    """Uniform float32 numbers in [0, 1), drawn like ``torch.rand`` on the CPU: torch's CPU
    generator is the standard 32-bit Mersenne Twister (seeded as numpy's legacy
    ``RandomState``), and a float32 keeps the low 24 bits of one 32-bit draw."""

    def __init__(self, seed: int):
        self._mt = np.random.RandomState(int(seed))

    def rand(self, *shape: int) -> np.ndarray:
        raw = self._mt.randint(0, 2**32, size=shape, dtype=np.uint64)
        return (raw & 0xFFFFFF).astype(F32) * F32(2.0**-24)


def still_masked(unknown: int, t: int, steps: int) -> int:
    """How many of a window's ``unknown`` positions stay masked after decoding step ``t``: the
    share cos(π (t + 1) / 2T)."""
    return int(np.floor(F32(unknown) * F32(math.cos(0.5 * math.pi * (t + 1) / steps))))


def _linear(x: np.ndarray, weight: np.ndarray, bias: np.ndarray) -> np.ndarray:
    return x @ weight.T + bias


def _modulated_norm(x: np.ndarray, scale: np.ndarray, shift: np.ndarray) -> np.ndarray:
    """LayerNorm(x) * (1 + scale) + shift over the last axis: the blocks' AdaLN."""
    mean = x.mean(-1, keepdims=True)
    centred = x - mean
    inv = 1.0 / np.sqrt((centred * centred).mean(-1, keepdims=True) + F32(LAYER_NORM_EPS))
    return centred * inv * (F32(1.0) + scale) + shift


def _gelu(x: np.ndarray) -> np.ndarray:
    """torch's default GELU, x Φ(x) = x (1 + erf(x / √2)) / 2."""
    return F32(0.5) * x * (F32(1.0) + erf(x * F32(_SQRT_HALF)))


def _silu(x: np.ndarray) -> np.ndarray:
    return x * expit(x)


def _softmax_inplace(x: np.ndarray) -> None:
    x -= x.max(-1, keepdims=True)
    np.exp(x, out=x)
    x /= x.sum(-1, keepdims=True)


def _log_softmax(x: np.ndarray) -> np.ndarray:
    shifted = x - x.max(-1, keepdims=True)
    return shifted - np.log(np.exp(shifted).sum(-1, keepdims=True))


class MaskGITSampler:
    """The masked transformer's decoding (``MaskGIT.sample``) from a state dict of arrays."""

    def __init__(self, state: dict[str, np.ndarray], cfg: MaskGITConfig):
        self.cfg = cfg
        self.w = {k: np.ascontiguousarray(v, dtype=F32) for k, v in state.items()}
        w, d = self.w, cfg.dim
        self.token_embed = [w[f"token_embed.{g}.weight"] for g in range(cfg.groups)]
        self.chain_embed = [w[f"chain_embed.{g}.weight"] for g in range(cfg.groups - 1)]
        self.heads = [(w[f"heads.{g}.weight"].T.copy(), w[f"heads.{g}.bias"])
                      for g in range(cfg.groups)]
        self.pos = (w["row_embed"][:, None, :] + w["col_embed"][None, :, :]).reshape(-1, d)
        self.blocks = [{name: w[f"blocks.{i}.{name}"].T.copy() if name.endswith("weight")
                        and w[f"blocks.{i}.{name}"].ndim == 2 else w[f"blocks.{i}.{name}"]
                        for name in ("attn.in_proj_weight", "attn.in_proj_bias",
                                     "attn.out_proj.weight", "attn.out_proj.bias",
                                     "mlp.0.weight", "mlp.0.bias", "mlp.3.weight", "mlp.3.bias",
                                     "modulation.weight", "modulation.bias")}
                       for i in range(cfg.depth)]

    def condition(self, cond: np.ndarray, guidance: float) -> list[tuple]:
        """Standardised c (11,) -> the AdaLN terms of every block and the final scale and
        shift, for c and (with guidance) for the null condition. They depend on c alone, so a
        map computes them once for all its windows and steps."""
        w = self.w
        e = _linear(_silu(_linear(cond.astype(F32), w["cond_mlp.0.weight"], w["cond_mlp.0.bias"])),
                    w["cond_mlp.2.weight"], w["cond_mlp.2.bias"])
        rows = [e, w["null_cond"]] if guidance > 0 else [e]

        def parts(values: np.ndarray, count: int) -> list[np.ndarray]:
            return [np.ascontiguousarray(p, dtype=F32) for p in np.split(values, count)]

        return [([parts(c @ b["modulation.weight"] + b["modulation.bias"], 6) for b in self.blocks],
                 parts(_linear(c, w["final_mod.weight"], w["final_mod.bias"]), 2))
                for c in rows]

    def trunk(self, tokens: np.ndarray, masked: np.ndarray, mods, rows=None) -> np.ndarray:
        """Features (n, dim) of the tokens (n, G) with the ``masked`` (n,) positions hidden,
        under one condition's AdaLN terms ``mods``; with ``rows`` (indices), only those
        positions' features. Every block attends over all positions, but after the last
        block's keys and values only the rows asked for matter, so that block computes only
        them (the other rows are most of a window that is mostly context)."""
        block_mods, (scale, shift) = mods
        x = sum(emb[tokens[:, g]] for g, emb in enumerate(self.token_embed))
        x = np.where(masked[:, None], self.w["mask_embed"], x)
        x = (x + self.pos[:len(tokens)]).astype(F32)
        subset = rows is not None and len(rows) >= MIN_ROWS
        for i, (block, terms) in enumerate(zip(self.blocks, block_mods, strict=True)):
            queries = rows if subset and i == len(self.blocks) - 1 else None
            x = self._block(x, block, terms, queries)
        h = _modulated_norm(x, scale, shift)
        return h if subset or rows is None else h[rows]

    def _block(self, x: np.ndarray, block: dict, terms, queries) -> np.ndarray:
        """One transformer block (AdaLN ``terms``), for the rows ``queries`` or all."""
        s1, b1, g1, s2, b2, g2 = terms
        attended = self._attention(_modulated_norm(x, s1, b1), block, queries)
        if queries is not None:
            x = x[queries]
        x = x + g1 * attended
        hidden = _gelu(_modulated_norm(x, s2, b2) @ block["mlp.0.weight"] + block["mlp.0.bias"])
        return x + g2 * (hidden @ block["mlp.3.weight"] + block["mlp.3.bias"])

    def _attention(self, h: np.ndarray, block: dict, queries=None) -> np.ndarray:
        """Self-attention of the rows of h, or of the rows ``queries`` only (over all of h)."""
        n, d = h.shape
        heads = self.cfg.heads
        qkv = (h @ block["attn.in_proj_weight"] + block["attn.in_proj_bias"])
        qkv = qkv.reshape(n, 3, heads, d // heads).transpose(1, 2, 0, 3)  # (3, heads, n, dh)
        q = qkv[0] if queries is None else qkv[0][:, queries]
        q = q * F32(1.0 / math.sqrt(d // heads))
        scores = q @ np.ascontiguousarray(qkv[1].transpose(0, 2, 1))  # (heads, m, n)
        _softmax_inplace(scores)
        out = (scores @ qkv[2]).transpose(1, 0, 2).reshape(q.shape[1], d)
        return out @ block["attn.out_proj.weight"] + block["attn.out_proj.bias"]

    def _masked_features(self, tokens: np.ndarray, masked: np.ndarray, mods) -> np.ndarray:
        return self.trunk(tokens, masked, mods, np.flatnonzero(masked))

    def group_logits(self, h: np.ndarray, g: int, earlier: np.ndarray) -> np.ndarray:
        """Logits (m, K) of group ``g`` given the tokens (m, g) of the groups before it."""
        for j in range(g):
            h = h + self.chain_embed[j][earlier[:, j]]
        weight, bias = self.heads[g]
        return h @ weight + bias

    def sample(self, mods: list[tuple], rng: TorchUniform, *, steps: int, known: np.ndarray,
               known_mask: np.ndarray, temperature: float, guidance: float) -> np.ndarray:
        """Iterative confidence-based decoding of one window (``MaskGIT.sample`` with batch 1):
        tokens (n, G), those under ``known_mask`` kept. At step t the share cos(π t / 2T) of
        the unknown positions stays masked; the sampled tokens with the highest log-probability
        plus annealed Gumbel noise are kept. ``mods`` come from :meth:`condition`."""
        n = self.cfg.grid ** 2
        tokens = np.where(known_mask[:, None], known, 0)
        masked = ~known_mask
        unknown = int(masked.sum())
        for t in range(steps):
            features = partial(self._masked_features, tokens, masked)
            h_cond, *h_free = map(features, mods)
            h_free = h_free[0] if h_free else None
            choice, logp = self._sample_masked(h_cond, h_free, rng, guidance, temperature)
            conf = np.zeros(n, F32)
            conf[masked] = logp
            keep_masked = still_masked(unknown, t, steps)
            anneal = 1.0 - (t + 1) / steps
            uniform = np.clip(rng.rand(n), F32(1e-9), F32(1 - 1e-9))
            noise = -np.log(-np.log(uniform))
            score = np.where(masked, conf + F32(2.0 * anneal) * noise, F32(np.inf))
            rank = np.empty(n, np.int64)
            rank[np.argsort(score, kind="stable")] = np.arange(n)
            still = masked & (rank < keep_masked)
            newly = masked & ~still
            sampled = tokens.copy()
            sampled[masked] = choice
            tokens = np.where(newly[:, None], sampled, tokens)
            masked = still
        return tokens

    def _sample_masked(self, h_cond, h_free, rng: TorchUniform, guidance: float,
                       temperature: float):
        """Tokens (m, G) for the m masked positions and their summed log-probability (m,):
        one categorical draw per group (inverse CDF of one uniform number), group g given the
        groups drawn before it."""
        m, G = h_cond.shape[0], self.cfg.groups
        choice = np.zeros((m, G), np.int64)
        conf = np.zeros(m, F32)
        for g in range(G):
            logits = self.group_logits(h_cond, g, choice[:, :g])
            if h_free is not None:
                free = self.group_logits(h_free, g, choice[:, :g])
                logits = logits + F32(guidance) * (logits - free)
            logp = _log_softmax(logits / F32(max(temperature, 1e-4)))
            drawn = _inverse_cdf(np.exp(logp), rng.rand(m))
            choice[:, g] = drawn
            conf += logp[np.arange(m), drawn]
        return choice, conf


def _inverse_cdf(probs: np.ndarray, uniform: np.ndarray) -> np.ndarray:
    """One categorical draw per row of ``probs`` (m, K) by inverse CDF: the number of partial
    sums at or below ``uniform`` times the row's total, at most K - 1."""
    cdf = np.cumsum(probs, axis=1, dtype=np.float64).astype(F32)
    drawn = (cdf <= (uniform * cdf[:, -1])[:, None]).sum(axis=1)
    return np.minimum(drawn, probs.shape[1] - 1)


class FieldDecoder:
    """The VQ-VAE's token lookup and convolutional decoder (``VQVAE.decode``), channels last."""

    def __init__(self, state: dict[str, np.ndarray], cfg: VQVAEConfig):
        self.cfg = cfg
        w = {k: np.asarray(v, dtype=F32) for k, v in state.items() if k.startswith(("decoder.",
                                                                                    "quantizer."))}
        books = w["quantizer.codebooks"]
        self.codes = books / np.maximum(np.linalg.norm(books, axis=-1, keepdims=True), 1e-12)
        net = "decoder.net"
        self.layers = [
            ("conv", *_conv_taps(w, f"{net}.0")),
            ("res", _res_block(w, f"{net}.1")), ("res", _res_block(w, f"{net}.2")),
            ("up", *_transpose_taps(w, f"{net}.3")), ("res", _res_block(w, f"{net}.4")),
            ("up", *_transpose_taps(w, f"{net}.5")), ("res", _res_block(w, f"{net}.6")),
            ("up", *_transpose_taps(w, f"{net}.7")),
            ("silu, conv", *_conv_taps(w, f"{net}.9")),
        ]

    def decode(self, tokens: np.ndarray) -> np.ndarray:
        """Tokens (h, w, G) -> field (8h, 8w, 6) in the value ranges of F."""
        h, w, G = tokens.shape
        x = self.codes[np.arange(G), tokens].reshape(h, w, -1)
        for kind, *params in self.layers:
            if kind == "conv":
                x = _conv3x3(_padded(x), *params)
            elif kind == "res":
                x = _apply_res_block(x, params[0])
            elif kind == "up":
                x = _conv_transpose(x, *params)
            else:
                x = _conv3x3(_norm_silu_padded(x, _NO_AFFINE, _NO_AFFINE, 0), *params)
        out = expit(x)
        out[..., 1:3] = np.tanh(x[..., 1:3])
        return out


def _conv_taps(w: dict, name: str) -> tuple[np.ndarray, np.ndarray]:
    """A 3 x 3 convolution's weight as 9 (Cin, Cout) matrices, tap (dy, dx) at 3 dy + dx."""
    weight = w[f"{name}.weight"]  # (Cout, Cin, 3, 3)
    return np.ascontiguousarray(weight.transpose(2, 3, 1, 0).reshape(9, *weight.shape[1::-1])), \
        w[f"{name}.bias"]


def _transpose_taps(w: dict, name: str) -> tuple[np.ndarray, np.ndarray]:
    """A stride-2 4 x 4 transposed convolution's weight (Cin, Cout, 4, 4), as (ky, kx, Cin, Cout)."""
    return np.ascontiguousarray(w[f"{name}.weight"].transpose(2, 3, 0, 1)), w[f"{name}.bias"]


def _res_block(w: dict, name: str) -> dict:
    body = f"{name}.body"
    return {"norm1": (w[f"{body}.0.weight"], w[f"{body}.0.bias"]), "conv1": _conv_taps(w, f"{body}.2"),
            "norm2": (w[f"{body}.3.weight"], w[f"{body}.3.bias"]), "conv2": _conv_taps(w, f"{body}.5")}


def _apply_res_block(x: np.ndarray, block: dict) -> np.ndarray:
    h = _conv3x3(_norm_silu_padded(x, *block["norm1"], GROUPS), *block["conv1"])
    h = _conv3x3(_norm_silu_padded(h, *block["norm2"], GROUPS), *block["conv2"])
    return x + h


GROUPS = 8  # the ResBlocks' GroupNorm(8, C)
_NO_AFFINE = np.zeros(0, F32)


def _padded(x: np.ndarray) -> np.ndarray:
    """(H, W, C) -> (H + 3, W + 2, C) with zeros around: the layout :func:`_conv3x3` reads (one
    row more at the bottom, so its last tap's slice stays inside)."""
    return np.pad(np.ascontiguousarray(x, dtype=F32), ((1, 2), (1, 1), (0, 0)))


def _norm_silu_padded(x: np.ndarray, weight: np.ndarray, bias: np.ndarray,
                      groups: int) -> np.ndarray:
    """SiLU(GroupNorm(x)) of an image (H, W, C) (``groups`` 0: SiLU alone), in the padded
    layout of :func:`_padded`. The group statistics are summed in float64."""
    H, W, C = x.shape
    if groups > 0:
        by_group = x.reshape(H * W, groups, C // groups)
        mean = by_group.mean(axis=(0, 2), dtype=np.float64)
        var = ((by_group - mean[:, None].astype(F32)) ** 2).mean(axis=(0, 2), dtype=np.float64)
        inv = np.repeat(1.0 / np.sqrt(var + 1e-5), C // groups)
        scale = (inv * weight).astype(F32)
        shift = (bias - np.repeat(mean, C // groups) * inv * weight).astype(F32)
        x = x * scale + shift
    return _padded(x * expit(x))


def _conv3x3(padded: np.ndarray, taps: np.ndarray, bias: np.ndarray) -> np.ndarray:
    """3 x 3 convolution of an image given in the layout of :func:`_padded`. The padded
    image is flattened, so each tap is one matrix product on a contiguous slice (rows of the
    result that fall on the padding columns are dropped at the end)."""
    H, Wp = padded.shape[0] - 3, padded.shape[1]
    W = Wp - 2
    flat = padded.reshape(-1, padded.shape[2])
    out = np.empty((H * Wp, taps.shape[2]), F32)
    out[:] = bias
    for dy in range(3):
        for dx in range(3):
            start = dy * Wp + dx
            out += flat[start:start + H * Wp] @ taps[3 * dy + dx]
    return np.ascontiguousarray(out.reshape(H, Wp, -1)[:, :W])


#: ConvTranspose2d(kernel 4, stride 2, padding 1): output row 2i + phase takes input rows
#: i + offset with kernel row k, for these (offset, k) pairs (the same for columns).
_PHASE_TAPS = {0: ((0, 1), (-1, 3)), 1: ((1, 0), (0, 2))}


def _conv_transpose(x: np.ndarray, taps: np.ndarray, bias: np.ndarray) -> np.ndarray:
    """Stride-2 4 x 4 transposed convolution (padding 1) of (H, W, Cin) -> (2H, 2W, Cout):
    each of the four output phases is a 2 x 2 convolution of the input."""
    H, W, C = x.shape
    Wp = W + 2
    flat = np.pad(x, ((1, 2), (1, 1), (0, 0))).reshape(-1, C)
    out = np.empty((H, 2, W, 2, taps.shape[3]), F32)
    for py, rows in _PHASE_TAPS.items():
        for px, columns in _PHASE_TAPS.items():
            acc = np.empty((H * Wp, taps.shape[3]), F32)
            acc[:] = bias
            for oy, ky in rows:
                for ox, kx in columns:
                    start = (1 + oy) * Wp + 1 + ox
                    acc += flat[start:start + H * Wp] @ taps[ky, kx]
            out[:, py, :, px] = acc.reshape(H, Wp, -1)[:, :W]
    return out.reshape(2 * H, 2 * W, -1)
