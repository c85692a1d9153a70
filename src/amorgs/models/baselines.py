"""The model-free samplers: the uniform baseline and the reuse of known solutions — no torch, no checkpoints.

Same contract as every sampler (:mod:`amorgs.models.samplers`, which re-exports these): ``sample(alpha, n,
rng) -> ndarray (n, 3N+4)`` of *valid* guesses in the stored decision-vector layout.  They live apart from
the learned samplers so that ``amorgs design`` with its default sampler (``nearest_alpha``), the ablation's
reuse cells and the workflow's configs read them without importing torch (≈ 2–4 s of start-up)::

    uniform                  τ, m_f, controls ~ the problem's uniform distribution (spec §6)
    nearest_alpha            HQ solutions of the nearest training α, unchanged: drawn without replacement
                             until that α's pool is exhausted, then with replacement
    nearest_alpha_perturbed  the same + N(0, σ²) noise in the box-normalised space, then make_valid
    continuation             nearest_alpha's draw, each solution moved to α by a secant to its nearest
                             match at a neighbouring training α

Also here, because the continuation needs it without torch: the Cartesian layout of the vanilla CVAE
(:func:`vanilla_vectors`, :func:`stored_from_vanilla`; :mod:`amorgs.models.cr3bp_models` explains the choice).
"""

from __future__ import annotations

import math
from typing import Protocol

import numpy as np
import pandas as pd

from amorgs.alphas import alpha_label, same_alpha
from amorgs.models.names import PERTURBATION_SCALE
from amorgs.problems import Problem
from amorgs.problems.base import check_alpha
from amorgs.problems.cr3bp.controls import cartesian_controls, spherical_controls
from amorgs.problems.cr3bp.transcription import N_SEGMENTS


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

    @classmethod
    def build(cls, problem: Problem, inputs) -> UniformSampler:
        return cls(problem)

    def sample(self, alpha: float, n: int, rng: np.random.Generator) -> np.ndarray:
        return make_valid(self.problem.sample_uniform(alpha, n, rng), self.problem)


# ------------------------------------------------------------------------- the vanilla CVAE's layout
def vanilla_vectors(stored: np.ndarray) -> np.ndarray:
    """Stored vectors (n, 64) → the vanilla CVAE's layout (τ_s, τ_i, τ_f, m_f, u_1x, u_1y, u_1z, …), (n, 64)."""
    stored = np.asarray(stored, dtype=np.float64)
    u = cartesian_controls(stored, N_SEGMENTS).reshape(len(stored), -1)
    return np.concatenate([stored[:, :4], u], axis=1)


def stored_from_vanilla(v: np.ndarray) -> np.ndarray:
    """Inverse of :func:`vanilla_vectors`: (n, 64) → stored layout (θ in [0, 2π), ρ = min(‖u‖, 1))."""
    v = np.asarray(v, dtype=np.float64)
    controls = spherical_controls(v[:, 4:].reshape(len(v), N_SEGMENTS, 3))
    return np.concatenate([v[:, :4], controls], axis=1)


# --------------------------------------------------------------------------------- non-neural baselines
#
# Arms that answer "does learning beat reusing known solutions?" (issues 11, 21).  They read the filtered
# high-quality table (``results/cr3bp/high_quality.parquet``) restricted to the *training* α: a row whose α
# has the label (three decimals) of the queried α is never used, so a test α can never see its own solutions.


def training_rows(high_quality: pd.DataFrame, train_alphas, names) -> dict[float, np.ndarray]:
    """Training α → the decision vectors (m, 3N+4) of its high-quality rows; α without rows are left out."""
    if high_quality is None or not len(high_quality):
        raise ValueError("the high-quality table is empty: the nearest-α / GMM baselines need training solutions")
    wanted = {alpha_label(a): float(a) for a in train_alphas}
    labels = high_quality["alpha"].map(alpha_label)
    out: dict[float, np.ndarray] = {}
    for label, alpha in sorted(wanted.items(), key=lambda kv: kv[1]):
        rows = high_quality[labels == label]
        if len(rows):
            out[alpha] = rows[list(names)].to_numpy(dtype=np.float64)
    if not out:
        raise ValueError(f"no high-quality rows at the training α {sorted(wanted.values())}")
    return out


def usable_training_alphas(by_alpha: dict[float, np.ndarray], alpha: float) -> list[float]:
    """The training α available at query ``alpha`` (any α sharing its three-decimal label excluded), sorted."""
    keep = [a for a in sorted(by_alpha) if not same_alpha(a, alpha)]
    if not keep:
        raise ValueError(f"no training α other than the queried α = {alpha!r}")
    return keep


def nearest_training_alpha(by_alpha: dict[float, np.ndarray], alpha: float) -> float:
    """The training α closest to ``alpha`` (ties: the smaller one), never ``alpha`` itself."""
    keep = usable_training_alphas(by_alpha, alpha)
    return min(keep, key=lambda a: (abs(a - alpha), a))


class NearestAlphaSampler:
    """Reuse, unchanged, the high-quality solutions of the nearest *training* α (its *pool*, :meth:`pool`).
    No learning at all.  ``n`` rows are drawn *without* replacement while the pool lasts — start i < pool size
    is a pool row not drawn before (one ``rng.permutation`` of the pool) — and the starts beyond the pool
    uniformly *with* replacement (one ``rng.integers`` call): every start up to the pool size solves a new
    guess, and the later ones repeat a start already solved."""

    name = "nearest_alpha"

    def __init__(self, problem: Problem, high_quality: pd.DataFrame, train_alphas):
        self.problem = problem
        self.by_alpha = training_rows(high_quality, train_alphas, problem.variable_names)

    @classmethod
    def build(cls, problem: Problem, inputs) -> NearestAlphaSampler:
        return cls(problem, inputs.high_quality, inputs.train_alphas)

    def pool(self, alpha: float) -> tuple[float, int]:
        """(the training α whose high-quality rows are reused at ``alpha``, the number of those rows)."""
        source = nearest_training_alpha(self.by_alpha, check_alpha(alpha, self.problem.alpha_range, self.problem.name))
        return source, len(self.by_alpha[source])

    def _draw(self, alpha: float, n: int, rng: np.random.Generator) -> np.ndarray:
        rows = self.by_alpha[self.pool(alpha)[0]]
        fresh = rng.permutation(len(rows))[:n]
        again = rng.integers(0, len(rows), size=n - len(fresh))
        return rows[np.concatenate([fresh, again])]

    def sample(self, alpha: float, n: int, rng: np.random.Generator) -> np.ndarray:
        return make_valid(self._draw(alpha, n, rng), self.problem)


class NearestAlphaPerturbedSampler(NearestAlphaSampler):
    """:class:`NearestAlphaSampler` plus Gaussian noise in the *normalised box*: each coordinate is mapped
    to [0, 1] by (x − lower)/(upper − lower) (τ by 40/15/15 TU, m_f by m0, θ by 2π, φ by π, ρ by 1), noise
    N(0, ``scale``²) is added there (one ``rng.normal`` call after the row draw), mapped back, then
    :func:`make_valid` wraps the azimuths and clips the rest into the bounds."""

    name = "nearest_alpha_perturbed"

    def __init__(self, problem: Problem, high_quality: pd.DataFrame, train_alphas,
                 scale: float = PERTURBATION_SCALE):
        super().__init__(problem, high_quality, train_alphas)
        if not (scale >= 0 and math.isfinite(scale)):
            raise ValueError(f"perturbation scale must be a finite number ≥ 0, got {scale!r}")
        self.scale = float(scale)

    @classmethod
    def build(cls, problem: Problem, inputs) -> NearestAlphaPerturbedSampler:
        return cls(problem, inputs.high_quality, inputs.train_alphas, inputs.perturbation_scale)

    def sample(self, alpha: float, n: int, rng: np.random.Generator) -> np.ndarray:
        x = self._draw(alpha, n, rng)
        span = self.problem.upper - self.problem.lower
        z = (x - self.problem.lower) / span + rng.normal(0.0, self.scale, size=x.shape)
        return make_valid(self.problem.lower + z * span, self.problem)


class ContinuationSampler(NearestAlphaSampler):
    """Reuse moved along α by a secant.  Each start is a solution x₀ of the nearest training α a₀, drawn as
    :class:`NearestAlphaSampler` draws; a *partner* training α a₁ is chosen (:meth:`partner`: the nearest on
    the other side of α when there is one — interpolation —, else the next nearest — extrapolation); x₀ is
    matched to its nearest high-quality solution x₁ at a₁ and moved to x = x₀ + (α − a₀)/(a₁ − a₀)·(x₁ − x₀).
    Matching and the secant use the vanilla CVAE's layout (τ, m_f and the Cartesian throttle vectors u_k,
    :func:`vanilla_vectors`: the azimuths of a coasting segment are arbitrary and carry no distance) divided
    by the box widths (τ by 40/15/15 TU, m_f by m0, u by 2); x is mapped back (:func:`stored_from_vanilla`) and
    made valid.  Uses no randomness beyond the row draw; with a single training α it is
    :class:`NearestAlphaSampler`."""

    name = "continuation"

    def partner(self, alpha: float) -> float:
        """The training α a₁ of the secant at ``alpha`` (a₀ itself when no other is usable)."""
        a0 = self.pool(alpha)[0]
        others = [a for a in usable_training_alphas(self.by_alpha, alpha) if a != a0]
        across = [a for a in others if (a - alpha) * (a0 - alpha) < 0]
        return min(across or others, key=lambda a: (abs(a - alpha), a)) if others else a0

    def sample(self, alpha: float, n: int, rng: np.random.Generator) -> np.ndarray:
        from scipy.spatial import cKDTree

        a0, a1 = self.pool(alpha)[0], self.partner(alpha)
        x0 = self._draw(alpha, n, rng)
        if a1 == a0:
            return make_valid(x0, self.problem)
        scale = np.concatenate([(self.problem.upper - self.problem.lower)[:4], np.full(x0.shape[1] - 4, 2.0)])
        v0, v1 = vanilla_vectors(x0) / scale, vanilla_vectors(self.by_alpha[a1]) / scale
        match = cKDTree(v1).query(v0)[1]
        v = v0 + (alpha - a0) / (a1 - a0) * (v1[match] - v0)
        return make_valid(stored_from_vanilla(v * scale), self.problem)
