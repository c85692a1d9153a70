"""De Jong's 5th function (Shekel's foxholes) as an α-parameterised family of 2-D NLPs.

Source: Li et al., "Global Search of Optimal Spacecraft Trajectories using Amortization and Deep Generative
Models", Sec. III.A (Eq. 19–20) and Sec. V.A (Eq. 38); spec ``lt-cr3bp.md`` §7.

    J(x; α) = (0.002 + Σᵢ 1 / (1 + (x₁ − Āᵢ₁)⁶ + (x₂ − Āᵢ₂)⁶))⁻¹,   Ā(α) = R(α) A,   x ∈ [−50, 50]²

with R(α) the counter-clockwise rotation by α ∈ [0, π/2] and A the 2×8 matrix of Eq. 38 (two clusters of
four holes).  Every quantity here is dimensionless.

The family's contract (:data:`FAMILY`): α ∈ [0, π/2] rad, the local solver scipy BFGS with
:class:`~amorgs.solvers.options.BfgsOptions`, and "high quality" = converged with J ≤ 10 (:class:`DejongFilter`).
"""

from __future__ import annotations

import math
import time
from collections.abc import Mapping
from typing import Annotated

import numpy as np
import pandas as pd
from pydantic import ConfigDict, Field
from pydantic.dataclasses import dataclass

from amorgs.problems.base import Family, QualityFilter, SolveRecord, check_alpha, check_vector
from amorgs.solvers.fingerprint import function_fingerprint, sample_points
from amorgs.solvers.options import BfgsOptions, as_options

#: Eq. 38: eight holes in two clusters of four (columns are (x₁, x₂) at α = 0).
A_PAPER = np.array(
    [
        [-32.0, -32.0, -28.0, -28.0, 12.0, 12.0, 18.0, 18.0],
        [32.0, 28.0, 32.0, 28.0, -12.0, -18.0, -12.0, -18.0],
    ]
)

#: The constant 0.002 of Eq. 19: J → 1/0.002 = 500 far from every hole.
PLATEAU_CONSTANT = 0.002

#: scipy BFGS ``status`` codes → the record's status word.
_BFGS_STATUS = {0: "success", 1: "max_iterations", 2: "precision_loss", 3: "nan_encountered"}


def rotation(alpha: float) -> np.ndarray:
    """The 2×2 counter-clockwise rotation matrix R(α) of Eq. 20 (α in radians)."""
    c, s = math.cos(alpha), math.sin(alpha)
    return np.array([[c, -s], [s, c]])


def minima_matrix(alpha: float) -> np.ndarray:
    """Ā(α) = R(α)·A with A of Eq. 38: shape (2, 8), one hole centre per column."""
    return rotation(alpha) @ A_PAPER


def true_minima(alpha: float) -> np.ndarray:
    """The analytic minima locations for α: the 8 columns of R(α)A as rows, shape (8, 2).

    These are the hole centres.  The true local minimisers of J sit at ≈ these points: the wells are
    sixth-order flat, so the pull of the neighbouring holes of the same cluster (4 or 6 units away) moves
    each minimiser ≈ 0.22 units (the 4-unit cluster) or ≈ 0.12 units (the 6-unit cluster) towards its
    neighbours, far inside the 3-unit radius used to score predictions.
    """
    return minima_matrix(alpha).T.copy()


def foxholes_25() -> np.ndarray:
    """The classic 25-foxhole A (Fig. 2): a 5×5 grid at −32, −16, 0, 16, 32; shape (2, 25), x₁ fastest."""
    g = np.array([-32.0, -16.0, 0.0, 16.0, 32.0])
    x1, x2 = np.meshgrid(g, g, indexing="xy")
    return np.vstack([x1.ravel(), x2.ravel()])


def dejong5(x: np.ndarray, A: np.ndarray) -> np.ndarray:
    """J of Eq. 19 for hole matrix ``A`` (2, n), vectorised: ``x`` is (..., 2), the result has shape (...)."""
    x = np.asarray(x, dtype=float)
    d = x[..., :, None] - A  # (..., 2, n)
    denom = 1.0 + d[..., 0, :] ** 6 + d[..., 1, :] ** 6
    return 1.0 / (PLATEAU_CONSTANT + np.sum(1.0 / denom, axis=-1))


def dejong5_gradient(x: np.ndarray, A: np.ndarray) -> np.ndarray:
    """∇ₓJ of Eq. 19, vectorised like :func:`dejong5`: ``x`` is (..., 2), the result has shape (..., 2)."""
    x = np.asarray(x, dtype=float)
    d = x[..., :, None] - A  # (..., 2, n)
    denom = 1.0 + d[..., 0, :] ** 6 + d[..., 1, :] ** 6
    s = PLATEAU_CONSTANT + np.sum(1.0 / denom, axis=-1)
    # dJ/dx = −S⁻² dS/dx,  dS/dx_k = −Σᵢ 6 d_ki⁵ / Dᵢ²
    return np.sum(6.0 * d**5 / denom[..., None, :] ** 2, axis=-1) / s[..., None] ** 2


class DeJong5:
    """De Jong's 5th function family (paper Sec. III.A, Eq. 19–20, 38).

    Decision vector ``x = (x1, x2)``, both dimensionless, box [−50, 50]²; the parameter α ∈ [0, π/2] (rad)
    rotates the eight holes of Eq. 38 about the origin.  The objective J is dimensionless: ≈ 0.998 at the
    bottom of each hole and → 500 on the plateau far from every hole.
    """

    name = "dejong"
    variable_names: tuple[str, ...] = ("x1", "x2")
    lower = np.array([-50.0, -50.0])
    upper = np.array([50.0, 50.0])
    alpha_range = (0.0, math.pi / 2)
    options_type = BfgsOptions

    def sample_uniform(self, alpha: float, n: int, rng: np.random.Generator) -> np.ndarray:
        """``n`` initial guesses uniform in the box, shape (n, 2); the box does not depend on α."""
        check_alpha(alpha, self.alpha_range, self.name)
        if int(n) < 0:
            raise ValueError(f"{self.name}: n must be ≥ 0, got {n!r}")
        return rng.uniform(self.lower, self.upper, size=(int(n), 2))

    def check_guess(self, x: np.ndarray) -> np.ndarray:
        """Validate one decision vector (length 2, finite, inside the box); ``ValueError`` names the field."""
        return check_vector(x, self.variable_names, self.lower, self.upper, self.name)

    def make_local_solver(self, options: BfgsOptions | Mapping | None = None) -> DeJongBFGS:
        """A BFGS solver; ``options`` as :class:`BfgsOptions` (a mapping or ``None`` is converted)."""
        return DeJongBFGS(self, as_options(BfgsOptions, options))


class DeJongBFGS:
    """scipy BFGS with the analytic gradient on J(·; α); see :meth:`solve`."""

    def __init__(self, problem: DeJong5, options: BfgsOptions):
        self.problem = problem
        self.options = options
        self.options_hash = options.digest()
        self._fingerprints: dict[float, str] = {}

    def fingerprint(self, alpha: float) -> str:
        """The numerical fingerprint of J(·; α) and its gradient (:func:`~amorgs.solvers.fingerprint.function_fingerprint`
        at seeded points of the box), once per α."""
        a = float(alpha)
        if a not in self._fingerprints:
            A = minima_matrix(a)
            points = sample_points(self.problem.lower, self.problem.upper)
            self._fingerprints[a] = function_fingerprint(
                (lambda x, _: dejong5(x, A), lambda x, _: dejong5_gradient(x, A)), points, a)
        return self._fingerprints[a]

    def solve(self, x0: np.ndarray, alpha: float) -> SolveRecord:
        """Minimise J(·; α) from ``x0`` (shape (2,)).

        ``converged`` is BFGS success *and* a solution inside the box.  BFGS stops wherever the gradient is
        below ``gtol``, which on the far plateau (J ≈ 500) can happen away from any hole: such records are
        converged stationary points with a large J, to be removed by an objective threshold downstream.
        Invalid ``alpha``/``x0`` raise ``ValueError``; numerical failures return status ``exception``.
        """
        p = self.problem
        from scipy.optimize import minimize  # here, not at the top: the family's contract is read without scipy

        a = check_alpha(alpha, p.alpha_range, p.name)
        x0 = p.check_guess(x0)
        A = minima_matrix(a)
        wall0, cpu0 = time.perf_counter(), time.process_time()
        try:
            res = minimize(
                dejong5,
                x0,
                args=(A,),
                jac=dejong5_gradient,
                method="BFGS",
                options={"gtol": self.options.gtol, "maxiter": self.options.maxiter},
            )
        except Exception as exc:  # noqa: BLE001 — a numerical failure is a record, never an exception
            return SolveRecord(
                status="exception",
                converged=False,
                solver_success=False,
                x=np.full(2, math.nan),
                wall_s=time.perf_counter() - wall0,
                cpu_s=time.process_time() - cpu0,
                message=f"{type(exc).__name__}: {exc}",
                nlp_fingerprint=self.fingerprint(a),
            )
        wall, cpu = time.perf_counter() - wall0, time.process_time() - cpu0
        x = np.asarray(res.x, dtype=float)
        inside = bool(np.all(np.isfinite(x)) and np.all(x >= p.lower) and np.all(x <= p.upper))
        return SolveRecord(
            status=_BFGS_STATUS.get(int(res.status), f"status_{int(res.status)}"),
            converged=bool(res.success) and inside,
            solver_success=bool(res.success),
            x=x,
            objective=float(res.fun),
            iterations=int(res.nit),
            wall_s=wall,
            cpu_s=cpu,
            message=str(res.message),
            nlp_fingerprint=self.fingerprint(a),
        )


@dataclass(frozen=True, config=ConfigDict(extra="forbid"))
class DejongFilter(QualityFilter):
    """High quality: converged with J ≤ ``max_objective`` (null: every converged solve).  The bound removes
    the converged stationary points on the far plateau (J ≈ 500) and keeps the minima of the holes (J ≈ 1)."""

    max_objective: Annotated[float | None, Field(description=(
        "keep converged solves with objective J ≤ this (J is dimensionless: ≈ 1 in a hole, ≈ 500 on the "
        "plateau); null: every converged solve"))] = 10.0

    def passes(self, table: pd.DataFrame) -> pd.Series:
        if self.max_objective is None:
            return pd.Series(True, index=table.index)
        return table["objective"] <= self.max_objective


FAMILY = Family(name=DeJong5.name, alpha_range=DeJong5.alpha_range, alpha_unit="rad", options_type=DeJong5.options_type,
                quality_type=DejongFilter, build=DeJong5, quick_solves=True)
