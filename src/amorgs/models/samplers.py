"""Initial-guess samplers for warm-starting the solver (DESIGN.md contract, paper Sec. V.B.7).

Every sampler has ``sample(alpha, n, rng) -> ndarray (n, 3N+4)`` in the stored decision-vector layout
(see :mod:`amorgs.problems.cr3bp.transcription`) and returns *valid* guesses: inside the problem's bounds,
azimuths wrapped to [0, 2π), throttles clipped to [0, 1].  ``rng`` is a ``numpy.random.Generator``; learned
samplers derive their torch seed from it, so a seeded rng gives identical samples.

The five samplers of the ablation (paper Sec. V.B.7), for the LT-CR3BP (N = 20, 64-vectors)::

    uniform               τ, m_f, controls ~ the problem's uniform distribution
    cvae_uniform_control  τ, m_f ~ GMM-prior CVAE(α);          controls uniform
    uniform_lstm_control  τ, m_f uniform;                      controls = LSTM(τ, m_f, α)
    vanilla_cvae          the whole vector ~ vanilla CVAE(α)   (Cartesian controls, see cr3bp_models)
    amorgs                τ, m_f ~ GMM-prior CVAE(α);          controls = LSTM(τ, m_f, α)

The LSTM is deterministic given its conditioning; all randomness of a learned sampler comes from ``rng``:
first one draw of the torch seed (when a CVAE is sampled), then the uniform parts in layout order.
:func:`build_sampler` loads the models from a directory of checkpoints named as in :data:`CHECKPOINTS`.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Protocol

import numpy as np
import torch

from amorgs.models import cvae, lstm
from amorgs.models.cr3bp_models import lstm_conditioning, stored_from_vanilla
from amorgs.problems import Problem
from amorgs.problems.base import check_alpha

SAMPLER_NAMES = ("uniform", "cvae_uniform_control", "uniform_lstm_control", "vanilla_cvae", "amorgs")
SAMPLER_LABELS = {
    "uniform": "Uniform",
    "uniform_lstm_control": "Uniform time & mass, LSTM control",
    "cvae_uniform_control": "CVAE time & mass, uniform control",
    "vanilla_cvae": "Vanilla CVAE",
    "amorgs": "AmorGS",
}
#: Model name → checkpoint file name inside a models directory (written by the train step).
CHECKPOINTS = {"cvae_gmm": "cvae_gmm.pt", "vanilla_cvae": "vanilla_cvae.pt", "lstm": "lstm.pt"}


class Sampler(Protocol):
    name: str

    def sample(self, alpha: float, n: int, rng: np.random.Generator) -> np.ndarray: ...


def make_valid(x: np.ndarray, problem: Problem) -> np.ndarray:
    """Wrap azimuths (every ``theta_*`` column) to [0, 2π) and clip everything else into the bounds."""
    x = np.array(x, dtype=float, copy=True)
    theta = [i for i, name in enumerate(problem.variable_names) if name.startswith("theta_")]
    x[:, theta] = np.mod(x[:, theta], 2 * math.pi)
    return np.clip(x, problem.lower, problem.upper)


class UniformSampler:
    """The naive baseline: the problem's own uniform initial-guess distribution (spec §6)."""

    name = "uniform"

    def __init__(self, problem: Problem):
        self.problem = problem

    def sample(self, alpha: float, n: int, rng: np.random.Generator) -> np.ndarray:
        return make_valid(self.problem.sample_uniform(alpha, n, rng), self.problem)


def torch_generator(rng: np.random.Generator) -> torch.Generator:
    """A CPU torch generator seeded by one draw from ``rng`` (so a seeded ``rng`` fixes the CVAE noise)."""
    return torch.Generator().manual_seed(int(rng.integers(0, 2**63 - 1)))


def _time_mass(model: cvae.GMMPriorCVAE, alpha: float, n: int, rng: np.random.Generator) -> np.ndarray:
    """(τ_s, τ_i, τ_f, m_f) samples (n, 4) from the time & mass CVAE, TU and kg."""
    return model.sample(alpha, n, generator=torch_generator(rng)).numpy().astype(np.float64)


class CVAETimeMassUniformControl:
    """τ_s, τ_i, τ_f, m_f from the GMM-prior CVAE at α; the 20 controls from the uniform distribution."""

    name = "cvae_uniform_control"

    def __init__(self, problem: Problem, time_mass_cvae: cvae.GMMPriorCVAE):
        self.problem = problem
        self.cvae = time_mass_cvae

    def sample(self, alpha: float, n: int, rng: np.random.Generator) -> np.ndarray:
        check_alpha(alpha, self.problem.alpha_range, self.problem.name)
        tm = _time_mass(self.cvae, alpha, n, rng)
        x = self.problem.sample_uniform(alpha, n, rng)
        x[:, :4] = tm
        return make_valid(x, self.problem)


class UniformTimeMassLSTMControl:
    """τ_s, τ_i, τ_f, m_f from the uniform distribution; controls from the LSTM given them and α."""

    name = "uniform_lstm_control"

    def __init__(self, problem: Problem, control_lstm: lstm.ControlLSTM):
        self.problem = problem
        self.lstm = control_lstm

    def sample(self, alpha: float, n: int, rng: np.random.Generator) -> np.ndarray:
        x = self.problem.sample_uniform(alpha, n, rng)
        x[:, 4:] = self.lstm.generate(lstm_conditioning(x[:, :4], alpha))
        return make_valid(x, self.problem)


class VanillaCVAESampler:
    """The whole vector from the vanilla CVAE at α, its Cartesian controls mapped back to (θ, φ, ρ)."""

    name = "vanilla_cvae"

    def __init__(self, problem: Problem, vanilla_cvae: cvae.VanillaCVAE):
        self.problem = problem
        self.cvae = vanilla_cvae

    def sample(self, alpha: float, n: int, rng: np.random.Generator) -> np.ndarray:
        check_alpha(alpha, self.problem.alpha_range, self.problem.name)
        v = self.cvae.sample(alpha, n, generator=torch_generator(rng)).numpy().astype(np.float64)
        return make_valid(stored_from_vanilla(v), self.problem)


class AmorGSSampler:
    """AmorGS: τ_s, τ_i, τ_f, m_f from the GMM-prior CVAE at α, then the controls from the LSTM given them."""

    name = "amorgs"

    def __init__(self, problem: Problem, time_mass_cvae: cvae.GMMPriorCVAE, control_lstm: lstm.ControlLSTM):
        self.problem = problem
        self.cvae = time_mass_cvae
        self.lstm = control_lstm

    def sample(self, alpha: float, n: int, rng: np.random.Generator) -> np.ndarray:
        check_alpha(alpha, self.problem.alpha_range, self.problem.name)
        tm = _time_mass(self.cvae, alpha, n, rng)
        x = np.concatenate([tm, self.lstm.generate(lstm_conditioning(tm, alpha))], axis=1)
        return make_valid(x, self.problem)


def _load_cvae(path: Path, cls: type[cvae.GMMPriorCVAE] | type[cvae.VanillaCVAE]):
    """A CVAE checkpoint that must hold a ``cls`` model; ``ValueError`` naming the file otherwise."""
    model = cvae.load(path)
    if not isinstance(model, cls):
        raise ValueError(f"{path}: expected a {cls.__name__}, got {type(model).__name__}")
    return model


def build_sampler(name: str, problem: Problem, models_dir: str | Path) -> Sampler:
    """The sampler called ``name`` (one of :data:`SAMPLER_NAMES`), its models loaded from ``models_dir``.

    Checkpoints are read on the CPU: ``cvae_gmm.pt`` (time & mass CVAE), ``vanilla_cvae.pt`` and ``lstm.pt``,
    only those the sampler needs; ``uniform`` needs none.
    """
    models = Path(models_dir)
    if name == "uniform":
        return UniformSampler(problem)
    if name == "vanilla_cvae":
        return VanillaCVAESampler(problem, _load_cvae(models / CHECKPOINTS["vanilla_cvae"], cvae.VanillaCVAE))
    if name == "cvae_uniform_control":
        return CVAETimeMassUniformControl(problem, _load_cvae(models / CHECKPOINTS["cvae_gmm"], cvae.GMMPriorCVAE))
    if name == "uniform_lstm_control":
        return UniformTimeMassLSTMControl(problem, lstm.load(models / CHECKPOINTS["lstm"]))
    if name == "amorgs":
        gmm = _load_cvae(models / CHECKPOINTS["cvae_gmm"], cvae.GMMPriorCVAE)
        return AmorGSSampler(problem, gmm, lstm.load(models / CHECKPOINTS["lstm"]))
    raise ValueError(f"unknown sampler {name!r}; choose one of {SAMPLER_NAMES}")
