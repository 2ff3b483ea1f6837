"""Training loops for the VQ-VAE and the masked transformer, reproducible by seed.

Both read a dataset written by ``roadweaver-sumo data prepare``. Whole source regions are held
out for evaluation (never a neighbouring crop of a training tile: the shifted crops overlap).
Step counts, not wall time, end training, so a seed gives the same weights on any machine with
the same torch build and thread count.
"""

from __future__ import annotations

import json
import time
from collections.abc import Callable
from dataclasses import asdict
from pathlib import Path

import numpy as np
import torch
import torch.nn.functional as F

from ..data.condition import CONDITION_NAMES
from ..data.prepare import ATTRIBUTION, decode_field, load_dataset
from ..errors import RoadweaverError
from .checkpoint import save_checkpoint
from .maskgit import MaskGIT, cosine_mask_ratio
from .settings import VQVAE_CONFIG, MaskGITConfig, TrainSettings, VQVAEConfig
from .vqvae import VQVAE, reconstruction_loss, road_iou, to_field

#: Regions kept out of training (by file-name prefix) when the dataset has them: one European
#: town and one US county, different enough from each other to test generalisation.
DEFAULT_HOLDOUT = ("heidelberg", "cobb-county")
#: The VQ-VAE first trains as a plain autoencoder for this share of its steps; its codebooks
#: then start from k-means of the encoder outputs. Quantising from step one starves the decoder
#: (a few codes win everything and the road lines never appear).
WARM_START_SHARE = 0.3
THRESHOLD_CANDIDATES = (0.25, 0.3, 0.35, 0.4, 0.45, 0.5, 0.55, 0.6, 0.65, 0.7, 0.75)


def _start(data_dir: Path, holdout: tuple[str, ...], settings: TrainSettings):
    """Seed torch and set its threads; return the batch generator, the dataset, which of its
    crops are held out, and its manifest."""
    torch.manual_seed(settings.seed)
    torch.set_num_threads(settings.threads)
    data = load_dataset(data_dir)
    manifest = json.loads((Path(data_dir) / "manifest.json").read_text())
    names = [s["file"] for s in manifest["sources"]]
    held = np.array([any(names[s].startswith(h) for h in holdout) for s in data["source"]])
    if held.all() or not held.any():  # a user's own dataset: hold out every 10th crop instead
        crop_id = np.arange(len(held)) // 4
        held = crop_id % 10 == 9
    if (~held).sum() < 1:
        raise RoadweaverError(f"{data_dir}: no tiles to train on")
    return torch.Generator().manual_seed(settings.seed), data, held, manifest


def _fields(Fq: np.ndarray) -> torch.Tensor:
    """uint8 (N, H, W, 6) -> float32 (N, 6, H, W)."""
    return torch.from_numpy(decode_field(Fq)).permute(0, 3, 1, 2).contiguous()


def _progress(log, name: str, step: int, total: int, start: float, **figures):
    rate = (time.perf_counter() - start) / max(step, 1)
    eta = rate * (total - step)
    parts = " ".join(f"{k} {v:.4g}" for k, v in figures.items())
    log(f"{name} step {step}/{total} {parts} ({rate:.2f} s/step, ETA {eta / 60:.1f} min)")


def _random_crops(x: torch.Tensor, crop: int, g: torch.Generator) -> torch.Tensor:
    if crop <= 0 or crop >= x.shape[-1]:
        return x
    size = x.shape[-1]
    out = torch.empty(x.shape[0], x.shape[1], crop, crop)
    starts = torch.randint(0, (size - crop) // 8 + 1, (x.shape[0], 2), generator=g) * 8
    for i, (y0, x0) in enumerate(starts.tolist()):
        out[i] = x[i, :, y0:y0 + crop, x0:x0 + crop]
    return out


def reconstructions(model: VQVAE, fields: torch.Tensor, batch: int = 32):
    """(reconstructed F, true F) batch by batch, through the quantiser."""
    model.eval()
    with torch.no_grad():
        for i in range(0, len(fields), batch):
            x = fields[i:i + batch]
            yield to_field(model(x)[0]), x
    model.train()


def evaluate_vqvae(model: VQVAE, fields: torch.Tensor, threshold: float = 0.5) -> dict:
    """Road-pixel IoU (reconstruction >= ``threshold`` against truth >= 0.5) and per-channel
    mean absolute error of reconstructions."""
    inter = union = 0
    err = torch.zeros(fields.shape[1])
    for rec, x in reconstructions(model, fields):
        p, t = rec[:, 0] >= threshold, x[:, 0] >= 0.5
        inter += (p & t).sum().item()
        union += (p | t).sum().item()
        err += (rec - x).abs().mean(dim=(0, 2, 3)) * len(x)
    return {"road_iou": inter / max(union, 1), "threshold": threshold,
            "mae": (err / len(fields)).tolist()}


def calibrate_threshold(model: VQVAE, fields: torch.Tensor,
                        candidates=THRESHOLD_CANDIDATES) -> float:
    """The road-probability threshold at which reconstructions of *training* tiles best match
    the true road pixels (truth >= 0.5). A decoder trained with weighted cross-entropy is not
    calibrated at exactly 0.5; sampling vectorises decoded fields at this threshold."""
    inter, union = np.zeros(len(candidates)), np.zeros(len(candidates))
    for rec, x in reconstructions(model, fields):
        t = x[:, 0] >= 0.5
        for k, c in enumerate(candidates):
            p = rec[:, 0] >= c
            inter[k] += (p & t).sum().item()
            union[k] += (p | t).sum().item()
    return float(candidates[int(np.argmax(inter / np.maximum(union, 1)))])


def _restart_dead_codes(model: VQVAE, usage: torch.Tensor, z: torch.Tensor,
                        g: torch.Generator) -> int:
    """Codes no batch chose since the last check take the value of a random encoder output:
    otherwise most of a codebook never learns and the effective vocabulary shrinks."""
    q = model.quantizer
    zs = q.split(z.detach()).reshape(-1, q.cfg.groups, q.cfg.code_dim)
    dead_total = 0
    with torch.no_grad():
        for gi in range(q.cfg.groups):
            dead = torch.nonzero(usage[gi] == 0).ravel()
            if len(dead):
                pick = torch.randint(0, len(zs), (len(dead),), generator=g)
                q.codebooks[gi, dead] = zs[pick, gi]
                dead_total += len(dead)
    usage.zero_()
    return dead_total


def _kmeans_codebooks(model: VQVAE, Fq: np.ndarray, train_idx: np.ndarray,
                      g: torch.Generator, seed: int, n_tiles: int = 96) -> None:
    """Codebooks from k-means of the warmed-up encoder's outputs (spherical: on unit vectors),
    so quantisation starts close to what the decoder has learnt to read."""
    from scipy.cluster.vq import kmeans2

    q = model.quantizer
    pick = np.sort(train_idx[torch.randint(0, len(train_idx), (n_tiles,), generator=g).numpy()])
    with torch.no_grad():
        zs = q.split(model.encoder(_fields(Fq[pick]))).reshape(-1, q.cfg.groups, q.cfg.code_dim)
        for gi in range(q.cfg.groups):
            centres, _ = kmeans2(zs[:, gi].double().numpy(), q.cfg.codebook_size, iter=10,
                                 minit="++", seed=seed)
            q.codebooks[gi] = torch.from_numpy(centres).float()


def train_vqvae(data_dir: Path, out_path: Path, settings: TrainSettings,
                cfg: VQVAEConfig = VQVAE_CONFIG, *, holdout=DEFAULT_HOLDOUT,
                log: Callable[[str], None] = print) -> dict:
    """Train the VQ-VAE; write the checkpoint; return the training record (losses, IoU)."""
    g, data, held, manifest = _start(data_dir, holdout, settings)
    train_idx = np.flatnonzero(~held)
    eval_fields = _fields(data["F"][held][:: max(1, held.sum() // 128)])
    model = VQVAE(cfg)
    opt = torch.optim.AdamW(model.parameters(), lr=settings.lr, weight_decay=0.0)
    sched = torch.optim.lr_scheduler.OneCycleLR(opt, settings.lr, total_steps=settings.steps,
                                                pct_start=0.05)
    warm = int(WARM_START_SHARE * settings.steps)
    usage = torch.zeros(cfg.groups, cfg.codebook_size)
    history, start, cpu = [], time.perf_counter(), time.process_time()
    for step in range(1, settings.steps + 1):
        pick = train_idx[torch.randint(0, len(train_idx), (settings.batch,), generator=g).numpy()]
        x = _random_crops(_fields(data["F"][np.sort(pick)]), settings.crop, g)
        if step <= warm:  # plain autoencoder on the unit-sphere latents: no quantiser yet
            logits = model.decoder(model.quantizer.unquantised(model.encoder(x)))
            codebook_loss = commitment = torch.zeros(())
        else:
            logits, idx, codebook_loss, commitment = model(x)
        rec = reconstruction_loss(logits, x)
        loss = rec + codebook_loss + commitment
        opt.zero_grad(set_to_none=True)
        loss.backward()
        opt.step()
        sched.step()
        if step == warm:
            _kmeans_codebooks(model, data["F"], train_idx, g, settings.seed)
        if step > warm:
            for gi in range(cfg.groups):
                usage[gi] += torch.bincount(idx[..., gi].ravel(), minlength=cfg.codebook_size)
            if (step - warm) % 100 == 0 and step < 0.8 * settings.steps:
                _restart_dead_codes(model, usage, model.encoder(x), g)
        if step % settings.eval_every == 0 or step == settings.steps:
            record = {"step": step, "reconstruction": rec.item(),
                      "codebook": codebook_loss.item(), "commitment": commitment.item(),
                      "train_road_iou": road_iou(to_field(logits.detach()), x),
                      **evaluate_vqvae(model, eval_fields)}
            history.append(record)
            _progress(log, "vqvae", step, settings.steps, start, rec=record["reconstruction"],
                      iou=record["road_iou"])
    seconds, cpu_seconds = time.perf_counter() - start, time.process_time() - cpu
    threshold = calibrate_threshold(model, _fields(data["F"][train_idx[::8]]))
    final = evaluate_vqvae(model, _fields(data["F"][held]), threshold)
    final["road_iou_at_0.5"] = evaluate_vqvae(model, _fields(data["F"][held]))["road_iou"]
    meta = {"kind": "vqvae", "config": cfg.to_dict(), "settings": asdict(settings),
            "history": history, "heldout": final, "heldout_tiles": int(held.sum()),
            "train_tiles": len(train_idx), "seconds": seconds, "cpu_seconds": cpu_seconds,
            "dataset": _dataset_meta(manifest), "attribution": ATTRIBUTION}
    save_checkpoint(out_path, model.state_dict(), meta)
    log(f"vqvae: held-out road IoU {final['road_iou']:.3f} in {seconds / 60:.1f} min")
    return meta


def _dataset_meta(manifest: dict) -> dict:
    return {"tiles": manifest["tiles"], "sources": [s["file"] for s in manifest["sources"]],
            "settings": manifest["settings"], "condition_stats": manifest["condition"]["stats"]}


def encode_dataset(vqvae: VQVAE, Fq: np.ndarray, batch: int = 64) -> torch.Tensor:
    """Token grids (N, h, w, G) of every tile."""
    vqvae.eval()
    out = [vqvae.encode(_fields(Fq[i:i + batch])) for i in range(0, len(Fq), batch)]
    return torch.cat(out)


def condition_stats(c: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Mean and std per condition entry; the transformer sees standardised c."""
    return c.mean(axis=0), np.maximum(c.std(axis=0), 1e-3)


def maskgit_loss(model: MaskGIT, tokens: torch.Tensor, cond: torch.Tensor,
                 g: torch.Generator, cond_drop: float) -> tuple[torch.Tensor, float]:
    """Mask a cosine-scheduled share of the positions, predict their tokens (cross-entropy on
    masked positions only, as in MaskGIT). A share of the batch loses its condition so that
    sampling can use classifier-free guidance."""
    B, h, w, G = tokens.shape
    n = h * w
    ratio = cosine_mask_ratio(torch.rand(B, generator=g))
    n_mask = torch.clamp((ratio * n).ceil().long(), 1, n)
    scores = torch.rand(B, n, generator=g)
    ranks = scores.argsort(dim=1).argsort(dim=1)
    mask = ranks < n_mask[:, None]  # (B, n)
    drop = torch.rand(B, generator=g) < cond_drop
    logits = model(tokens.reshape(B, n, G), mask, cond, drop)  # (B, n, G, K)
    target = tokens.reshape(B, n, G)
    loss = F.cross_entropy(logits[mask].reshape(-1, logits.shape[-1]), target[mask].reshape(-1))
    acc = (logits[mask].argmax(-1) == target[mask]).float().mean().item()
    return loss, acc


def _transformer_updates(model: MaskGIT, settings: TrainSettings) -> Callable:
    """The transformer's optimiser step for a loss: AdamW, one-cycle schedule, gradients
    clipped to norm 1."""
    opt = torch.optim.AdamW(model.parameters(), lr=settings.lr, betas=(0.9, 0.95),
                            weight_decay=0.05)
    sched = torch.optim.lr_scheduler.OneCycleLR(opt, settings.lr, total_steps=settings.steps,
                                                pct_start=0.05)

    def update(loss: torch.Tensor) -> None:
        opt.zero_grad(set_to_none=True)
        loss.backward()
        torch.nn.utils.clip_grad_norm_(model.parameters(), 1.0)
        opt.step()
        sched.step()

    return update


def _batch(train_idx: np.ndarray, size: int, g: torch.Generator) -> torch.Tensor:
    return torch.from_numpy(train_idx)[torch.randint(0, len(train_idx), (size,), generator=g)]


def train_maskgit(data_dir: Path, vqvae_path: Path, out_path: Path, settings: TrainSettings,
                  cfg: MaskGITConfig | None = None, *, cond_drop: float = 0.1,
                  holdout=DEFAULT_HOLDOUT, log: Callable[[str], None] = print) -> dict:
    """Train the masked transformer on the token grids of a trained VQ-VAE."""
    from .checkpoint import load_vqvae

    g, data, held, manifest = _start(data_dir, holdout, settings)
    vqvae, vq_meta = load_vqvae(vqvae_path)
    start = time.perf_counter()
    tokens = encode_dataset(vqvae, data["F"])
    log(f"maskgit: encoded {len(tokens)} tiles in {time.perf_counter() - start:.0f} s")
    vcfg = vqvae.cfg
    if cfg is None:
        cfg = MaskGITConfig()
    cfg = MaskGITConfig(**{**cfg.to_dict(), "codebook_size": vcfg.codebook_size,
                           "groups": vcfg.groups, "grid": tokens.shape[1]})
    c = data["c"].astype(np.float32)
    mean, std = condition_stats(c[~held])
    cond = torch.from_numpy((c - mean) / std)
    model = MaskGIT(cfg)
    update = _transformer_updates(model, settings)
    train_idx, eval_idx = np.flatnonzero(~held), np.flatnonzero(held)
    history, start, cpu = [], time.perf_counter(), time.process_time()
    for step in range(1, settings.steps + 1):
        pick = _batch(train_idx, settings.batch, g)
        loss, acc = maskgit_loss(model, tokens[pick], cond[pick], g, cond_drop)
        update(loss)
        if step % settings.eval_every == 0 or step == settings.steps:
            model.eval()
            with torch.no_grad():
                ge = torch.Generator().manual_seed(1)
                pick = torch.from_numpy(eval_idx[:256])
                eval_loss, eval_acc = maskgit_loss(model, tokens[pick], cond[pick], ge, 0.0)
            model.train()
            record = {"step": step, "loss": loss.item(), "acc": acc,
                      "heldout_loss": eval_loss.item(), "heldout_acc": eval_acc}
            history.append(record)
            _progress(log, "maskgit", step, settings.steps, start, loss=record["loss"],
                      heldout=record["heldout_loss"])
    seconds, cpu_seconds = time.perf_counter() - start, time.process_time() - cpu
    meta = {"kind": "maskgit", "config": cfg.to_dict(), "settings": asdict(settings),
            "cond_drop": cond_drop, "condition_names": list(CONDITION_NAMES),
            "condition_mean": mean.tolist(), "condition_std": std.tolist(),
            "history": history, "seconds": seconds, "cpu_seconds": cpu_seconds,
            "train_tiles": len(train_idx),
            "vqvae": {"config": vq_meta["config"], "heldout": vq_meta.get("heldout")},
            "dataset": _dataset_meta(manifest), "attribution": ATTRIBUTION}
    save_checkpoint(out_path, model.state_dict(), meta)
    log(f"maskgit: final held-out loss {history[-1]['heldout_loss']:.3f} "
        f"in {seconds / 60:.1f} min")
    return meta


def distillation_loss(student: MaskGIT, teacher: MaskGIT, tokens: torch.Tensor,
                      cond: torch.Tensor, g: torch.Generator, guidance: float) -> torch.Tensor:
    """Cross-entropy of the student's conditional prediction against the teacher's guided one,
    softmax(l_c + guidance (l_c - l_null)), on positions masked as in training: what sampling
    with guidance draws from, in one transformer pass instead of two."""
    B, h, w, G = tokens.shape
    n = h * w
    ratio = cosine_mask_ratio(torch.rand(B, generator=g))
    n_mask = torch.clamp((ratio * n).ceil().long(), 1, n)
    mask = torch.rand(B, n, generator=g).argsort(dim=1).argsort(dim=1) < n_mask[:, None]
    flat = tokens.reshape(B, n, G)
    with torch.no_grad():
        cond_logits = teacher(flat, mask, cond)
        free_logits = teacher(flat, mask, cond, torch.ones(B, dtype=torch.bool))
        target = torch.softmax(cond_logits + guidance * (cond_logits - free_logits), dim=-1)
    logp = torch.log_softmax(student(flat, mask, cond), dim=-1)
    return -(target[mask] * logp[mask]).sum(-1).mean()


def distil_guidance(data_dir: Path, vqvae_path: Path, teacher_path: Path, out_path: Path,
                    settings: TrainSettings, *, guidance: float = 1.0, holdout=DEFAULT_HOLDOUT,
                    log: Callable[[str], None] = print) -> dict:
    """Fine-tune a copy of a trained transformer so that its conditional prediction alone is
    the teacher's guided one (guidance distillation, Meng et al. 2023): sampling then needs
    one transformer pass per decoding step instead of two. ``vqvae_path``: the VQ-VAE the
    teacher was trained on, which encodes the tiles."""
    from .checkpoint import load_maskgit, load_vqvae

    g, data, held, _ = _start(data_dir, holdout, settings)
    teacher, meta = load_maskgit(teacher_path)
    if meta.get("guidance_distilled"):
        raise RoadweaverError(f"{teacher_path} is already distilled; distil its teacher")
    vqvae, _ = load_vqvae(vqvae_path)
    tokens = encode_dataset(vqvae, data["F"])
    mean, std = np.asarray(meta["condition_mean"]), np.asarray(meta["condition_std"])
    cond = torch.from_numpy(((data["c"] - mean) / std).astype(np.float32))
    student, _ = load_maskgit(teacher_path)
    student.train()
    update = _transformer_updates(student, settings)
    train_idx, eval_idx = np.flatnonzero(~held), np.flatnonzero(held)

    def heldout() -> float:
        student.eval()
        with torch.no_grad():
            pick = torch.from_numpy(eval_idx[:256])
            value = distillation_loss(student, teacher, tokens[pick], cond[pick],
                                      torch.Generator().manual_seed(1), guidance).item()
        student.train()
        return value

    history, start, cpu = [{"step": 0, "heldout_loss": heldout()}], time.perf_counter(), \
        time.process_time()
    for step in range(1, settings.steps + 1):
        pick = _batch(train_idx, settings.batch, g)
        loss = distillation_loss(student, teacher, tokens[pick], cond[pick], g, guidance)
        update(loss)
        if step % settings.eval_every == 0 or step == settings.steps:
            history.append({"step": step, "loss": loss.item(), "heldout_loss": heldout()})
            _progress(log, "distil", step, settings.steps, start, loss=history[-1]["loss"],
                      heldout=history[-1]["heldout_loss"])
    seconds, cpu_seconds = time.perf_counter() - start, time.process_time() - cpu
    out_meta = {**meta, "guidance_distilled": guidance,
                "distillation": {"settings": asdict(settings), "history": history,
                                 "seconds": seconds, "cpu_seconds": cpu_seconds}}
    save_checkpoint(out_path, student.state_dict(), out_meta)
    log(f"distil: held-out cross-entropy to the guided teacher {history[0]['heldout_loss']:.3f}"
        f" -> {history[-1]['heldout_loss']:.3f} in {seconds / 60:.1f} min")
    return out_meta
