"""The training loop reports its progress while it runs, one flushed line every few epochs."""

from __future__ import annotations

import re

import numpy as np
import torch

from amorgs.models.cvae import CVAEConfig, GMMPriorCVAE, Normalizer
from amorgs.models.training import TrainConfig, train

LINE = re.compile(r"^epoch (\d+)/(\d+)  loss \S+  .*\| \S+ s/epoch, \d+ s left$")


def tiny_run(capsys, **cfg) -> list[str]:
    rng = np.random.default_rng(0)
    x = rng.normal(size=(40, 3))
    alpha = rng.uniform(size=40)
    torch.manual_seed(0)
    model = GMMPriorCVAE(CVAEConfig.small(x_dim=3, latent_dim=2, n_components=2), Normalizer.from_data(x))
    train(model, x, alpha, TrainConfig(batch_size=16, lr=1e-3, device="cpu", **cfg))
    return capsys.readouterr().out.splitlines()


def epochs_reported(lines: list[str]) -> list[int]:
    for line in lines:
        assert LINE.match(line), line
    return [int(LINE.match(line).group(1)) for line in lines]


def test_default_reports_about_twenty_times_first_and_last(capsys):
    assert epochs_reported(tiny_run(capsys, epochs=45)) == [1, *range(3, 46, 3)]
    assert epochs_reported(tiny_run(capsys, epochs=4)) == [1, 2, 3, 4]


def test_explicit_interval_and_silence(capsys):
    assert epochs_reported(tiny_run(capsys, epochs=7, progress_every=3)) == [1, 3, 6, 7]
    assert tiny_run(capsys, epochs=3, progress_every=0) == []
