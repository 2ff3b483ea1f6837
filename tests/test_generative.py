"""The learned skeleton: training loops and checkpoints on a tiny dataset made here, sampling
(in-painting, determinism), numpy inference against the torch modules, the shipped weights
(sampled without torch) and the CLI."""

import math
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import torch

from roadweaver_sumo import cli
from roadweaver_sumo.data.prepare import prepare_dataset
from roadweaver_sumo.errors import RoadweaverError
from roadweaver_sumo.generative import inference
from roadweaver_sumo.generative.checkpoint import (
    SHIPPED_MASKGIT,
    SHIPPED_VQVAE,
    load_maskgit,
    load_vqvae,
    read_checkpoint,
)
from roadweaver_sumo.generative.inference import TorchUniform
from roadweaver_sumo.generative.maskgit import MaskGIT
from roadweaver_sumo.generative.sampling import (
    GUIDANCE,
    STEPS,
    Generator,
    decode_canvas,
    sample_field,
    sample_tokens,
    window_starts,
    window_steps,
)
from roadweaver_sumo.generative.settings import MaskGITConfig, TrainSettings, VQVAEConfig
from roadweaver_sumo.generative.training import distil_guidance, train_maskgit, train_vqvae
from roadweaver_sumo.skeleton.learned import learned_skeleton, stroke_classes
from roadweaver_sumo.spec import ScenarioSpec

LAT0, LON0 = 48.0, 11.0
M_PER_DEG = 6_371_008.8 * math.pi / 180
TINY_VQ = VQVAEConfig(width=8, codebook_size=16, groups=2, code_dim=4)
TINY_MG = MaskGITConfig(dim=32, depth=1, heads=2, dropout=0.0)


def grid_town_osm(path: Path, n: int = 9, spacing: float = 100.0) -> Path:
    """An n x n grid of residential streets with a curved primary road through it."""
    def lonlat(x, y):
        return LON0 + x / (M_PER_DEG * math.cos(math.radians(LAT0))), LAT0 + y / M_PER_DEG

    xml = ['<?xml version="1.0"?>', '<osm version="0.6" generator="test">']
    ids = {}
    for i in range(n):
        for j in range(n):
            ids[i, j] = len(ids) + 1
            lon, lat = lonlat(i * spacing, j * spacing)
            xml.append(f'<node id="{ids[i, j]}" lat="{lat:.8f}" lon="{lon:.8f}" version="1"/>')
    curve = []
    for k in range(40):
        x = k * spacing * (n - 1) / 39
        y = 0.5 * spacing * (n - 1) + 120 * math.sin(x / 150)
        curve.append(1000 + k)
        lon, lat = lonlat(x, y)
        xml.append(f'<node id="{1000 + k}" lat="{lat:.8f}" lon="{lon:.8f}" version="1"/>')
    ways = [[ids[i, j] for j in range(n)] for i in range(n)]
    ways += [[ids[i, j] for i in range(n)] for j in range(n)]
    for w, nodes in enumerate(ways + [curve]):
        kind = "primary" if nodes is curve else "residential"
        refs = "".join(f'<nd ref="{r}"/>' for r in nodes)
        xml.append(f'<way id="{w + 1}" version="1">{refs}<tag k="highway" v="{kind}"/></way>')
    xml.append("</osm>")
    path.write_text("\n".join(xml))
    return path


@pytest.fixture(scope="module")
def tiny_dataset(tmp_path_factory) -> Path:
    root = tmp_path_factory.mktemp("data")
    osm = grid_town_osm(root / "town.osm")
    out = root / "tiles"
    prepare_dataset([osm], out, tile_m=400.0, size=32, shifts=(0.0, 0.25, 0.5),
                    min_coverage=0.3, log=lambda m: None)
    return out


@pytest.fixture(scope="module")
def tiny_models(tiny_dataset, tmp_path_factory):
    root = tmp_path_factory.mktemp("models")
    vq_settings = TrainSettings(steps=6, batch=4, lr=1e-3, eval_every=3)
    vq_meta = train_vqvae(tiny_dataset, root / "vq.npz", vq_settings, TINY_VQ, log=lambda m: None)
    mg_settings = TrainSettings(steps=6, batch=4, lr=1e-3, eval_every=3)
    mg_meta = train_maskgit(tiny_dataset, root / "vq.npz", root / "mg.npz", mg_settings, TINY_MG,
                            log=lambda m: None)
    return root, vq_meta, mg_meta


def test_training_records_losses_and_metrics(tiny_models):
    _, vq_meta, mg_meta = tiny_models
    assert vq_meta["kind"] == "vqvae" and mg_meta["kind"] == "maskgit"
    assert [h["step"] for h in vq_meta["history"]] == [3, 6]
    for h in vq_meta["history"]:
        assert all(np.isfinite(h[k]) for k in ("reconstruction", "codebook", "commitment"))
        assert 0.0 <= h["road_iou"] <= 1.0
    assert vq_meta["heldout_tiles"] > 0 and vq_meta["train_tiles"] > 0
    assert all(np.isfinite(h["loss"]) and np.isfinite(h["heldout_loss"])
               for h in mg_meta["history"])
    assert "OpenStreetMap" in vq_meta["attribution"] and "ODbL" in mg_meta["attribution"]
    assert mg_meta["config"]["grid"] == 4  # 32-pixel tiles, stride 8


def test_training_is_reproducible_by_seed(tiny_dataset, tiny_models, tmp_path):
    root, _, _ = tiny_models
    settings = TrainSettings(steps=6, batch=4, lr=1e-3, eval_every=3)
    train_vqvae(tiny_dataset, tmp_path / "again.npz", settings, TINY_VQ, log=lambda m: None)
    a, _ = read_checkpoint(root / "vq.npz", "vqvae")
    b, _ = read_checkpoint(tmp_path / "again.npz", "vqvae")
    assert a.keys() == b.keys() and all(np.array_equal(a[k], b[k]) for k in a)
    train_vqvae(tiny_dataset, tmp_path / "other.npz", replace(settings, seed=1), TINY_VQ,
                log=lambda m: None)
    c, _ = read_checkpoint(tmp_path / "other.npz", "vqvae")
    assert not all(np.array_equal(a[k], c[k]) for k in a)


def test_guidance_distillation_moves_the_student_to_the_guided_teacher(tiny_dataset, tiny_models,
                                                                       tmp_path):
    """The distilled copy predicts the teacher's guided distribution better than the teacher's
    own conditional prediction does, and samples without guidance (one pass per step)."""
    root, _, _ = tiny_models
    settings = TrainSettings(steps=30, batch=16, lr=1e-3, eval_every=15)
    meta = distil_guidance(tiny_dataset, root / "vq.npz", root / "mg.npz", tmp_path / "d.npz",
                           settings, log=lambda m: None)
    history = meta["distillation"]["history"]
    assert [h["step"] for h in history] == [0, 15, 30]
    assert history[-1]["heldout_loss"] < history[0]["heldout_loss"]
    assert meta["guidance_distilled"] == 1.0 and meta["config"] == load_maskgit(root / "mg.npz")[1]["config"]
    assert Generator.load(root / "vq.npz", tmp_path / "d.npz").guidance == 0.0
    assert Generator.load(root / "vq.npz", root / "mg.npz").guidance == GUIDANCE > 0
    with pytest.raises(RoadweaverError, match="already distilled"):
        distil_guidance(tiny_dataset, root / "vq.npz", tmp_path / "d.npz", tmp_path / "e.npz",
                        settings, log=lambda m: None)


def test_second_token_group_is_predicted_given_the_first():
    """The chain: group 1's logits change with the group-0 token at the same position,
    group 0's do not depend on group 1."""
    torch.manual_seed(0)
    model = MaskGIT(MaskGITConfig(dim=32, depth=1, heads=2, codebook_size=16, groups=2, grid=4,
                                  dropout=0.0)).eval()
    for head in model.heads:  # leave adaLN-Zero's identity start so the heads see something
        torch.nn.init.normal_(head.weight)
    tokens = torch.randint(0, 16, (1, 16, 2))
    mask = torch.ones(1, 16, dtype=torch.bool)
    other = tokens.clone()
    other[..., 0] = (other[..., 0] + 1) % 16
    with torch.no_grad():
        a, b = model(tokens, mask, torch.zeros(1, 11)), model(other, mask, torch.zeros(1, 11))
    assert torch.equal(a[..., 0, :], b[..., 0, :])
    assert not torch.allclose(a[..., 1, :], b[..., 1, :])
    third = tokens.clone()
    third[..., 1] = (third[..., 1] + 1) % 16
    with torch.no_grad():
        c = model(third, mask, torch.zeros(1, 11))
    assert torch.equal(a, c)  # all positions masked: group-1 tokens are never seen


def test_checkpoint_round_trip_and_bad_files(tiny_models, tmp_path):
    root, _, _ = tiny_models
    vq, meta = load_vqvae(root / "vq.npz")
    assert vq.cfg == TINY_VQ and meta["config"] == TINY_VQ.to_dict()
    with pytest.raises(Exception, match="expected 'maskgit'"):
        load_maskgit(root / "vq.npz")
    junk = tmp_path / "junk.npz"
    junk.write_bytes(b"not a checkpoint")
    with pytest.raises(Exception, match="not a roadweaver-sumo checkpoint"):
        load_vqvae(junk)
    with pytest.raises(Exception, match="not found"):
        load_vqvae(tmp_path / "missing.npz")


def test_sampling_any_extent_is_deterministic(tiny_models):
    root, _, _ = tiny_models
    gen = Generator.load(root / "vq.npz", root / "mg.npz")
    c = np.zeros(11, dtype=np.float32)
    F1, res = sample_field(gen, c, 1000.0, 600.0, seed=3)
    F2, _ = sample_field(gen, c, 1000.0, 600.0, seed=3)
    F3, _ = sample_field(gen, c, 1000.0, 600.0, seed=4)
    assert res == pytest.approx(400.0 / 32)
    assert F1.shape[0] * res >= 600.0 and F1.shape[1] * res >= 1000.0
    assert np.array_equal(F1, F2) and not np.array_equal(F1, F3)
    assert F1[..., 0].min() >= 0 and F1[..., 0].max() <= 1
    assert F1[..., 1:3].min() >= -1 and F1[..., 1:3].max() <= 1


def test_inpainting_keeps_known_tokens(tiny_models):
    root, _, _ = tiny_models
    gen = Generator.load(root / "vq.npz", root / "mg.npz")
    n, G = gen.grid ** 2, gen.sampler.cfg.groups
    known = np.random.default_rng(0).integers(0, gen.sampler.cfg.codebook_size, (n, G))
    known_mask = np.arange(n) < n // 2
    rows = gen.sampler.condition(np.zeros(11, np.float32), guidance=1.0)
    out = gen.sampler.sample(rows, TorchUniform(0), steps=4, known=known, known_mask=known_mask,
                             temperature=1.25, guidance=1.0)
    assert np.array_equal(out[known_mask], known[known_mask])
    assert out.min() >= 0 and out.max() < gen.sampler.cfg.codebook_size


@pytest.mark.skipif(not SHIPPED_MASKGIT.is_file(), reason="weights not trained yet")
def test_trunk_rows_are_those_of_the_full_trunk():
    """Features of some rows only (the last block computing just those) are the full trunk's
    rows, for any number of rows: to float32 rounding (BLAS kernels of some CPUs sum a row
    differently when the matrix has other rows)."""
    gen = Generator.load()
    rng = np.random.default_rng(0)
    n, G = gen.grid ** 2, gen.sampler.cfg.groups
    row = gen.sampler.condition(np.zeros(11, np.float32), guidance=1.0)[0]
    for m in (0, 1, 15, 16, 17, 45, 64, 255, 256):
        tokens = rng.integers(0, gen.sampler.cfg.codebook_size, (n, G))
        masked = np.zeros(n, dtype=bool)
        masked[rng.choice(n, m, replace=False)] = True
        rows = np.flatnonzero(masked)
        np.testing.assert_allclose(gen.sampler.trunk(tokens, masked, row, rows),
                                   gen.sampler.trunk(tokens, masked, row)[rows],
                                   rtol=1e-4, atol=1e-5)


def test_inverse_cdf_draws_follow_the_probabilities():
    """Drawn categories come up as often as their probabilities say (20,000 draws of one row
    of 8, each share within 0.015); u = 0 takes the first category, u just below 1 the last
    one that has probability, and a nearly one-hot row its peak."""
    probs = np.array([0.05, 0.3, 0.0, 0.15, 0.2, 0.1, 0.2, 0.0], np.float32)
    u = np.random.default_rng(3).random(20000).astype(np.float32)
    got = inference._inverse_cdf(np.repeat(probs[None], len(u), axis=0), u)
    assert np.abs(np.bincount(got, minlength=8) / len(u) - probs).max() < 0.015
    edges = inference._inverse_cdf(np.repeat(probs[None], 2, axis=0),
                                   np.array([0.0, 1 - 2**-24], np.float32))
    assert edges.tolist() == [0, 6]
    peaked = np.full((3, 512), 1e-12, np.float32)
    peaked[:, 7] = 1.0
    assert inference._inverse_cdf(peaked, np.array([0.1, 0.5, 0.9], np.float32)).tolist() == [7] * 3


@pytest.mark.skipif(not SHIPPED_MASKGIT.is_file(), reason="weights not trained yet")
def test_a_larger_canvas_extends_the_one_window_sample_of_its_seed():
    """Windows are sampled in raster order from one random stream, so a larger map of the same
    seed and condition keeps the first window's tokens (its corner is the small map), and the
    next window takes them as context instead of sampling them again."""
    gen = Generator.load()
    c = np.zeros(11, np.float32)
    g = gen.grid
    alone = sample_tokens(gen, c, (g, g), 5)
    canvas = sample_tokens(gen, c, (g, 2 * g), 5)
    assert np.array_equal(canvas[:, :g], alone)
    assert not np.array_equal(canvas[:, g:], alone)  # the next windows sample new tokens
    assert not np.array_equal(sample_tokens(gen, c, (g, g), 6), alone)


def test_window_starts_cover_the_canvas_with_half_overlap():
    assert window_starts(16, 16) == [0]
    assert window_starts(10, 16) == [0]
    assert window_starts(40, 16) == [0, 8, 16, 24]
    assert window_starts(30, 16) == [0, 8, 14]


def test_stroke_classes_rank_long_straight_roads_first():
    from roadweaver_sumo.roadgraph import add_road, new_road_graph

    G = new_road_graph(1000, 1000)
    # a straight 1 km avenue split by three junctions, and short side streets
    for k in range(5):
        G.add_node(k, xy=(250.0 * k, 500.0))
    for k in range(4):
        add_road(G, k, k + 1, np.array([G.nodes[k]["xy"], G.nodes[k + 1]["xy"]]), "arterial")
    for k in (1, 2, 3):
        G.add_node(10 + k, xy=(250.0 * k, 600.0))
        add_road(G, k, 10 + k, np.array([G.nodes[k]["xy"], G.nodes[10 + k]["xy"]]), "arterial")
    classes = stroke_classes(G)
    assert all(classes[(k, k + 1)] == "arterial" for k in range(4))
    assert all(classes[(k, 10 + k)] != "arterial" for k in (1, 2, 3))


@pytest.mark.skipif(not SHIPPED_MASKGIT.is_file(), reason="weights not trained yet")
def test_shipped_weights_give_a_learned_skeleton():
    total = sum(p.stat().st_size for p in SHIPPED_VQVAE.parent.glob("*.npz"))
    assert total <= 20 * 2**20
    spec = ScenarioSpec(density=30, vehicles=10, width=2500, height=2000, skeleton="learned")
    sk = learned_skeleton(spec)
    again = learned_skeleton(spec)
    assert len(sk.polylines) > 10 and len(sk.classes) == len(sk.polylines)
    assert {"arterial", "collector", "local"} >= set(sk.classes)
    pts = np.vstack(sk.polylines)
    assert pts.min() >= -1e-6 and pts[:, 0].max() <= 2500 + 1e-6 and pts[:, 1].max() <= 2000
    assert all(np.array_equal(a, b) for a, b in zip(sk.polylines, again.polylines))
    assert sk.road_prob.shape == sk.basis.c2.shape == (200, 250)


def test_uniform_stream_is_torch_rand():
    """The sampler's random numbers are torch.rand's for the same seed, in the same order."""
    g = torch.Generator().manual_seed(1234)
    ours = TorchUniform(1234)
    for shape in [(3,), (1, 300), (50, 1)]:
        assert np.array_equal(ours.rand(*shape), torch.rand(*shape, generator=g).numpy())


def test_numpy_inference_matches_the_torch_modules(tiny_models):
    """The numpy forward passes compute what the trained torch modules compute, within float32
    rounding: transformer features, a chained group's logits, decoded fields."""
    root, _, _ = tiny_models
    gen = Generator.load(root / "vq.npz", root / "mg.npz")
    vq, _ = load_vqvae(root / "vq.npz")
    mg, _ = load_maskgit(root / "mg.npz")
    rng = np.random.default_rng(0)
    n = mg.cfg.grid ** 2
    tokens = rng.integers(0, mg.cfg.codebook_size, (n, mg.cfg.groups))
    masked = rng.random(n) < 0.5
    cond = rng.normal(size=11).astype(np.float32)
    with torch.no_grad():
        expected = mg.trunk(torch.from_numpy(tokens).repeat(2, 1, 1),
                            torch.from_numpy(masked).repeat(2, 1), torch.from_numpy(cond).repeat(2, 1),
                            torch.tensor([False, True])).numpy()
    rows = gen.sampler.condition(cond, guidance=1.0)
    ours = np.stack([gen.sampler.trunk(tokens, masked, row) for row in rows])
    assert np.allclose(ours, expected, atol=1e-5)
    canvas = rng.integers(0, vq.cfg.codebook_size, (5, 7, vq.cfg.groups))
    with torch.no_grad():
        field = vq.decode(torch.from_numpy(canvas)[None])[0].permute(1, 2, 0).numpy()
    assert np.allclose(decode_canvas(gen.decoder, canvas), field, atol=1e-5)
    h = ours[0][masked]
    earlier = tokens[masked][:, :1]
    with torch.no_grad():
        want = mg.group_logits(torch.from_numpy(h), 1, torch.from_numpy(earlier)).numpy()
    assert np.allclose(gen.sampler.group_logits(h, 1, earlier), want, atol=1e-5)


def test_learned_skeleton_needs_no_torch():
    """Sampling a map imports neither torch nor anything that pulls it in."""
    code = ("import sys; from roadweaver_sumo.spec import ScenarioSpec; "
            "from roadweaver_sumo.skeleton import make_skeleton; "
            "sk = make_skeleton(ScenarioSpec(density=30, vehicles=10, width=1000, height=1000)); "
            "assert sk.provenance['generator'] == 'learned' and sk.polylines; "
            "assert 'torch' not in sys.modules, 'torch was imported'")
    subprocess.run([sys.executable, "-c", code], check=True)


def test_train_cli_errors_are_one_line(tmp_path, capsys):
    assert cli.main(["train", "vqvae", "--data", str(tmp_path), "--out",
                     str(tmp_path / "m.npz")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "not a prepared dataset" in err
    (tmp_path / "m.npz").write_bytes(b"x")
    assert cli.main(["train", "maskgit", "--data", str(tmp_path), "--vqvae", "v.npz", "--out",
                     str(tmp_path / "m.npz")]) == 2
    assert "pass --force" in capsys.readouterr().err
    assert cli.main(["train", "vqvae", "--data", str(tmp_path), "--out", str(tmp_path / "n.npz"),
                     "--steps", "0"]) == 2
    assert "error" in capsys.readouterr().err


def test_train_cli_writes_a_checkpoint(tiny_dataset, tmp_path, capsys):
    out = tmp_path / "vq.npz"
    assert cli.main(["train", "vqvae", "--data", str(tiny_dataset), "--out", str(out),
                     "--steps", "2", "--batch", "2", "--quiet"]) == 0
    assert "held-out road IoU" in capsys.readouterr().out
    assert load_vqvae(out)[1]["settings"]["steps"] == 2



def test_train_without_torch_says_how_to_get_it(tmp_path, capsys, monkeypatch):
    """Sampling needs no torch, training does: without it, one line naming the extra."""
    import importlib.util

    find_spec = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec",
                        lambda name, *a: None if name == "torch" else find_spec(name, *a))
    assert cli.main(["train", "vqvae", "--data", str(tmp_path), "--out",
                     str(tmp_path / "m.npz")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "training needs torch" in err and "[train]" in err


def test_a_window_that_is_mostly_context_takes_fewer_steps():
    """The transformer passes of a large map: a fresh window takes every step, a window with
    half its tokens known half of them, one with three quarters known a single step."""
    assert window_steps(1.0) == STEPS
    assert window_steps(0.5) == math.ceil(STEPS / 2)
    assert window_steps(0.25) == 1 and window_steps(0.01) == 1
