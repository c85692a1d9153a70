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

and three non-neural (or half-neural) baselines that reuse known solutions (issue 11)::

    nearest_alpha            HQ solutions of the nearest training α, unchanged: drawn without replacement
                             until that α's pool is exhausted, then with replacement
    nearest_alpha_perturbed  the same + N(0, σ²) noise in the box-normalised space, then make_valid
    gmm_lstm                 τ, m_f ~ per-training-α Gaussian mixture, blended between the bracketing α;
                             controls = LSTM(τ, m_f, α)

and one built to beat reuse (issue 21 §3)::

    continuation             nearest_alpha's draw, each solution moved to α by a secant to its nearest
                             match at a neighbouring training α
    reuse_cvae               nearest_alpha's draw, each solution replaced by a sample of a CVAE of its
                             correction to α (:mod:`amorgs.models.reuse_cvae`)

The model-free ones (uniform, the two nearest-α arms, continuation) are defined in
:mod:`amorgs.models.baselines`, which imports no torch, and re-exported here.

The LSTM is deterministic given its conditioning; all randomness of a learned sampler comes from ``rng``:
first one draw of the torch seed (when a CVAE is sampled), then the uniform parts in layout order.

Each class's ``build(problem, inputs)`` is its arm's builder in the table of arms
(:data:`amorgs.ablation.arms.ARMS`, which :func:`amorgs.ablation.arms.build_sampler` resolves): ``inputs``
carries the loaded models by name (the model table, :data:`amorgs.models.names.MODELS`), the
high-quality table, the training α and the arm options.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import torch

from amorgs.models import cvae, lstm
from amorgs.models.cvae import torch_generator
from amorgs.models.baselines import (  # noqa: F401  (the model-free samplers, re-exported: one place for all)
    ContinuationSampler,
    NearestAlphaPerturbedSampler,
    NearestAlphaSampler,
    Sampler,
    UniformSampler,
    make_valid,
    nearest_training_alpha,
    stored_from_vanilla,
    training_rows,
    usable_training_alphas,
)
from amorgs.models.cr3bp_models import lstm_conditioning
from amorgs.problems import Problem
from amorgs.problems.base import check_alpha


def _time_mass(model: cvae.GMMPriorCVAE, alpha: float, n: int, rng: np.random.Generator) -> np.ndarray:
    """(τ_s, τ_i, τ_f, m_f) samples (n, 4) from the time & mass CVAE, TU and kg."""
    return model.sample(alpha, n, generator=torch_generator(rng)).numpy().astype(np.float64)


class CVAETimeMassUniformControl:
    """τ_s, τ_i, τ_f, m_f from the GMM-prior CVAE at α; the 20 controls from the uniform distribution."""

    name = "cvae_uniform_control"

    def __init__(self, problem: Problem, time_mass_cvae: cvae.GMMPriorCVAE):
        self.problem = problem
        self.cvae = time_mass_cvae

    @classmethod
    def build(cls, problem: Problem, inputs) -> CVAETimeMassUniformControl:
        return cls(problem, inputs.models["cvae_gmm"])

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

    @classmethod
    def build(cls, problem: Problem, inputs) -> UniformTimeMassLSTMControl:
        return cls(problem, inputs.models["lstm"])

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

    @classmethod
    def build(cls, problem: Problem, inputs) -> VanillaCVAESampler:
        return cls(problem, inputs.models["vanilla_cvae"])

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

    @classmethod
    def build(cls, problem: Problem, inputs) -> AmorGSSampler:
        return cls(problem, inputs.models["cvae_gmm"], inputs.models["lstm"])

    def sample(self, alpha: float, n: int, rng: np.random.Generator) -> np.ndarray:
        check_alpha(alpha, self.problem.alpha_range, self.problem.name)
        tm = _time_mass(self.cvae, alpha, n, rng)
        x = np.concatenate([tm, self.lstm.generate(lstm_conditioning(tm, alpha))], axis=1)
        return make_valid(x, self.problem)


class GMMLSTMSampler:
    """A cheap non-neural density for (τ_s, τ_i, τ_f, m_f) with the LSTM's controls.

    Per training α a full-covariance Gaussian mixture (scikit-learn, ``min(components, rows)`` components,
    ``random_state=0``: the fit is deterministic) on that α's high-quality (τ_s, τ_i, τ_f, m_f).  At a query α
    between two training α a < α < b the density is the *mixture of the two mixtures*, weighted
    (b − α)/(b − a) and (α − a)/(b − a); outside the training range, the nearest α's mixture.  Sampling
    uses only ``rng`` (one draw of the bracket per sample, then the component, then standard normals);
    the controls are LSTM(τ, m_f, α) as in AmorGS.
    """

    name = "gmm_lstm"

    def __init__(self, problem: Problem, high_quality: pd.DataFrame, train_alphas, control_lstm: lstm.ControlLSTM,
                 components: int = 5):
        from sklearn.mixture import GaussianMixture

        self.problem = problem
        self.lstm = control_lstm
        self.by_alpha = training_rows(high_quality, train_alphas, problem.variable_names)
        self.mixtures: dict[float, tuple[np.ndarray, np.ndarray, np.ndarray]] = {}
        for a, rows in self.by_alpha.items():
            tm = rows[:, :4]
            k = max(1, min(int(components), len(tm)))
            if len(tm) == 1:  # one solution: a point mass with a small isotropic spread
                self.mixtures[a] = (np.ones(1), tm.copy(), np.eye(4)[None] * 1e-3)
                continue
            gm = GaussianMixture(k, covariance_type="full", reg_covar=1e-4, random_state=0).fit(tm)
            self.mixtures[a] = (gm.weights_ / gm.weights_.sum(), gm.means_, np.linalg.cholesky(gm.covariances_))

    @classmethod
    def build(cls, problem: Problem, inputs) -> GMMLSTMSampler:
        return cls(problem, inputs.high_quality, inputs.train_alphas, inputs.models["lstm"], inputs.gmm_components)

    def bracket(self, alpha: float) -> tuple[tuple[float, float], tuple[float, float]]:
        """((a, w_a), (b, w_b)): the training α whose mixtures are blended at ``alpha`` and their weights."""
        keep = usable_training_alphas(self.by_alpha, alpha)
        below = [a for a in keep if a <= alpha]
        above = [a for a in keep if a >= alpha]
        if not below or not above:
            a = nearest_training_alpha(self.by_alpha, alpha)
            return (a, 1.0), (a, 0.0)
        a, b = below[-1], above[0]
        if a == b:
            return (a, 1.0), (b, 0.0)
        w = (b - alpha) / (b - a)
        return (a, w), (b, 1.0 - w)

    def time_mass(self, alpha: float, n: int, rng: np.random.Generator) -> np.ndarray:
        (a, wa), (b, _) = self.bracket(alpha)
        use_a = rng.random(n) < wa
        out = np.empty((n, 4))
        for src, mask in ((a, use_a), (b, ~use_a)):
            m = int(mask.sum())
            if not m:
                continue
            weights, means, chol = self.mixtures[src]
            comp = rng.choice(len(weights), size=m, p=weights)
            z = rng.standard_normal((m, 4))
            out[mask] = means[comp] + np.einsum("nij,nj->ni", chol[comp], z)
        return out

    def sample(self, alpha: float, n: int, rng: np.random.Generator) -> np.ndarray:
        alpha = check_alpha(alpha, self.problem.alpha_range, self.problem.name)
        tm = np.clip(self.time_mass(alpha, n, rng), self.problem.lower[:4], self.problem.upper[:4])
        x = np.concatenate([tm, self.lstm.generate(lstm_conditioning(tm, alpha))], axis=1)
        return make_valid(x, self.problem)
