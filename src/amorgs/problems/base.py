"""The problem protocol shared by every parameterised family of NLPs, and the solve record.

A *problem* is a family of NLPs indexed by a scalar parameter α.  It knows its decision-vector layout
(``variable_names``), its box bounds, how to draw uniform initial guesses, how to validate inputs and how
to build a *local solver* — an object holding compiled functions that must be created inside the process
that uses it (CasADi objects do not pickle) — from its solver's typed options (``options_type``, one of the
classes of :mod:`amorgs.solvers.options`).  Everything that crosses a process boundary is plain data:
problem names, options objects, numpy arrays and :class:`SolveRecord`.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field
from typing import Protocol

import numpy as np


@dataclass
class SolveRecord:
    """Outcome of one local solve; a numerical failure is a record, never an exception.

    ``status`` is the solver's own word (e.g. IPOPT's ``Solve_Succeeded``) or one of ``exception``,
    ``crashed``, ``timeout`` for failures caught around the solver.  ``converged`` is the *verified*
    verdict: solver success, match-point defect below tolerance and (where the problem has one) the
    independent re-propagation defect below its tolerance.  ``solver_success`` keeps the solver's own
    verdict so the two can be compared.  ``x`` is the solution in the problem's stored layout (NaN when
    there is none).  Times are seconds; ``defect`` and ``verify_defect`` are in the problem's defect units
    (dimensionless for the CR3BP: DU, VU, tonnes).
    """

    status: str
    converged: bool
    solver_success: bool
    x: np.ndarray
    objective: float = math.nan
    iterations: int = 0
    wall_s: float = math.nan
    cpu_s: float = math.nan
    defect: float = math.nan
    verify_defect: float = math.nan
    message: str = ""
    extra: dict = field(default_factory=dict)

    def to_row(self, variable_names: tuple[str, ...]) -> dict:
        """Flatten into one table row: solution as named columns, everything else as scalars."""
        row = {k: v for k, v in asdict(self).items() if k not in ("x", "extra")}
        row.update({name: float(v) for name, v in zip(variable_names, self.x)})
        row.update(self.extra)
        return row


class LocalSolver(Protocol):
    """A compiled local solver for one problem; create it inside the worker process."""

    def solve(self, x0: np.ndarray, alpha: float) -> SolveRecord: ...


class Problem(Protocol):
    """A parameterised family of NLPs; see the module docstring."""

    name: str
    variable_names: tuple[str, ...]
    lower: np.ndarray
    upper: np.ndarray
    alpha_range: tuple[float, float]
    #: The options class its local solver takes (e.g. :class:`~amorgs.solvers.options.IpoptOptions`).
    #: Optional for a user-defined ``"module:Class"`` family: without it the solver gets the caller's mapping.
    options_type: type

    def sample_uniform(self, alpha: float, n: int, rng: np.random.Generator) -> np.ndarray: ...

    def check_guess(self, x: np.ndarray) -> np.ndarray:
        """Validate one decision vector (length, finite, bounds); ``ValueError`` names the field."""
        ...

    def make_local_solver(self, options=None) -> LocalSolver:
        """A local solver with ``options`` (an ``options_type`` instance; a mapping or ``None`` is converted)."""
        ...


def check_alpha(alpha: float, alpha_range: tuple[float, float], problem: str) -> float:
    """Return ``alpha`` as float or raise a ``ValueError`` that names the field and the range."""
    lo, hi = alpha_range
    try:
        a = float(alpha)
    except (TypeError, ValueError):
        raise ValueError(f"{problem}: alpha must be a number, got {alpha!r}") from None
    if not math.isfinite(a) or a < lo - 1e-12 or a > hi + 1e-12:
        raise ValueError(f"{problem}: alpha={alpha!r} is outside its range [{lo}, {hi}]")
    return a


def check_vector(
    x: np.ndarray,
    variable_names: tuple[str, ...],
    lower: np.ndarray,
    upper: np.ndarray,
    problem: str,
    what: str = "initial guess",
    tol: float = 1e-9,
) -> np.ndarray:
    """Validate a decision vector: length, finiteness and bounds, naming the offending field."""
    arr = np.asarray(x, dtype=float)
    if arr.ndim != 1 or arr.size != len(variable_names):
        raise ValueError(
            f"{problem}: {what} must be a vector of length {len(variable_names)} "
            f"({variable_names[0]} … {variable_names[-1]}), got shape {arr.shape}"
        )
    bad = ~np.isfinite(arr)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise ValueError(f"{problem}: {what} field {variable_names[i]!r} is not finite ({arr[i]})")
    out = (arr < lower - tol) | (arr > upper + tol)
    if out.any():
        i = int(np.flatnonzero(out)[0])
        raise ValueError(
            f"{problem}: {what} field {variable_names[i]!r}={arr[i]:.6g} violates its bounds "
            f"[{lower[i]:.6g}, {upper[i]:.6g}]"
        )
    return arr
