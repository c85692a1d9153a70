"""The low-thrust Earth–Moon transfer as a problem family over α (max thrust in N).

Decision vector (stored layout, 64 entries): ``(τ_s, τ_i, τ_f, m_f, θ_1, φ_1, ρ_1, …, θ_20, φ_20, ρ_20)``
with times in TU, m_f in kg of fuel at the terminal state, angles in rad, throttle in [0, 1]; see
:mod:`amorgs.problems.cr3bp.transcription`.  The objective is −m_f (kg), minimised.  The local solver is
IPOPT (:mod:`amorgs.solvers.ipopt`) with :class:`~amorgs.solvers.options.IpoptOptions`.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np

from amorgs.problems.base import check_alpha, check_vector
from amorgs.problems.cr3bp import FAMILY
from amorgs.problems.cr3bp.boundary import load_boundary_conditions
from amorgs.problems.cr3bp.propagation import independent_defect
from amorgs.problems.cr3bp.transcription import (
    N_SEGMENTS,
    TAU_COAST_MAX,
    TAU_S_MAX,
    ForwardBackwardTranscription,
    variable_names,
)
from amorgs.solvers.ipopt import IpoptSolver
from amorgs.solvers.options import IpoptOptions, TranscriptionOptions, as_options


class LowThrustTransfer:
    """Problem family: minimum-fuel transfer from the GTO spiral end to the L1-halo stable manifold."""

    name = FAMILY.name
    alpha_range = FAMILY.alpha_range
    options_type = FAMILY.options_type

    def __init__(self, boundary_conditions: dict):
        self.initial_state = np.asarray(boundary_conditions["initial_state"], float)
        self.terminal_state = np.asarray(boundary_conditions["terminal_state"], float)
        self.variable_names = variable_names(N_SEGMENTS)
        m0 = float(self.initial_state[6])
        self.lower = np.array([0.0, 0.0, 0.0, 0.0] + [0.0, -math.pi / 2, 0.0] * N_SEGMENTS)
        self.upper = np.array([TAU_S_MAX, TAU_COAST_MAX, TAU_COAST_MAX, m0] + [2 * math.pi, math.pi / 2, 1.0] * N_SEGMENTS)

    @classmethod
    def from_resource(cls, path=None) -> LowThrustTransfer:
        return cls(load_boundary_conditions(path))

    def sample_uniform(self, alpha: float, n: int, rng: np.random.Generator) -> np.ndarray:
        """Uniform initial guesses of spec §6 (m_f ~ U[350, 450] kg); shape (n, 64)."""
        check_alpha(alpha, self.alpha_range, self.name)
        lo = self.lower.copy()
        hi = self.upper.copy()
        lo[3], hi[3] = 350.0, 450.0
        return lo + (hi - lo) * rng.random((n, lo.size))

    def check_guess(self, x: np.ndarray) -> np.ndarray:
        return check_vector(x, self.variable_names, self.lower, self.upper, self.name)

    def transcribe(self, options: TranscriptionOptions) -> ForwardBackwardTranscription:
        """The NLP for one integration grid (``options`` resolved for α: :meth:`TranscriptionOptions.for_alpha`)."""
        return ForwardBackwardTranscription(self.initial_state, self.terminal_state, options)

    def code_identity(self) -> dict:
        """The boundary states, compiled into the NLP code as constants (part of the compile-cache key)."""
        return {"initial": self.initial_state.tolist(), "terminal": self.terminal_state.tolist()}

    def objective(self, x: np.ndarray) -> float:
        """−m_f (kg) of a stored decision vector."""
        return -float(x[3])

    def verify_defect(self, x: np.ndarray, alpha: float) -> float:
        """Independent DOP853 re-propagation defect (DU, VU, tonnes); see :mod:`.propagation`."""
        return independent_defect(x, alpha, self.initial_state, self.terminal_state)

    def make_local_solver(self, options: IpoptOptions | Mapping | None = None) -> IpoptSolver:
        """An IPOPT solver; ``options`` as :class:`IpoptOptions` (a mapping or ``None`` is converted)."""
        return IpoptSolver(self, as_options(IpoptOptions, options))

