"""CVAEs (GMM prior and vanilla), the normalizer, checkpoints and the training loop, on tiny data."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch

from amorgs.models.cvae import (
    CVAEConfig,
    GMMPriorCVAE,
    Normalizer,
    VanillaCVAE,
    VanillaCVAEConfig,
    load,
    save,
)
from amorgs.models.training import TrainConfig, train


def synthetic(n: int = 96, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Two clusters in 3-D whose positions move with α ∈ [0, 1]: x = ±(10, 0, 5) + 20 α (1, 1, 0) + noise."""
    rng = np.random.default_rng(seed)
    alpha = rng.choice([0.0, 0.25, 0.5, 0.75, 1.0], size=n)
    sign = rng.choice([-1.0, 1.0], size=n)
    x = sign[:, None] * np.array([10.0, 0.0, 5.0]) + 20.0 * alpha[:, None] * np.array([1.0, 1.0, 0.0])
    return x + rng.normal(0.0, 0.3, size=x.shape), alpha


def gmm_model(x: np.ndarray, seed: int = 0) -> GMMPriorCVAE:
    torch.manual_seed(seed)
    return GMMPriorCVAE(CVAEConfig.small(x_dim=3, latent_dim=2, n_components=2), Normalizer.from_data(x))


def vanilla_model(x: np.ndarray, seed: int = 0) -> VanillaCVAE:
    torch.manual_seed(seed)
    return VanillaCVAE(VanillaCVAEConfig.small(x_dim=3, latent_dim=2), Normalizer.from_data(x))


MODELS = {"gmm": gmm_model, "vanilla": vanilla_model}

FAST = TrainConfig(epochs=40, batch_size=32, lr=3e-3, seed=0, device="cpu")


# ------------------------------------------------------------------------------------------ configs
def test_presets_match_the_paper_tables():
    assert CVAEConfig.dejong_paper().layer_table() == {  # Table 3
        "Embed_x": [2, 32, 64, 64], "Embed_alpha": [1, 32, 64, 64], "Encode": [128, 64, 64],
        "Encode_mu": [64, 32, 2], "Encode_Sigma": [64, 32, 2], "Embed_z": [2, 32, 64, 64],
        "Decode_x": [128, 64, 64, 2], "GMM_w": [1, 512, 512, 512, 2], "GMM_mu": [1, 512, 512, 512, 4],
        "GMM_Sigma": [1, 512, 512, 512, 4],
    }
    wide, narrow = [1024] * 4, [256] * 4
    assert CVAEConfig.cr3bp_paper().layer_table() == {  # Table 4 (CVAE part)
        "Embed_x": [4, *wide], "Embed_alpha": [1, *narrow], "Encode": [1280, 512, 512, 512, 128],
        "Encode_mu": [128, 128, 128, 4], "Encode_Sigma": [128, 128, 128, 4], "Embed_z": [4, *wide],
        "Decode_x": [1280, 512, 512, 512, 4], "GMM_w": [1, 512, 512, 512, 20],
        "GMM_mu": [1, 512, 512, 512, 80], "GMM_Sigma": [1, 512, 512, 512, 80],
    }
    assert VanillaCVAEConfig.cr3bp_paper().layer_table() == {  # Table 5
        "Embed_x": [64, *wide], "Embed_alpha": [1, *narrow], "Encode": [1280, 512, 512, 512, 128],
        "Encode_mu": [128, 128, 128, 64], "Encode_Sigma": [128, 128, 128, 64], "Embed_z": [64, *wide],
        "Decode_x": [1280, 512, 512, 512, 64],
    }
    assert CVAEConfig.dejong_paper().kl_weight == 1e-4


def test_paper_sized_models_build_with_the_table_layers():
    model = GMMPriorCVAE(CVAEConfig.cr3bp_paper())
    linears = [m for m in model.gmm_mu if isinstance(m, torch.nn.Linear)]
    assert [(m.in_features, m.out_features) for m in linears] == [(1, 512), (512, 512), (512, 512), (512, 80)]
    vanilla = VanillaCVAE(VanillaCVAEConfig.cr3bp_paper())
    assert vanilla.decode_x[-1].out_features == 64


# ------------------------------------------------------------------------------------------ normalizer
def test_normalizer_round_trip_and_range():
    x, _ = synthetic()
    x[:, 2] = 7.0  # a constant column
    norm = Normalizer.from_data(x)
    xt = torch.as_tensor(x, dtype=torch.float32)
    u = norm.transform(xt)
    torch.testing.assert_close(u[:, :2].min(0).values, torch.zeros(2))
    torch.testing.assert_close(u[:, :2].max(0).values, torch.ones(2))
    torch.testing.assert_close(u[:, 2], torch.zeros(len(x)))  # constant column: unit scale, offset removed
    torch.testing.assert_close(norm.inverse(u), xt, rtol=1e-6, atol=1e-5)
    box = Normalizer(np.array([-50.0, -50.0]), np.array([50.0, 50.0]))  # fixed bounds, e.g. a problem's box
    torch.testing.assert_close(box.transform(torch.tensor([[0.0, 50.0]])), torch.tensor([[0.5, 1.0]]))
    with pytest.raises(ValueError, match="high"):
        Normalizer(np.array([1.0]), np.array([0.0]))


# ------------------------------------------------------------------------------------------ shapes
@pytest.mark.parametrize("kind", MODELS)
def test_shapes(kind):
    x, alpha = synthetic(16)
    model = MODELS[kind](x)
    u = model.normalizer.transform(torch.as_tensor(x, dtype=torch.float32))
    a = torch.as_tensor(alpha, dtype=torch.float32)[:, None]
    mu, logvar = model.encode(u, a)
    assert mu.shape == logvar.shape == (16, 2)
    z = model.reparameterize(mu, logvar)
    assert z.shape == (16, 2)
    out = model.decode(z, a)
    assert out.shape == (16, 3) and bool(((out > 0) & (out < 1)).all())
    samples = model.sample(0.3, 7, torch.Generator().manual_seed(0))
    assert samples.shape == (7, 3) and torch.isfinite(samples).all()


def test_gmm_prior_is_a_normalised_mixture():
    x, alpha = synthetic(16)
    model = gmm_model(x)
    p = model.prior(torch.as_tensor(alpha, dtype=torch.float32)[:, None])
    assert p.log_w.shape == (16, 2) and p.mu.shape == p.logvar.shape == (16, 2, 2)
    torch.testing.assert_close(p.w.sum(-1), torch.ones(16))
    # log G integrates to one: a Monte-Carlo check on a grid in 2-D
    g = torch.linspace(-12, 12, 241)
    zz = torch.stack(torch.meshgrid(g, g, indexing="ij"), -1).reshape(-1, 2)
    one = p._replace(log_w=p.log_w[:1].expand(len(zz), 2), mu=p.mu[:1].expand(len(zz), 2, 2),
                     logvar=p.logvar[:1].expand(len(zz), 2, 2))
    with torch.no_grad():
        mass = torch.exp(one.log_prob(zz)).sum() * (g[1] - g[0]) ** 2
    assert float(mass) == pytest.approx(1.0, abs=1e-3)


# ------------------------------------------------------------------------------------------ training
@pytest.mark.parametrize("kind", MODELS)
def test_loss_finite_and_decreasing(kind):
    x, alpha = synthetic()
    model = MODELS[kind](x)
    seen = []
    hist = train(model, x, alpha, FAST, on_epoch=lambda e, m: seen.append((e, m)))
    assert [e for e, _ in seen] == list(range(1, FAST.epochs + 1))
    assert set(hist) >= {"epoch", "loss", "recon", "kl", "epoch_s"}
    loss = np.array(hist["loss"])
    assert np.isfinite(loss).all() and np.isfinite(hist["kl"]).all()
    assert loss[-5:].mean() < 0.5 * loss[:5].mean()


def test_training_is_deterministic():
    x, alpha = synthetic()
    runs = []
    for _ in range(2):
        model = gmm_model(x, seed=3)
        hist = train(model, x, alpha, TrainConfig(epochs=5, batch_size=32, lr=1e-3, seed=11, device="cpu"))
        runs.append((hist["loss"], model.sample(0.5, 20, torch.Generator().manual_seed(1))))
    assert runs[0][0] == runs[1][0]
    torch.testing.assert_close(runs[0][1], runs[1][1], rtol=0, atol=0)


def test_train_rejects_bad_inputs():
    x, alpha = synthetic(8)
    model = gmm_model(x)
    with pytest.raises(ValueError, match="rows"):
        train(model, x, alpha[:5], FAST)
    with pytest.raises(ValueError, match="batch_size"):
        train(model, x, alpha, TrainConfig(batch_size=1))


# ------------------------------------------------------------------------------------------ sampling
@pytest.mark.parametrize("kind", MODELS)
def test_sampling_deterministic_and_conditioned(kind):
    x, alpha = synthetic()
    model = MODELS[kind](x)
    train(model, x, alpha, FAST)
    assert model.training  # sampling must not leave the model in eval mode
    s1 = model.sample(0.25, 200, torch.Generator().manual_seed(5))
    assert model.training
    s2 = model.sample(0.25, 200, torch.Generator().manual_seed(5))
    torch.testing.assert_close(s1, s2, rtol=0, atol=0)
    assert not torch.equal(s1, model.sample(0.25, 200, torch.Generator().manual_seed(6)))
    lo = model.sample(0.0, 400, torch.Generator().manual_seed(5)).mean(0)
    hi = model.sample(1.0, 400, torch.Generator().manual_seed(5)).mean(0)
    # the data move by +20 in x1 and x2 from α = 0 to α = 1 and not in x3
    assert float(hi[0] - lo[0]) > 10 and float(hi[1] - lo[1]) > 10
    assert abs(float(hi[2] - lo[2])) < 5


def test_alpha_argument_forms():
    x, _ = synthetic(8)
    model = gmm_model(x)
    g = lambda: torch.Generator().manual_seed(0)  # noqa: E731
    ref = model.sample(0.5, 4, g())
    torch.testing.assert_close(model.sample(np.array([0.5]), 4, g()), ref)
    torch.testing.assert_close(model.sample(torch.full((4, 1), 0.5), 4, g()), ref)
    with pytest.raises(ValueError, match="alpha"):
        model.sample(np.array([0.1, 0.2]), 4, g())


# ------------------------------------------------------------------------------------------ checkpoints
@pytest.mark.parametrize("kind", MODELS)
def test_save_load_round_trip(kind, tmp_path):
    x, alpha = synthetic()
    model = MODELS[kind](x)
    train(model, x, alpha, TrainConfig(epochs=3, batch_size=32, seed=0, device="cpu"))
    path = tmp_path / "model.pt"
    save(model, path)
    loaded = load(path)
    assert type(loaded) is type(model) and loaded.config == model.config and not loaded.training
    torch.testing.assert_close(loaded.normalizer.low, model.normalizer.low)
    for a in (0.0, 0.6):
        expected = model.sample(a, 50, torch.Generator().manual_seed(9))
        torch.testing.assert_close(loaded.sample(a, 50, torch.Generator().manual_seed(9)), expected, rtol=0, atol=0)


def test_load_rejects_other_files(tmp_path):
    path = tmp_path / "other.pt"
    torch.save({"weights": torch.zeros(2)}, path)
    with pytest.raises(ValueError, match="checkpoint"):
        load(path)


def test_sample_needs_no_encoder():
    x, alpha = synthetic()
    model = gmm_model(x)
    train(model, x, alpha, TrainConfig(epochs=2, batch_size=32, seed=0, device="cpu"))
    for net in (model.embed_x, model.encoder, model.encode_mu, model.encode_sigma):
        for p in net.parameters():
            p.data.fill_(math.nan)
    assert torch.isfinite(model.sample(0.5, 10, torch.Generator().manual_seed(0))).all()
