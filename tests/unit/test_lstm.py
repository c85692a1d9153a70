"""The control LSTM: conversions, shapes, learning a conditional pattern, save/load."""

import numpy as np
import pytest
import torch

from amorgs.models.cvae import Normalizer
from amorgs.models.lstm import ControlLSTM, LSTMConfig, cartesian_controls, load, save, spherical_controls
from amorgs.models.training import TrainConfig, train


def test_spherical_cartesian_round_trip():
    rng = np.random.default_rng(0)
    n, N = 16, 20
    x = np.zeros((n, 4 + 3 * N))
    x[:, 4::3] = rng.uniform(0, 2 * np.pi, (n, N))
    x[:, 5::3] = rng.uniform(-1.5, 1.5, (n, N))
    x[:, 6::3] = rng.uniform(0.01, 1, (n, N))
    back = spherical_controls(cartesian_controls(x))
    np.testing.assert_allclose(back, x[:, 4:], atol=1e-9)


def test_learns_a_conditional_control_pattern():
    torch.manual_seed(0)
    rng = np.random.default_rng(0)
    n = 256
    cond = np.column_stack([rng.uniform(0, 40, n), rng.uniform(0, 15, n), rng.uniform(0, 15, n),
                            rng.uniform(400, 440, n), rng.uniform(0.1, 1, n)])
    k = np.arange(20) / 20
    # target: u_z follows α, u_x a ramp in time, u_y zero
    target = np.stack([np.broadcast_to(k, (n, 20)) - 0.5, np.zeros((n, 20)), np.repeat(cond[:, 4:5] - 0.5, 20, 1)], -1)
    model = ControlLSTM(LSTMConfig.small(), Normalizer.from_data(cond))
    hist = train(model, target, cond, TrainConfig(epochs=60, batch_size=64, lr=3e-3, seed=1, device="cpu"))
    assert hist["loss"][-1] < 0.1 * hist["loss"][0]
    model.eval()
    with torch.no_grad():
        lo = model(torch.tensor(np.r_[cond[0, :4], 0.1][None], dtype=torch.float32))[0, :, 2].mean()
        hi = model(torch.tensor(np.r_[cond[0, :4], 1.0][None], dtype=torch.float32))[0, :, 2].mean()
    assert float(hi - lo) > 0.4  # conditioning on α changes the output


def test_generate_layout_and_save_load(tmp_path):
    torch.manual_seed(0)
    cond = np.column_stack([np.linspace(1, 30, 8), np.ones(8), np.ones(8), np.full(8, 420.0), np.linspace(0.1, 1, 8)])
    model = ControlLSTM(LSTMConfig.small(), Normalizer.from_data(cond)).eval()
    u = model.generate(cond)
    assert u.shape == (8, 60)
    assert np.all((u[:, 0::3] >= 0) & (u[:, 0::3] < 2 * np.pi))
    assert np.all(np.abs(u[:, 1::3]) <= np.pi / 2) and np.all((u[:, 2::3] >= 0) & (u[:, 2::3] <= 1))
    save(model, tmp_path / "lstm.pt")
    np.testing.assert_array_equal(load(tmp_path / "lstm.pt").generate(cond), u)
    with pytest.raises(ValueError, match="decoder"):
        ControlLSTM(LSTMConfig(hidden=10))
