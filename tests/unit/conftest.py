"""Fixtures shared by the sampler and arm tests: tiny real models, briefly trained on a synthetic table."""

from __future__ import annotations

import pytest
from cr3bp_synthetic import TRAIN_ALPHAS, synthetic_hq


@pytest.fixture(scope="session")
def tiny_hq():
    """A synthetic high-quality table: 48 rows at :data:`cr3bp_synthetic.TRAIN_ALPHAS`."""
    return synthetic_hq(48)


@pytest.fixture(scope="session")
def tiny_models(one_torch_thread, tiny_hq):
    """Every CR3BP model (``small`` preset), trained 5 full-batch epochs on :func:`tiny_hq`."""
    from amorgs.models.names import MODELS
    from amorgs.models.training import TrainConfig

    brief = TrainConfig(epochs=5, batch_size=1024, lr=5e-3, seed=0, device="cpu")
    return {**{m.name: m.train(tiny_hq, "small", brief) for m in MODELS},
            "selector": tiny_selector(tiny_hq)}


def tiny_selector(hq):
    """A transfer selector fitted on synthetic transfers of ``hq``'s rows: every row solved at each other training
    α, landing high-quality when its time of flight is short (as the frontier's reuse starts did)."""
    import pandas as pd

    from amorgs.models.selector import TransferSelector
    from amorgs.problems import get_problem

    names = get_problem("cr3bp").variable_names
    parts = []
    for target in TRAIN_ALPHAS:
        rows = hq[hq["alpha"] != target]
        tof = rows["tau_s"] + rows["tau_i"] + rows["tau_f"]
        guesses = rows[list(names)].rename(columns={n: f"guess_{n}" for n in names})
        parts.append(guesses.assign(alpha=target, source_alpha=rows["alpha"].to_numpy(), seed=0,
                                    start=range(len(rows)), converged=(tof < tof.median()).to_numpy(),
                                    m_f=420.0, iterations=(100 + 10 * tof).astype(int).to_numpy()))
    return TransferSelector(seed=0, max_iter=20).fit(pd.concat(parts, ignore_index=True), names)


@pytest.fixture(scope="session")
def tiny_models_dir(tiny_models, tmp_path_factory):
    """:func:`tiny_models` saved as checkpoints, named as the train step names them."""
    from amorgs.models.names import get_model
    from amorgs.models.selector import SELECTOR_FILE

    d = tmp_path_factory.mktemp("models")
    for name, model in tiny_models.items():
        if name == "selector":
            model.save(d / SELECTOR_FILE)
        else:
            entry = get_model(name)
            entry.save(model, d / entry.checkpoint)
    return d
