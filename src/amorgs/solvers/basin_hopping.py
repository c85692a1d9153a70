"""Global search strategies over any local solver: multi-start, and monotonic basin hopping (MBH).

MBH (Leary 2000; tuned for low-thrust trajectories by Englander & Englander 2014, whose most robust hops were
Pareto-distributed; the inner loop of NASA's EMTG) keeps an *incumbent* — the best feasible solution of the
current run — and repeatedly perturbs it and re-solves: a hop is kept when its solution is feasible (the
solver's verified ``converged``) and lowers the objective by more than ``min_improvement``; after ``patience``
hops in a row that do not, the run restarts from the next start of the sampler.  Multi-start is the strategy
that never hops: every solve starts from the sampler.  Both spend one iteration budget (IPOPT iterations summed
over every solve, the project's unit of cost), so their traces are comparable with each other and with the
ablation's cells.

Problem-agnostic (this layer imports no problem): a search gets ``solve(x0) -> SolveRecord``, ``next_start() ->
x0 or None`` (a sampler's next guess; None when a finite pool is exhausted), the box ``lower``/``upper`` of the
stored decision vector and a seeded generator.  Hops move every component — or only the named ones
(``HopSettings.variables``, e.g. the CR3BP's times) — by ``scale`` × its box width × a draw of the hop distribution
and clip to the box.  The objective is the solver's (for the CR3BP −m_f in kg, so
"lower" is "more fuel left").
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from amorgs.solvers.record import SolveRecord


def _gaussian(rng: np.random.Generator, size: int, shape: float) -> np.ndarray:
    return rng.standard_normal(size)


def _cauchy(rng: np.random.Generator, size: int, shape: float) -> np.ndarray:
    return rng.standard_cauchy(size)


def _uniform(rng: np.random.Generator, size: int, shape: float) -> np.ndarray:
    return rng.uniform(-1.0, 1.0, size)


def _pareto(rng: np.random.Generator, size: int, shape: float) -> np.ndarray:
    """Symmetric Pareto (type II, Lomax) with tail index ``shape``: |d| = (1 − u)^(−1/shape) − 1, random sign —
    mostly small moves with a heavy tail of long jumps (median |d| = 2^(1/shape) − 1 ≈ 0.59 at shape 1.5)."""
    magnitude = (1.0 - rng.uniform(0.0, 1.0, size)) ** (-1.0 / shape) - 1.0
    return np.where(rng.uniform(0.0, 1.0, size) < 0.5, -magnitude, magnitude)


#: The hop distributions: name → draw(rng, size, shape) of dimensionless steps (multiplied by scale × box width).
HOP_DISTRIBUTIONS: dict[str, Callable[[np.random.Generator, int, float], np.ndarray]] = {
    "pareto": _pareto,
    "cauchy": _cauchy,
    "gaussian": _gaussian,
    "uniform": _uniform,
}


#: The search strategies, registered once: name → what it does (the ``strategy`` column, setting and wildcard).
STRATEGIES = {
    "multistart": "every solve starts from the sampler (never hops)",
    "mbh": "monotonic basin hopping: hop from the incumbent, restart from the sampler after `patience` misses",
    "mbh_warm": "basin hopping whose hop re-solves start IPOPT as near a solution (WARM_HOP_IPOPT)",
}

#: IPOPT options of a re-solve started near a solution (a hop of ``mbh_warm``): keep the start's bound-active
#: variables where they are (IPOPT's default pushes them 1e-2 inside the box) and start the barrier small
#: instead of at μ = 0.1, so the re-solve does not walk most of the way again.
WARM_HOP_IPOPT = {"mu_init": 1e-6, "bound_push": 1e-8, "bound_frac": 1e-8, "bound_mult_init_method": "mu-based"}


def hop_solver_options(strategy: str, options):
    """The solver options of ``strategy``'s hop re-solves: ``options`` with :data:`WARM_HOP_IPOPT` over its extra
    IPOPT options for ``mbh_warm`` (an :class:`~amorgs.solvers.options.IpoptOptions`), None (the starts' solver)
    otherwise."""
    if strategy != "mbh_warm":
        return None
    import dataclasses

    return dataclasses.replace(options, ipopt_options={**options.ipopt_options, **WARM_HOP_IPOPT})


@dataclass(frozen=True)
class HopSettings:
    """How MBH hops.

    distribution: a key of :data:`HOP_DISTRIBUTIONS`.   scale: step per unit draw, as a fraction of each
    variable's box width (dimensionless).   shape: the Pareto tail index (the other distributions ignore it).
    patience: consecutive non-improving hops before the run restarts from the sampler (0: never hop —
    multi-start).   min_improvement: how much a hop must lower the objective to be kept (objective units: kg
    for the CR3BP).   variables: the names of the stored variables a hop moves (the problem's
    ``variable_names``; for the CR3BP ``("tau_s", "tau_i", "tau_f")`` hops only the times); empty (the default):
    every one.
    """

    distribution: str = "pareto"
    scale: float = 0.02
    shape: float = 1.5
    patience: int = 10
    min_improvement: float = 1e-6
    variables: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        if self.distribution not in HOP_DISTRIBUTIONS:
            raise ValueError(f"hop distribution {self.distribution!r}: one of {', '.join(HOP_DISTRIBUTIONS)}")
        if not (self.scale > 0 and self.shape > 0 and self.patience >= 0 and self.min_improvement >= 0):
            raise ValueError(f"hop settings out of range: {self}")
        object.__setattr__(self, "variables", tuple(self.variables))  # a list from JSON reads as the same settings
        if len(set(self.variables)) != len(self.variables):
            raise ValueError(f"hop variables named twice: {', '.join(self.variables)}")

    def movable(self, variable_names: tuple[str, ...] | None) -> np.ndarray | None:
        """The boolean mask of the components a hop moves over a vector named ``variable_names``, or None for
        every component; ``ValueError`` naming what is missing when :attr:`variables` names a variable that
        ``variable_names`` lacks (or gives no names to look them up in)."""
        if not self.variables:
            return None
        if variable_names is None:
            raise ValueError(f"hop variables {', '.join(self.variables)}: the search was given no variable names")
        unknown = [v for v in self.variables if v not in variable_names]
        if unknown:
            raise ValueError(f"hop variables {', '.join(unknown)}: not variables of the problem "
                             f"({', '.join(variable_names[:6])}, …)")
        return np.isin(np.asarray(variable_names), self.variables)


def hop(x: np.ndarray, lower: np.ndarray, upper: np.ndarray, settings: HopSettings,
        rng: np.random.Generator, movable: np.ndarray | None = None) -> np.ndarray:
    """``x`` moved by ``settings.scale`` × (upper − lower) × a draw of the hop distribution per component — per
    component of the boolean mask ``movable`` only, where given (:meth:`HopSettings.movable`; the draws are made
    for those components alone) — clipped to the box."""
    if movable is None:
        draw = HOP_DISTRIBUTIONS[settings.distribution](rng, x.size, settings.shape)
    else:
        draw = np.zeros(x.size)
        draw[movable] = HOP_DISTRIBUTIONS[settings.distribution](rng, int(np.count_nonzero(movable)), settings.shape)
    return np.clip(x + settings.scale * (upper - lower) * draw, lower, upper)


def improves(record: SolveRecord, incumbent: SolveRecord | None, min_improvement: float) -> bool:
    """The acceptance rule: a feasible (verified converged) solution with a finite objective that beats the
    incumbent's by more than ``min_improvement`` (any feasible one when there is no incumbent)."""
    if not record.converged or not math.isfinite(record.objective):
        return False
    return incumbent is None or record.objective < incumbent.objective - min_improvement


@dataclass
class SearchTrace:
    """One search: a row per solve (``events``: solve, run, kind 'start'/'hop', iterations, cumulative
    iterations, status, converged, objective, accepted, best objective so far — NaN before the first feasible
    one —, and the fingerprint of the NLP the solve ran on), the guess each solve started from (``guesses``, one per event: what a certificate re-solves) and the
    stored vectors of its feasible solutions (``solutions``, one row each, in the order found, with their
    ``event`` index).  ``stop``: 'budget' or 'starts exhausted'."""

    events: list[dict] = field(default_factory=list)
    guesses: list[np.ndarray] = field(default_factory=list)
    solutions: list[tuple[int, np.ndarray]] = field(default_factory=list)
    stop: str = "budget"

    @property
    def iterations(self) -> int:
        return self.events[-1]["cumulative_iterations"] if self.events else 0

    @property
    def best(self) -> float:
        """The best feasible objective found (NaN if none)."""
        return self.events[-1]["best_objective"] if self.events else math.nan


def search(solve: Callable[[np.ndarray], SolveRecord], next_start: Callable[[], np.ndarray | None],
           lower: np.ndarray, upper: np.ndarray, settings: HopSettings, budget_iterations: int,
           rng: np.random.Generator, solve_hop: Callable[[np.ndarray], SolveRecord] | None = None,
           variable_names: tuple[str, ...] | None = None) -> SearchTrace:
    """Run one search until the iterations of its solves reach ``budget_iterations`` (the solve that crosses it
    counts whole) or the sampler runs out.  ``settings.patience`` = 0 is multi-start; hops are re-solved by
    ``solve_hop`` where given (``mbh_warm``), else by ``solve``; ``variable_names`` name the vector's components
    (needed where ``settings.variables`` picks the ones a hop moves)."""
    if budget_iterations <= 0:
        raise ValueError(f"budget_iterations must be positive, got {budget_iterations}")
    movable = settings.movable(variable_names)
    trace = SearchTrace()
    incumbent: SolveRecord | None = None
    best = math.nan
    misses = 0  # consecutive hops that were not kept
    run = -1
    used = 0
    while used < budget_iterations:
        restart = incumbent is None or misses >= settings.patience
        if restart:
            x0 = next_start()
            if x0 is None:
                trace.stop = "starts exhausted"
                break
            incumbent, misses, run = None, 0, run + 1
        else:
            x0 = hop(np.asarray(incumbent.x, float), lower, upper, settings, rng, movable)
        record = (solve if restart or solve_hop is None else solve_hop)(np.asarray(x0, float))
        used += max(1, int(record.iterations))  # a solve that failed before IPOPT ran still costs: no endless loop
        accepted = improves(record, incumbent, settings.min_improvement)
        if accepted:
            incumbent, misses = record, 0
        elif not restart:
            misses += 1
        if record.converged and math.isfinite(record.objective):
            best = record.objective if math.isnan(best) else min(best, record.objective)
            trace.solutions.append((len(trace.events), np.asarray(record.x, float).copy()))
        trace.guesses.append(np.asarray(x0, float).copy())
        trace.events.append({
            "solve": len(trace.events), "run": run, "kind": "start" if restart else "hop",
            "iterations": int(record.iterations), "cumulative_iterations": used, "status": record.status,
            "converged": bool(record.converged), "objective": float(record.objective), "accepted": accepted,
            "best_objective": best, "nlp_fingerprint": record.nlp_fingerprint,
        })
    return trace


class Chains:
    """``k`` MBH chains advanced a round at a time: each round proposes one start per chain — the sampler's next
    start for a chain with no feasible incumbent or ``patience`` misses in a row, else a hop from its incumbent —
    and takes the round's solves back in the same order (:meth:`update`).  The rule of :func:`search`, for a
    caller that solves a round's starts in parallel (``amorgs design --strategy mbh``); ``variable_names`` as for
    :func:`search`."""

    def __init__(self, k: int, settings: HopSettings, variable_names: tuple[str, ...] | None = None):
        self.settings = settings
        self.movable = settings.movable(variable_names)
        self.incumbents: list[SolveRecord | None] = [None] * k
        self.misses = [0] * k

    def propose(self, fresh: Callable[[int], np.ndarray], lower: np.ndarray, upper: np.ndarray,
                rng: np.random.Generator, size: int | None = None) -> tuple[np.ndarray, list[str]]:
        """The starts of the first ``size`` chains (default all) and their kinds ('start'/'hop'):
        ``fresh(m)`` draws the m restarts (called once, before the hops draw from ``rng``)."""
        size = len(self.incumbents) if size is None else size
        restart = [self.incumbents[i] is None or self.misses[i] >= self.settings.patience for i in range(size)]
        wanted = sum(restart)
        drawn = np.asarray(fresh(wanted), float) if wanted else np.empty((0, 0))
        if len(drawn) < wanted:
            raise ValueError(f"the sampler gave {len(drawn)} starts for {wanted} restarting chains")
        drawn = iter(drawn)
        guesses, kinds = [], []
        for i in range(size):
            if restart[i]:
                self.incumbents[i], self.misses[i] = None, 0
                guesses.append(next(drawn))
                kinds.append("start")
            else:
                guesses.append(hop(np.asarray(self.incumbents[i].x, float), lower, upper, self.settings, rng,
                                   self.movable))
                kinds.append("hop")
        return np.array(guesses), kinds

    def update(self, records: list[SolveRecord], kinds: list[str]) -> list[bool]:
        """Each chain's solve of the round (in :meth:`propose`'s order): kept when it improves the incumbent
        (:func:`improves`); a hop not kept is a miss.  Returns which were kept."""
        kept = []
        for i, (record, kind) in enumerate(zip(records, kinds)):
            accepted = improves(record, self.incumbents[i], self.settings.min_improvement)
            if accepted:
                self.incumbents[i], self.misses[i] = record, 0
            elif kind == "hop":
                self.misses[i] += 1
            kept.append(accepted)
        return kept
