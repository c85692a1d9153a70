"""AmorGS end to end on De Jong's 5th function (paper Sec. V.A): BFGS minima → CVAE → samples at unseen α.

Settings (chosen so that this passes reliably on one CPU core in ≈ 25–30 s; see the report in the commit):
26 training α (every other point of the grid iπ/100), 16 uniform BFGS starts each (416 solves, ≈ 3 s),
minima kept when converged with J ≤ 10; CVAE preset ``small`` (Table 3 encoder/decoder, K = 2, 2-D latent,
(64, 64) prior MLPs), full-batch Adam, lr 5e-3, 1500 epochs.  Small mini-batches (64) with batch norm
trained far worse in the same time; the (512, 512, 512) prior of Table 3 is ≈ 5× slower per step.
1500 epochs: 0.977–0.986 within radius 3 and 8/8 minima covered at the four test α, against the thresholds
0.9 / 0.8 and 8 / 7.  Training is not bit-reproducible across CPUs (torch's kernels follow the instruction set):
on an AMD EPYC (2026-12-03) seeds 0–3 gave a worst test α of 0.865, 0.878, 0.979, 0.935 at 1500 epochs, but
0.497 (seed 0, α = π/3), 0.843, 0.964, 0.905 at 750 — so the test keeps 1500 (750 for a while, issue 22 §4).
"""

from __future__ import annotations

import math
import time

import numpy as np
import pandas as pd
import pytest
import torch
from matplotlib.figure import Figure

from amorgs.analysis.dejong_eval import prediction_metrics
from amorgs.figures.dejong import fig16_dejong_predictions
from amorgs.models.cvae import CVAEConfig, GMMPriorCVAE, Normalizer
from amorgs.models.training import TrainConfig, train
from amorgs.problems.dejong import DeJong5

SEED = 0
TRAIN_ALPHAS = [i * math.pi / 100 for i in range(0, 51, 2)]
TEST_ALPHAS = [math.pi / 9, 2 * math.pi / 9, math.pi / 3, 4 * math.pi / 9]
STARTS_PER_ALPHA = 16
MAX_OBJECTIVE = 10.0  # the workflow's De Jong filter: hole minima have J ≈ 1, plateau stops J ≈ 500
TRAIN = TrainConfig(epochs=1500, batch_size=512, lr=5e-3, seed=SEED, device="cpu")


def bfgs_minima() -> tuple[np.ndarray, np.ndarray]:
    problem = DeJong5()
    solver = problem.make_local_solver({"gtol": 1e-6})
    rng = np.random.default_rng(SEED)
    xs, alphas = [], []
    for alpha in TRAIN_ALPHAS:
        for x0 in problem.sample_uniform(alpha, STARTS_PER_ALPHA, rng):
            rec = solver.solve(x0, alpha)
            if rec.converged and rec.objective <= MAX_OBJECTIVE:
                xs.append(rec.x)
                alphas.append(alpha)
    return np.array(xs), np.array(alphas)


@pytest.fixture
def one_torch_thread():
    """Small networks: one intra-op thread is fastest, and avoids spinning against other jobs on the box."""
    before = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(before)


@pytest.mark.slow
def test_cvae_predicts_the_minima_at_unseen_alpha(one_torch_thread):
    x, alpha = bfgs_minima()
    assert len(x) > 0.9 * len(TRAIN_ALPHAS) * STARTS_PER_ALPHA

    torch.manual_seed(SEED)
    model = GMMPriorCVAE(CVAEConfig.small(x_dim=2, latent_dim=2, n_components=2), Normalizer.from_data(x))
    t0 = time.perf_counter()
    history = train(model, x, alpha, TRAIN)
    train_s = time.perf_counter() - t0
    assert history["loss"][-1] < 0.1 * history["loss"][0]

    generator = torch.Generator().manual_seed(SEED)
    samples = {a: model.sample(a, 1000, generator).numpy() for a in TEST_ALPHAS}
    metrics = {a: prediction_metrics(s, a, radius=3.0) for a, s in samples.items()}
    print(f"\ntrained {TRAIN.epochs} epochs on {len(x)} minima in {train_s:.1f} s")
    for a, m in metrics.items():
        print(f"  α = {a / math.pi:.3f}π: {m['fraction_within_radius']:.3f} within 3, {m['minima_covered']}/8 covered")

    first = metrics[math.pi / 9]
    assert first["fraction_within_radius"] >= 0.9
    assert first["minima_covered"] == 8
    for m in metrics.values():  # the other unseen α: looser, as a regression guard
        assert m["fraction_within_radius"] >= 0.8 and m["minima_covered"] >= 7
    train_df = pd.DataFrame({"alpha": alpha, "x1": x[:, 0], "x2": x[:, 1]})
    assert isinstance(fig16_dejong_predictions(train_df, samples, TRAIN_ALPHAS[::5]), Figure)
