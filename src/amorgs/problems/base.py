"""The contract every problem family keeps: the :class:`Problem` protocol, the :class:`QualityFilter` base and
the :class:`Family` record that registers a family.

A *problem* is a family of NLPs indexed by a scalar parameter α.  It knows its decision-vector layout
(``variable_names``), its box bounds, how to draw uniform initial guesses, how to validate inputs and how
to build a *local solver* — an object holding compiled functions that must be created inside the process
that uses it (CasADi objects do not pickle) — from its solver's typed options (``options_type``, one of the
classes of :mod:`amorgs.solvers.options`).  Everything that crosses a process boundary is plain data:
problem objects, options objects, numpy arrays and :class:`~amorgs.solvers.record.SolveRecord`.  The solve
record and the local-solver protocol belong to the solvers (:mod:`amorgs.solvers.record`), the α range check
to :mod:`amorgs.alphas`; both are re-exported here for the problem families.

A family owns, besides the problem: its α range (in its own unit), its solver-options type, its quality
filter (what "high quality" means for its solutions, with typed thresholds whose defaults are the family's)
and how to build the problem.  The :class:`Family` record holds these without building the problem, so the
config and the workflow read them without loading CasADi or a boundary-condition file.
"""

from __future__ import annotations

import abc
import dataclasses
import functools
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any, Protocol, TypeVar

import numpy as np
import pandas as pd
import pydantic

from amorgs.alphas import check_alpha
from amorgs.solvers.record import LocalSolver, SolveRecord

__all__ = ["Family", "LocalSolver", "Problem", "QualityFilter", "SolveRecord", "check_alpha", "check_vector"]

_Q = TypeVar("_Q", bound="QualityFilter")


class Problem(Protocol):
    """A parameterised family of NLPs; see the module docstring.  ``lower``/``upper`` are the box bounds of the
    decision vector (shape ``(len(variable_names),)``, in the units its class docstring gives); ``alpha_range``
    is the inclusive range of α (the family's :attr:`Family.alpha_range`)."""

    name: str
    variable_names: tuple[str, ...]
    lower: np.ndarray
    upper: np.ndarray
    alpha_range: tuple[float, float]
    #: The options class its local solver takes (e.g. :class:`~amorgs.solvers.options.IpoptOptions`).
    #: Optional only for a stand-in ``"module:Class"`` problem of the tests (the pool then hands the solver the
    #: caller's mapping); a registered family has one.
    options_type: type

    def sample_uniform(self, alpha: float, n: int, rng: np.random.Generator) -> np.ndarray:
        """``n`` initial guesses drawn from ``rng``, shape ``(n, len(variable_names))``, inside the bounds."""
        ...

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


class QualityFilter(abc.ABC):
    """What "high quality" means for one family's solutions: converged, and :meth:`passes` the family's typed
    thresholds.  A family subclasses it as a frozen pydantic dataclass (unknown keys and wrong types raise a
    ``ValueError`` naming the field) whose field defaults are the family's default thresholds; it serves
    directly as the type of the config key ``problems.<family>.filter``."""

    @abc.abstractmethod
    def passes(self, table: pd.DataFrame) -> pd.Series:
        """Whether each row of a solution table meets the thresholds (``converged`` aside)."""

    def mask(self, table: pd.DataFrame) -> pd.Series:
        """``True`` for the rows of ``table`` that converged and pass the thresholds (index kept)."""
        return table["converged"].astype(bool) & self.passes(table).astype(bool)

    def select(self, table: pd.DataFrame) -> pd.DataFrame:
        """The high-quality rows of ``table``, in order, index reset."""
        return table.loc[self.mask(table)].reset_index(drop=True)

    def to_dict(self) -> dict[str, Any]:
        """The thresholds as plain JSON-able data; :meth:`from_mapping` inverts it."""
        return dataclasses.asdict(self)  # type: ignore[call-overload]

    @classmethod
    def from_mapping(cls: type[_Q], mapping: Mapping[str, Any] | None) -> _Q:
        """Build from a plain mapping (e.g. a config section); missing keys take the family's defaults."""
        return _adapter(cls).validate_python(dict(mapping or {}))


@functools.cache
def _adapter(cls: type) -> pydantic.TypeAdapter:
    return pydantic.TypeAdapter(cls)


@dataclass(frozen=True)
class Family:
    """One registered problem family (:data:`amorgs.problems.FAMILIES`): what the config and the workflow need
    to know of it without building the problem.

    ``alpha_range`` is the inclusive range of α in ``alpha_unit``; ``options_type`` the typed options of its
    local solver (:mod:`amorgs.solvers.options`; its defaults are the family's default solver options);
    ``quality_type`` its :class:`QualityFilter` (its defaults are the family's default thresholds, e.g. β);
    ``build`` makes the problem (a zero-argument callable that imports what the problem needs only when called);
    ``quick_solves``: a local solve takes milliseconds, so a generate job of a small shard of it does seconds of work
    and its MLflow run is written when the workflow ends (:attr:`amorgs.steps.Step.deferred_tracking`).
    """

    name: str
    alpha_range: tuple[float, float]
    alpha_unit: str
    options_type: type
    quality_type: type[QualityFilter]
    build: Callable[[], Problem]
    quick_solves: bool = False
