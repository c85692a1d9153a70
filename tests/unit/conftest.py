"""Fixtures shared by the sampler and arm tests: tiny real models, briefly trained on a synthetic table."""

from __future__ import annotations

import pytest
from cr3bp_synthetic import synthetic_hq


@pytest.fixture(scope="session")
def tiny_hq():
    """A synthetic high-quality table: 48 rows at :data:`cr3bp_synthetic.TRAIN_ALPHAS`."""
    return synthetic_hq(48)


@pytest.fixture(scope="session")
def tiny_models(one_torch_thread, tiny_hq):
    """Every CR3BP model (``small`` preset), trained 5 full-batch epochs on :func:`tiny_hq`."""
    from amorgs.models.cr3bp_models import TRAINERS
    from amorgs.models.training import TrainConfig

    brief = TrainConfig(epochs=5, batch_size=1024, lr=5e-3, seed=0, device="cpu")
    return {name: train(tiny_hq, "small", brief) for name, train in TRAINERS.items()}


@pytest.fixture(scope="session")
def tiny_models_dir(tiny_models, tmp_path_factory):
    """:func:`tiny_models` saved as checkpoints, named as the train step names them."""
    from amorgs.models import cvae, lstm
    from amorgs.models.samplers import CHECKPOINTS

    d = tmp_path_factory.mktemp("models")
    for name, model in tiny_models.items():
        (lstm.save if name == "lstm" else cvae.save)(model, d / CHECKPOINTS[name])
    return d
