"""Training entry points for the LT-CR3BP generative models (paper Sec. IV.B–D, V.B.1–2, Tables 4–5).

Input everywhere: a high-quality solution table ``hq`` (one row per solution, any number of rows ≥ 2) with
columns ``alpha`` and the stored decision vector ``tau_s, tau_i, tau_f`` (TU), ``m_f`` (kg), ``theta_kk``,
``phi_kk`` (rad), ``rho_kk`` (throttle, [0, 1]) for k = 01 … 20.  Pass rows at the *training* α only: every
row given is trained on, and nothing else about the data (its size, its α values) is assumed.

The three models (their entries in the model table :data:`amorgs.models.names.MODELS` name these trainers)::

    cvae_gmm      GMMPriorCVAE   x = (τ_s, τ_i, τ_f, m_f)                     cond α
    vanilla_cvae  VanillaCVAE    x = (τ_s, τ_i, τ_f, m_f, u_1, …, u_20)       cond α
    lstm          ControlLSTM    x = (u_1, …, u_20), shape (20, 3)           cond (τ_s, τ_i, τ_f, m_f, α)

``u_k = ρ_k (cos φ_k cos θ_k, cos φ_k sin θ_k, sin φ_k)`` is the Cartesian throttle vector of segment k
(dimensionless, ‖u_k‖ ≤ 1, :func:`amorgs.models.lstm.cartesian_controls`).

Vanilla layout choice: the vanilla CVAE models the *Cartesian* controls, not the stored angles.  The azimuth
wraps (θ = 0.01 and 6.27 rad are neighbours but far apart as numbers), and θ is undefined at the poles and
θ, φ both at zero throttle, so an MSE on (θ, φ, ρ) penalises distances that are not there; the components of
u are continuous everywhere.  Three numbers per segment keep the vector 64 long, as in Table 5.
:func:`vanilla_vectors` builds that layout and :func:`stored_from_vanilla` maps samples back to the stored
layout (ρ = ‖u‖ clipped to 1); both live in :mod:`amorgs.models.baselines` (the continuation baseline uses them
without torch) and are imported here.

Normalisation: every model gets a :class:`~amorgs.models.cvae.Normalizer` fitted on its training data
(column-wise min/max), stored in its checkpoint, so a CVAE's sigmoid output spans the training range.

Presets (``"paper"``, ``"small"``): the paper's Table 4 (GMM CVAE, K = 20, 4-D latent; LSTM) and Table 5
(vanilla CVAE, 64-D latent) widths, or the narrow CPU-friendly widths of ``CVAEConfig.small`` /
``VanillaCVAEConfig.small`` / ``LSTMConfig.small`` with the same input, latent and component sizes.

Training: :func:`amorgs.models.training.train` (Adam) with the given :class:`TrainConfig`; ``train_cfg.seed``
also seeds the initial weights, so one (data, preset, config) gives one model on a given device and thread
count.  The layers use batch norm: large batches (≥ 512 rows, or the full table) with lr ≈ 5e-3 train well;
mini-batches of 64 trained poorly in our De Jong runs.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pandas as pd
import torch

from amorgs.models.baselines import stored_from_vanilla, vanilla_vectors  # noqa: F401  (the layout, torch-free)
from amorgs.models.cvae import CVAEConfig, GMMPriorCVAE, Normalizer, VanillaCVAE, VanillaCVAEConfig
from amorgs.models.lstm import ControlLSTM, LSTMConfig, cartesian_controls
from amorgs.models.training import TrainConfig, train
from amorgs.problems.cr3bp.transcription import N_SEGMENTS, variable_names

from amorgs.models.names import CR3BP_PRESETS as PRESETS  # noqa: E402  (the one registry of presets)
TIME_MASS_COLUMNS = ("tau_s", "tau_i", "tau_f", "m_f")
#: Latent size of the GMM-prior CVAE and its number of mixture components K (paper Sec. V.B.2).
GMM_LATENT_DIM = 4
GMM_COMPONENTS = 20
#: Width of the vanilla CVAE's data vector and of its standard-Gaussian latent (paper Table 5).
VANILLA_DIM = 4 + 3 * N_SEGMENTS

OnEpoch = Callable[[int, dict[str, float]], None]


# ------------------------------------------------------------------------------------------- presets
def _check_preset(preset: str) -> None:
    if preset not in PRESETS:
        raise ValueError(f"unknown model preset {preset!r}; choose one of {PRESETS}")


def time_mass_cvae_config(preset: str) -> CVAEConfig:
    """Layer widths of the time & mass CVAE: Table 4 (``paper``) or the narrow ``small`` widths."""
    _check_preset(preset)
    if preset == "paper":
        return CVAEConfig.cr3bp_paper()
    return CVAEConfig.small(x_dim=len(TIME_MASS_COLUMNS), latent_dim=GMM_LATENT_DIM, n_components=GMM_COMPONENTS)


def vanilla_cvae_config(preset: str) -> VanillaCVAEConfig:
    """Layer widths of the vanilla CVAE: Table 5 (``paper``) or the narrow ``small`` widths (64-D latent)."""
    _check_preset(preset)
    if preset == "paper":
        return VanillaCVAEConfig.cr3bp_paper()
    return VanillaCVAEConfig.small(x_dim=VANILLA_DIM, latent_dim=VANILLA_DIM)


def lstm_config(preset: str) -> LSTMConfig:
    """Layer sizes of the control LSTM: Table 4 (``paper``) or :meth:`LSTMConfig.small`."""
    _check_preset(preset)
    return LSTMConfig.paper() if preset == "paper" else LSTMConfig.small()


# ------------------------------------------------------------------------------------------- layouts
def time_mass(hq: pd.DataFrame) -> np.ndarray:
    """(τ_s, τ_i, τ_f, m_f) of every row, shape (n, 4), TU and kg."""
    return hq[list(TIME_MASS_COLUMNS)].to_numpy(dtype=np.float64, copy=True)


def stored_vectors(hq: pd.DataFrame) -> np.ndarray:
    """The stored decision vectors of every row, shape (n, 64) (:func:`variable_names` order)."""
    return hq[list(variable_names(N_SEGMENTS))].to_numpy(dtype=np.float64, copy=True)


def lstm_conditioning(time_and_mass: np.ndarray, alpha: float | np.ndarray) -> np.ndarray:
    """LSTM input rows (τ_s, τ_i, τ_f, m_f, α), shape (n, 5); ``alpha`` a scalar or one value per row."""
    tm = np.asarray(time_and_mass, dtype=np.float64).reshape(-1, len(TIME_MASS_COLUMNS))
    a = np.broadcast_to(np.asarray(alpha, dtype=np.float64), (len(tm),))
    return np.column_stack([tm, a])


def subsample(hq: pd.DataFrame, fraction: float, seed: int) -> pd.DataFrame:
    """A random ``fraction`` ∈ (0, 1] of the rows of every α (rounded, at least one row per α), for the
    reduced-data study of Fig. 18; order kept, index reset.  ``fraction`` = 1 returns all rows."""
    if not 0 < fraction <= 1:
        raise ValueError(f"fraction must be in (0, 1], got {fraction}")
    rng = np.random.default_rng(seed)
    keep = np.zeros(len(hq), dtype=bool)
    for rows in hq.groupby("alpha", sort=True).indices.values():
        k = max(1, int(round(fraction * len(rows))))
        keep[rng.choice(rows, size=k, replace=False)] = True
    return hq.loc[keep].reset_index(drop=True)


def _alpha(hq: pd.DataFrame) -> np.ndarray:
    return hq["alpha"].to_numpy(dtype=np.float64, copy=True)


# ------------------------------------------------------------------------------------------- training
def train_time_mass_cvae(
    hq: pd.DataFrame, preset: str, train_cfg: TrainConfig, on_epoch: OnEpoch | None = None
) -> GMMPriorCVAE:
    """GMM-prior CVAE of p(τ_s, τ_i, τ_f, m_f | α) on ``hq`` (paper Table 4); returned on the CPU, eval mode.

    ``on_epoch(epoch, metrics)`` receives ``loss``, ``recon``, ``kl`` and ``epoch_s`` after every epoch.
    """
    x = time_mass(hq)
    torch.manual_seed(train_cfg.seed)
    model = GMMPriorCVAE(time_mass_cvae_config(preset), Normalizer.from_data(x))
    train(model, x, _alpha(hq), train_cfg, on_epoch)
    return model.cpu().eval()


def train_vanilla_cvae(
    hq: pd.DataFrame, preset: str, train_cfg: TrainConfig, on_epoch: OnEpoch | None = None
) -> VanillaCVAE:
    """Vanilla CVAE of p(x | α) for the whole vector in the Cartesian layout of :func:`vanilla_vectors`
    (paper Table 5); returned on the CPU, eval mode.  ``on_epoch`` as for :func:`train_time_mass_cvae`."""
    x = vanilla_vectors(stored_vectors(hq))
    torch.manual_seed(train_cfg.seed)
    model = VanillaCVAE(vanilla_cvae_config(preset), Normalizer.from_data(x))
    train(model, x, _alpha(hq), train_cfg, on_epoch)
    return model.cpu().eval()


def train_control_lstm(
    hq: pd.DataFrame, preset: str, train_cfg: TrainConfig, on_epoch: OnEpoch | None = None
) -> ControlLSTM:
    """Control LSTM u_1 … u_20 = f(τ_s, τ_i, τ_f, m_f, α) with an MSE on the Cartesian controls (paper
    Sec. IV.D, Table 4); returned on the CPU, eval mode.  ``on_epoch`` receives ``loss`` and ``epoch_s``."""
    cond = lstm_conditioning(time_mass(hq), _alpha(hq))
    u = cartesian_controls(stored_vectors(hq), N_SEGMENTS)
    torch.manual_seed(train_cfg.seed)
    model = ControlLSTM(lstm_config(preset), Normalizer.from_data(cond))
    train(model, u, cond, train_cfg, on_epoch)
    return model.cpu().eval()

