"""Condition + map extent -> decoded road field F of any size, without seams.

The token canvas covers the whole map. It holds the tokens of filling it one window (the
transformer's 16 x 16 tile) at a time in raster order, windows overlapping by half: the tokens a
window shares with windows sampled before it are kept fixed as context and only the rest is
generated (MaskGIT in-painting), so every road that crosses a window border is continued by the
next window. Windows whose context is complete are sampled side by side, each with the random
numbers it draws in raster order, so the tokens are raster order's whatever the schedule. The
finished canvas goes through the convolutional decoder in one pass, so the decoded field has no
tile borders.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from concurrent.futures import FIRST_COMPLETED, ThreadPoolExecutor, wait
from contextlib import contextmanager
from dataclasses import dataclass

import numpy as np
from threadpoolctl import threadpool_limits

from .checkpoint import SHIPPED_MASKGIT, SHIPPED_VQVAE, read_checkpoint
from .inference import DrawnUniform, FieldDecoder, MaskGITSampler, TorchUniform
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


@contextmanager
def two_threads() -> Iterator[ThreadPoolExecutor]:
    """Two threads, each multiplying its matrices on one core: two windows side by side are
    twice as fast as one on two BLAS threads, whose start-up costs more than these small
    products. A window is computed the same way on any thread, so the tokens do not depend
    on them."""
    with threadpool_limits(limits=1, user_api="blas"), ThreadPoolExecutor(2) as pool:
        yield pool


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
    after: list[int]  # the earlier windows it overlaps, whose tokens it takes as context


def _raster_windows(shape: tuple[int, int], g: int, steps: int) -> list[_Window]:
    """The canvas's windows in raster order, each with what it knows when its turn comes."""
    ys, xs = window_starts(shape[0], g), window_starts(shape[1], g)

    def near(starts: list[int]) -> list[list[int]]:
        return [[j for j, b in enumerate(starts) if abs(a - b) < g] for a in starts]

    near_y, near_x = near(ys), near(xs)
    done = np.zeros(shape, dtype=bool)
    windows = []
    for i, y in enumerate(ys):
        for j, x in enumerate(xs):
            known_mask = done[y:y + g, x:x + g].reshape(g * g).copy()
            done[y:y + g, x:x + g] = True
            share = 1.0 - known_mask.mean()
            after = [k for k in (a * len(xs) + b for a in near_y[i] for b in near_x[j])
                     if k < len(windows)]
            windows.append(_Window((y, x), known_mask, window_steps(share, steps), after))
    return windows


def window_steps(unknown_share: float, steps: int = STEPS) -> int:
    """Decoding steps of a window with this share of its tokens still to sample: ``steps`` for
    a fresh window, proportionally fewer (at least one) for a window that is mostly context."""
    return max(1, math.ceil(steps * unknown_share))


def sample_tokens(gen: Generator, c: np.ndarray, shape: tuple[int, int], seed: int, *,
                  steps: int = STEPS, guidance: float | None = None,
                  temperature: float = TEMPERATURE, progress=None) -> np.ndarray:
    """A token canvas (ny, nx, G) of at least one window: the tokens raster order samples
    (``guidance`` None: the generator's own, :attr:`Generator.guidance`).

    A window's tokens depend only on its context and its random numbers, so each window is
    sampled as soon as the windows it overlaps are done, given the stretch of the random
    stream it would have drawn in raster order (its share is known beforehand: how many
    numbers a window draws depends only on how many tokens it fills and its steps)."""
    g, G = gen.grid, gen.sampler.cfg.groups
    guidance = gen.guidance if guidance is None else guidance
    ny, nx = max(shape[0], g), max(shape[1], g)
    canvas = np.zeros((ny, nx, G), dtype=np.int64)
    modulations = gen.sampler.condition(gen.standardise(c), guidance)
    windows = _raster_windows((ny, nx), g, steps)
    rng = TorchUniform(seed)
    streams = [DrawnUniform(rng.rand(gen.sampler.draw_count(g * g - int(w.known_mask.sum()),
                                                            w.steps)))
               for w in windows]

    def sample(k: int) -> None:
        window = windows[k]
        y, x = window.origin
        known = canvas[y:y + g, x:x + g].reshape(g * g, G)
        out = gen.sampler.sample(modulations, streams[k], steps=window.steps, known=known,
                                 known_mask=window.known_mask, guidance=guidance,
                                 temperature=temperature)
        assert streams[k].used == len(streams[k].values)
        canvas[y:y + g, x:x + g] = out.reshape(g, g, G)

    with two_threads() as pool:
        _in_dependency_order(windows, sample, pool, progress)
    return canvas


def _in_dependency_order(windows: list[_Window], sample, pool: ThreadPoolExecutor,
                         progress) -> None:
    """Run ``sample(k)`` for every window once those it overlaps are done. Windows that are
    ready together run side by side on the pool's two threads; a window that is alone (the
    canvas's first ones) runs here."""
    waiting = [len(w.after) for w in windows]
    unlocks: list[list[int]] = [[] for _ in windows]
    for k, w in enumerate(windows):
        for j in w.after:
            unlocks[j].append(k)
    ready, running, finished = [0], {}, 0

    def finish(k: int) -> None:
        nonlocal finished
        finished += 1
        for later in unlocks[k]:
            waiting[later] -= 1
            if not waiting[later]:
                ready.append(later)
        if progress:
            progress(finished, len(windows))

    while ready or running:
        if len(ready) == 1 and not running:
            k = ready.pop()
            sample(k)
            finish(k)
            continue
        for k in sorted(ready):
            running[pool.submit(sample, k)] = k
        ready.clear()
        done, _ = wait(running, return_when=FIRST_COMPLETED)
        for future in done:
            future.result()
            finish(running.pop(future))


def sample_field(gen: Generator, c: np.ndarray, width_m: float, height_m: float, seed: int, *,
                 scale: float = 1.0, **options) -> tuple[np.ndarray, float]:
    """Decoded F (rows north from y = 0, as ``data.field``) covering at least the map, and its
    metres per pixel. ``scale`` stretches the model's tile over ``scale`` times the training
    extent (sparser networks than the data have look like scaled-up denser ones)."""
    token_m = gen.tile_m * scale / gen.grid
    shape = (math.ceil(height_m / token_m), math.ceil(width_m / token_m))
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
