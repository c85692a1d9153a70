"""What a local solver returns and promises: the solve record and the local-solver protocol.

They belong to the solvers, so that the solvers need nothing of the problems (the problem families, in
:mod:`amorgs.problems`, build local solvers that keep this protocol).
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
    there is none).  ``nlp_fingerprint`` is the numerical fingerprint of the problem the solver solved at this α
    (:mod:`amorgs.solvers.fingerprint`; empty when the solve never reached a solver, e.g. a crashed worker).
    Times are seconds; ``defect`` and ``verify_defect`` are in the problem's defect units
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
    nlp_fingerprint: str = ""
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
