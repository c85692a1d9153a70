"""Early stopping (issue 40 §3): a seeded held-out share, its loss every epoch, a stop after ``patience`` epochs
without improvement, and the best epoch's weights restored — on a real GMM-prior CVAE."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from amorgs.models.cvae import CVAEConfig, GMMPriorCVAE, Normalizer
from amorgs.models.training import TrainConfig, _validation_loss, train


def data(n: int = 400):
    rng = np.random.default_rng(0)
    alpha = rng.uniform(size=n)
    x = np.column_stack([alpha * 3 + rng.normal(scale=0.1, size=n), rng.normal(size=n), rng.normal(size=n)])
    return x, alpha


def fit(**cfg):
    x, alpha = data()
    torch.manual_seed(0)
    model = GMMPriorCVAE(CVAEConfig.small(x_dim=3, latent_dim=2, n_components=2), Normalizer.from_data(x))
    history = train(model, x, alpha, TrainConfig(batch_size=64, lr=5e-3, device="cpu", progress_every=0, **cfg))
    return model, history


def test_patience_stops_early_and_restores_the_best_epoch():
    model, history = fit(epochs=400, validation_fraction=0.2, patience=10)
    ran = len(history["epoch"])
    best = int(history["best_epoch"][0])
    assert ran < 400 and ran - best == 10  # stopped once 10 epochs passed without improvement
    val = history["val_loss"]
    assert val[best - 1] <= min(val) * (1 + 1e-3)  # the best within min_delta
    # the restored weights are the best epoch's: their held-out loss is that epoch's val_loss
    x, alpha = data()
    split = torch.randperm(400, generator=torch.Generator().manual_seed(0 + 1))[:80]
    cfg = TrainConfig(batch_size=64, seed=0, device="cpu")
    got = _validation_loss(model, torch.as_tensor(x[split.numpy()], dtype=torch.float32),
                           torch.as_tensor(alpha[split.numpy()], dtype=torch.float32)[:, None], cfg)
    assert got == pytest.approx(val[best - 1], rel=1e-5)
    again, history_again = fit(epochs=400, validation_fraction=0.2, patience=10)  # seeded: a rerun is the same
    assert history_again["val_loss"] == val
    assert all(torch.equal(a, b) for a, b in zip(model.state_dict().values(), again.state_dict().values()))


def test_without_a_validation_share_training_is_what_it_was():
    _, plain = fit(epochs=5)
    _, logged = fit(epochs=5, validation_fraction=0.2)  # held out and reported, never stops
    assert "val_loss" not in plain and len(logged["val_loss"]) == 5 and "best_epoch" not in logged
    with pytest.raises(ValueError, match="validation share for patience"):
        fit(epochs=5, patience=3)
    with pytest.raises(ValueError, match="validation_fraction"):
        fit(epochs=5, validation_fraction=1.0)
