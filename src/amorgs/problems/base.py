"""The problem protocol shared by every parameterised family of NLPs.

A *problem* is a family of NLPs indexed by a scalar parameter α.  It knows its decision-vector layout
(``variable_names``), its box bounds, how to draw uniform initial guesses, how to validate inputs and how
to build a *local solver* — an object holding compiled functions that must be created inside the process
that uses it (CasADi objects do not pickle) — from its solver's typed options (``options_type``, one of the
classes of :mod:`amorgs.solvers.options`).  Everything that crosses a process boundary is plain data:
problem names, options objects, numpy arrays and :class:`~amorgs.solvers.record.SolveRecord`.  The solve
record and the local-solver protocol belong to the solvers (:mod:`amorgs.solvers.record`), the α range check
to :mod:`amorgs.alphas`; both are re-exported here for the problem families.
"""

from __future__ import annotations

from typing import Protocol

import numpy as np

from amorgs.alphas import check_alpha
from amorgs.solvers.record import LocalSolver, SolveRecord

__all__ = ["LocalSolver", "Problem", "SolveRecord", "check_alpha", "check_vector"]


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
