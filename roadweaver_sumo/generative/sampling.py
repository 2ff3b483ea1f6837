"""Condition + map extent -> decoded road field F of any size, without seams.

The token canvas covers the whole map. It holds the tokens of filling it one window (the
transformer's 16 x 16 tile) at a time in raster order, windows overlapping by half: the tokens a
window shares with windows sampled before it are kept fixed as context and only the rest is
generated (MaskGIT in-painting), so every road that crosses a window border is continued by the
next window. The finished canvas goes through the convolutional decoder in one pass, so the decoded field has no
tile borders.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from threadpoolctl import threadpool_limits

from .checkpoint import SHIPPED_MASKGIT, SHIPPED_VQVAE, read_checkpoint
from .inference import FieldDecoder, MaskGITSampler, TorchUniform
from .settings import MaskGITConfig, VQVAEConfig

#: Decoding steps of a fresh window; a window that is mostly context takes proportionally
#: fewer (:func:`window_steps`), so most windows of a large map take one. (8 steps, at least 2
#: a window, sampled twice the transformer passes; over 30 seeds at 2 km, ten 6 km maps and
#: four 4 km ones the maps' figures came out the same within the seeds' spread: docs/learned.md.)
STEPS = 4
#: Classifier-free guidance scale of a transformer trained with condition dropout. A
#: transformer with the guidance distilled into it (``training.distil_guidance``, the shipped
#: one) samples without: one trunk pass per decoding step instead of two.
GUIDANCE = 1.0
#: Logit temperature. At 1.0, confidence-based decoding committed the confident "no road"
#: tokens first and some asks (mixed style at density 60) decoded to an almost empty tile (road
#: share 0.3-0.7 %); at 1.25 those tiles hold 13-20 % road pixels (real tiles: 24-45 %). With
#: half the steps each step commits more tokens at once, and the fields hold more road: at
#: 1.25 the skeleton made 56 % of a 6 km map's road nodes (density 60) instead of 30 %, its
#: roads turning 239° per km instead of 146°; at 1.05 it makes 31 %, turning 146°/km.
TEMPERATURE = 1.05
#: Canvases up to DECODE_BLOCK tokens a side (20 km at scale 1) decode in one pass; larger ones
#: in blocks with DECODE_MARGIN tokens of context (GroupNorm statistics make blocks differ
#: slightly, by less than 0.1 in a few pixels at block borders).
DECODE_BLOCK, DECODE_MARGIN = 160, 8
#: A window's matrix products are small (256 rows) and the decoder's are many: BLAS threads
#: cost more to wake than they save, and on a machine busy with other work (scenarios built
#: side by side) they wait for each other. Sampling and decoding hold BLAS to this many threads.
BLAS_THREADS = 1


@dataclass
class Generator:
    """The trained pair (numpy forward passes) plus what sampling needs from the transformer's
    training record."""

    decoder: FieldDecoder
    sampler: MaskGITSampler
    cond_mean: np.ndarray
    cond_std: np.ndarray
    tile_m: float  # metres covered by one window at scale 1 (the training tile)
    meta: dict
    road_threshold: float = 0.5  # road pixels of decoded fields (calibrated in training)

    @classmethod
    def load(cls, vqvae_path=SHIPPED_VQVAE, maskgit_path=SHIPPED_MASKGIT) -> Generator:
        vq_state, vq_meta = read_checkpoint(vqvae_path, "vqvae")
        mg_state, meta = read_checkpoint(maskgit_path, "maskgit")
        return cls(FieldDecoder(vq_state, VQVAEConfig(**vq_meta["config"])),
                   MaskGITSampler(mg_state, MaskGITConfig(**meta["config"])),
                   np.array(meta["condition_mean"], dtype=np.float32),
                   np.array(meta["condition_std"], dtype=np.float32),
                   float(meta["dataset"]["settings"]["tile_m"]), meta,
                   float(vq_meta["heldout"].get("threshold", 0.5)))

    @property
    def guidance(self) -> float:
        return 0.0 if self.meta.get("guidance_distilled") else GUIDANCE

    @property
    def grid(self) -> int:
        return self.sampler.cfg.grid

    def standardise(self, c: np.ndarray) -> np.ndarray:
        return ((np.asarray(c, np.float32) - self.cond_mean) / self.cond_std).astype(np.float32)


def window_starts(length: int, window: int) -> list[int]:
    """Window origins along one axis: stride half a window, the last flush with the end."""
    if length <= window:
        return [0]
    stride = window // 2
    starts = list(range(0, length - window + 1, stride))
    if starts[-1] != length - window:
        starts.append(length - window)
    return starts


@dataclass
class _Window:
    """One window of the canvas as raster order samples it."""

    origin: tuple[int, int]
    known_mask: np.ndarray  # (g * g,) the tokens already sampled by earlier windows
    steps: int


def _raster_windows(shape: tuple[int, int], g: int, steps: int) -> list[_Window]:
    """The canvas's windows in raster order, each with what it knows when its turn comes."""
    done = np.zeros(shape, dtype=bool)
    windows = []
    for y in window_starts(shape[0], g):
        for x in window_starts(shape[1], g):
            known_mask = done[y:y + g, x:x + g].reshape(g * g).copy()
            done[y:y + g, x:x + g] = True
            windows.append(_Window((y, x), known_mask, window_steps(1.0 - known_mask.mean(), steps)))
    return windows


def window_steps(unknown_share: float, steps: int = STEPS) -> int:
    """Decoding steps of a window with this share of its tokens still to sample: ``steps`` for
    a fresh window, proportionally fewer (at least one) for a window that is mostly context."""
    return max(1, math.ceil(steps * unknown_share))


def sample_tokens(gen: Generator, c: np.ndarray, shape: tuple[int, int], seed: int, *,
                  steps: int = STEPS, guidance: float | None = None,
                  temperature: float = TEMPERATURE) -> np.ndarray:
    """A token canvas (ny, nx, G) of at least one window, sampled window after window in raster
    order from one random stream (``guidance`` None: the generator's own,
    :attr:`Generator.guidance`)."""
    g, G = gen.grid, gen.sampler.cfg.groups
    guidance = gen.guidance if guidance is None else guidance
    ny, nx = max(shape[0], g), max(shape[1], g)
    canvas = np.zeros((ny, nx, G), dtype=np.int64)
    modulations = gen.sampler.condition(gen.standardise(c), guidance)
    rng = TorchUniform(seed)
    for window in _raster_windows((ny, nx), g, steps):
        y, x = window.origin
        known = canvas[y:y + g, x:x + g].reshape(g * g, G)
        out = gen.sampler.sample(modulations, rng, steps=window.steps, known=known,
                                 known_mask=window.known_mask, guidance=guidance,
                                 temperature=temperature)
        canvas[y:y + g, x:x + g] = out.reshape(g, g, G)
    return canvas


def sample_field(gen: Generator, c: np.ndarray, width_m: float, height_m: float, seed: int, *,
                 scale: float = 1.0, **options) -> tuple[np.ndarray, float]:
    """Decoded F (rows north from y = 0, as ``data.field``) covering at least the map, and its
    metres per pixel. ``scale`` stretches the model's tile over ``scale`` times the training
    extent (sparser networks than the data have look like scaled-up denser ones)."""
    token_m = gen.tile_m * scale / gen.grid
    shape = (math.ceil(height_m / token_m), math.ceil(width_m / token_m))
    with threadpool_limits(limits=BLAS_THREADS, user_api="blas"):
        tokens = sample_tokens(gen, c, shape, seed, **options)
        return decode_canvas(gen.decoder, tokens), token_m / 8


def decode_canvas(decoder: FieldDecoder, tokens: np.ndarray, block: int = DECODE_BLOCK,
                  margin: int = DECODE_MARGIN) -> np.ndarray:
    """Decode a token canvas (ny, nx, G) into F (8 ny, 8 nx, 6) in blocks of ``block`` tokens,
    each decoded with ``margin`` tokens of context on every side and only its centre kept, so
    memory stays bounded on a 50 km map."""
    ny, nx = tokens.shape[:2]
    out = np.zeros((8 * ny, 8 * nx, 6), dtype=np.float32)
    for y0 in range(0, ny, block):
        for x0 in range(0, nx, block):
            ya, xa = max(y0 - margin, 0), max(x0 - margin, 0)
            yb, xb = min(y0 + block + margin, ny), min(x0 + block + margin, nx)
            part = decoder.decode(tokens[ya:yb, xa:xb])
            h, w = min(block, ny - y0), min(block, nx - x0)
            oy, ox = 8 * (y0 - ya), 8 * (x0 - xa)
            out[8 * y0:8 * (y0 + h), 8 * x0:8 * (x0 + w)] = part[oy:oy + 8 * h, ox:ox + 8 * w]
    return out
