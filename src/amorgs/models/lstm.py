"""Bidirectional LSTM that generates the control sequence (u_1 … u_N) from (τ_s, τ_i, τ_f, m_f, α).

Paper Sec. IV.D, Fig. 15b, Table 4: an encoder MLP [5, 512, 512, 512] embeds the conditioning, a
bidirectional LSTM runs over the N = 20 segments (its input at step k is the embedding and k/N), and a
per-step decoder MLP [512, 512, 512, 3] outputs the Cartesian throttle vector u_k = ρ_k û_k ∈ [−1, 1]³
(tanh head).  Loss: MSE on the Cartesian components (they are continuous where the angles wrap).

Speed: the LSTM's input is the same embedding at every step plus k/N, so :meth:`ControlLSTM.recurrence`
projects the embedding through the input weights once per row instead of once per step, then runs the
standard LSTM cell (PyTorch's gate order i, f, g, o; the parameters are those of the ``nn.LSTM`` it holds, so
checkpoints are unchanged).  Equal to ``nn.LSTM`` to float rounding (tests/unit/test_lstm.py); per training
epoch on CPU 1.4× (paper widths) to 1.75× (small) faster (docs/performance.md, "Training the CR3BP models").

Normalisation: the conditioning is mapped to [0, 1] with a :class:`~amorgs.models.cvae.Normalizer` fitted on
the training data and stored in the model's buffers; the outputs need none (already in [−1, 1]).
``amorgs.problems.cr3bp.controls`` (re-exported here) converts between the stored (θ, φ, ρ) layout and u.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
import torch
from torch import Tensor, nn

from amorgs.models.cvae import Normalizer, mlp
from amorgs.problems.cr3bp.controls import cartesian_controls, spherical_controls

CHECKPOINT_FORMAT = "amorgs-lstm-1"
__all__ = ["ControlLSTM", "LSTMConfig", "cartesian_controls", "load", "save", "spherical_controls"]


@dataclass(frozen=True)
class LSTMConfig:
    """Layer sizes: ``encoder`` starts at the conditioning width (5), ``decoder`` ends at 3; the LSTM has
    ``hidden`` units per direction, so the decoder input is 2·hidden."""

    n_steps: int = 20
    encoder: tuple[int, ...] = (5, 512, 512, 512)
    hidden: int = 256
    decoder: tuple[int, ...] = (512, 512, 512, 3)
    negative_slope: float = 0.01

    @classmethod
    def paper(cls) -> "LSTMConfig":
        """Table 4 of the paper (bidirectional: 2 × 256 = 512 features into the decoder)."""
        return cls()

    @classmethod
    def small(cls) -> "LSTMConfig":
        """A CPU-friendly preset for smoke runs and tests."""
        return cls(encoder=(5, 64, 64), hidden=32, decoder=(64, 64, 3))


class ControlLSTM(nn.Module):
    """p(u_1 … u_N | τ, m_f, α) as a deterministic sequence regressor (paper Fig. 15b)."""

    def __init__(self, config: LSTMConfig, normalizer: Normalizer | None = None):
        super().__init__()
        if config.decoder[0] != 2 * config.hidden or config.decoder[-1] != 3:
            raise ValueError(f"LSTMConfig: decoder must start at 2·hidden = {2 * config.hidden} and end at 3")
        self.config = config
        self.normalizer = normalizer or Normalizer(torch.zeros(config.encoder[0]), torch.ones(config.encoder[0]))
        self.encoder = mlp(list(config.encoder), config.negative_slope, head=False)
        self.lstm = nn.LSTM(config.encoder[-1] + 1, config.hidden, batch_first=True, bidirectional=True)
        self.decoder = mlp(list(config.decoder), config.negative_slope, head=True)
        self.register_buffer("steps", torch.arange(config.n_steps, dtype=torch.float32) / config.n_steps)

    def forward(self, cond: Tensor) -> Tensor:
        """cond (B, 5) in physical units → controls (B, N, 3) in [−1, 1]."""
        h = self.encoder(self.normalizer.transform(cond))
        out = self.recurrence(h)
        b, n = out.shape[:2]
        y = self.decoder(out.reshape(b * n, -1)).reshape(b, n, 3)
        return torch.tanh(y)

    def recurrence(self, h: Tensor) -> Tensor:
        """The bidirectional LSTM over the sequence x_k = [h, k/N], k = 0 … N−1: embedding h (B, E) →
        hidden states (B, N, 2·hidden), forward direction first, as ``self.lstm`` on that sequence gives."""
        n, width = self.config.n_steps, h.shape[1]
        directions = []
        for suffix, order in (("", range(n)), ("_reverse", range(n - 1, -1, -1))):
            w_in = getattr(self.lstm, f"weight_ih_l0{suffix}")  # (4·hidden, E + 1); last column: k/N
            w_rec = getattr(self.lstm, f"weight_hh_l0{suffix}").T
            constant = h @ w_in[:, :width].T + getattr(self.lstm, f"bias_ih_l0{suffix}") \
                + getattr(self.lstm, f"bias_hh_l0{suffix}")
            state = cell = h.new_zeros(h.shape[0], self.config.hidden)
            states: list[Tensor] = [h] * n
            for k in order:
                gate_i, gate_f, gate_g, gate_o = (constant + self.steps[k] * w_in[:, width] + state @ w_rec).chunk(4, 1)
                cell = torch.sigmoid(gate_f) * cell + torch.sigmoid(gate_i) * torch.tanh(gate_g)
                state = torch.sigmoid(gate_o) * torch.tanh(cell)
                states[k] = state
            directions.append(torch.stack(states, dim=1))
        return torch.cat(directions, dim=2)

    def loss(self, x: Tensor, cond: Tensor) -> tuple[Tensor, dict[str, float]]:
        """MSE between generated and true Cartesian controls; x is (B, N, 3) or (B, 3N)."""
        target = x.reshape(x.shape[0], self.config.n_steps, 3)
        mse = torch.mean((self(cond) - target) ** 2)
        return mse, {"loss": float(mse.detach())}

    @torch.no_grad()
    def generate(self, cond: np.ndarray) -> np.ndarray:
        """Controls in the stored (θ, φ, ρ) layout, shape (n, 3N), for conditioning rows (n, 5)."""
        self.eval()
        device = next(self.parameters()).device
        u = self(torch.as_tensor(np.asarray(cond), dtype=torch.float32, device=device)).cpu().numpy()
        return spherical_controls(u)


def save(model: ControlLSTM, path: str | Path) -> None:
    """One checkpoint: config and state dict (normaliser bounds included)."""
    state = {k: v.detach().cpu() for k, v in model.state_dict().items()}
    torch.save({"format": CHECKPOINT_FORMAT, "config": asdict(model.config), "state_dict": state}, Path(path))


def load(path: str | Path) -> ControlLSTM:
    """Rebuild a model written by :func:`save`, on the CPU and in eval mode."""
    ckpt = torch.load(Path(path), map_location="cpu", weights_only=True)
    if ckpt.get("format") != CHECKPOINT_FORMAT:
        raise ValueError(f"{path}: not an amorgs LSTM checkpoint (format {ckpt.get('format')!r})")
    cfg = LSTMConfig(**{k: tuple(v) if isinstance(v, list) else v for k, v in ckpt["config"].items()})
    model = ControlLSTM(cfg, Normalizer(ckpt["state_dict"]["normalizer.low"], ckpt["state_dict"]["normalizer.high"]))
    model.load_state_dict(ckpt["state_dict"])
    return model.eval()
