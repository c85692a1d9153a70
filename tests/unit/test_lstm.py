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


@pytest.mark.parametrize("config", [LSTMConfig.small(), LSTMConfig(encoder=(5, 24), hidden=12, decoder=(24, 3))])
def test_recurrence_equals_torch_lstm_on_the_repeated_input_sequence(config):
    """The hand-written recurrence (input projection once per row) gives nn.LSTM's states and gradients."""
    torch.manual_seed(3)
    model = ControlLSTM(config)
    h = torch.randn(7, config.encoder[-1], requires_grad=True)
    n = config.n_steps
    seq = torch.cat([h[:, None, :].expand(7, n, h.shape[1]), model.steps[None, :, None].expand(7, n, 1)], dim=2)
    reference, _ = model.lstm(seq)
    ours = model.recurrence(h)
    torch.testing.assert_close(ours, reference, atol=1e-6, rtol=1e-5)
    weights = torch.randn_like(reference)
    grads_ref = torch.autograd.grad((reference * weights).sum(), [h, *model.lstm.parameters()])
    grads_ours = torch.autograd.grad((ours * weights).sum(), [h, *model.lstm.parameters()])
    for ref, got in zip(grads_ref, grads_ours, strict=True):
        torch.testing.assert_close(got, ref, atol=1e-5, rtol=1e-4)
