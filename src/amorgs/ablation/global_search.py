"""Global search cells (strategy × sampler × α) and their runtime to the best known trajectory.

A *cell* runs R independent searches (:func:`amorgs.solvers.basin_hopping.search`) of one strategy from one
sampler's starts at one α, each with its own seeded generator and the same iteration budget.  Its answer is not
"how many high-quality solutions per iteration" (the ablation's) but "how soon is the funnel bottom reached":

* **best known**: the lowest objective of any verified solution at that α (for the CR3BP −m_f, kg) — the
  library's and every search's (:func:`best_known`);
* **runtime to target** δ: the cumulative IPOPT iterations at which a search's best objective first comes within
  δ of the best known (m_f ≥ best − δ); the *expected runtime* (ERT, the COCO benchmarking platform's aRT) is
  the iterations spent by all R searches — until success, or the whole budget — per successful search, with a
  bootstrap interval over searches (:func:`runtime_to_target`);
* **distinct near-best**: how many η-distinct trajectories (:mod:`amorgs.analysis.diversity`) within δ of the
  best known the cell found, over all its searches;
* the runtime ECDF (:func:`runtime_ecdf`): the fraction of (search, δ) pairs reached against iterations.

Strategies (:data:`~amorgs.solvers.basin_hopping.STRATEGIES`) are registered once: multi-start never hops; MBH hops per its
:class:`~amorgs.solvers.basin_hopping.HopSettings`.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable
from dataclasses import dataclass, replace

import numpy as np
import pandas as pd

from amorgs.ablation.arms import REUSE_ARM, get_arm
from amorgs.analysis.diversity import DiversityParams, diverse_subset
from amorgs.solvers.basin_hopping import STRATEGIES, HopSettings, search

#: Default targets δ: within this much of the best known objective (kg of final mass for the CR3BP).
DELTAS = (0.1, 0.5, 2.0)


def strategy_settings(strategy: str, hops: HopSettings) -> HopSettings:
    """The hop settings a strategy searches with: ``hops`` for the basin-hopping strategies, ``patience = 0``
    (never hop) for multi-start; ``ValueError`` for an unknown strategy."""
    if strategy not in STRATEGIES:
        raise ValueError(f"strategy {strategy!r}: one of {', '.join(STRATEGIES)}")
    return replace(hops, patience=0) if strategy == "multistart" else hops


@dataclass(frozen=True)
class Cell:
    """One global-search cell: ``searches`` searches of ``strategy`` from ``sampler`` at ``alpha``, each with
    ``budget`` IPOPT iterations; search r's generator is ``default_rng([seed, r])``."""

    sampler: str
    strategy: str
    alpha: float
    searches: int
    budget: int
    seed: int
    hops: HopSettings = HopSettings()


def repeats_search_0(cell: Cell) -> bool:
    """Whether every search of ``cell`` is its search 0: a multi-start (it never hops, so its generator draws
    only the starts) from a sampler that does not use its generator (:attr:`~amorgs.ablation.arms.Arm.rng_free`,
    the selector's one ranking).  Such a cell's searches are solved once and relabelled (:func:`as_search`)."""
    return cell.strategy == "multistart" and get_arm(cell.sampler).rng_free


def as_search(result: tuple[list[dict], list[dict]], r: int) -> tuple[list[dict], list[dict]]:
    """A search's event rows and solutions (:func:`run_search`'s result) relabelled as search ``r``."""
    events, solutions = result
    return [{**e, "search": r} for e in events], [{**s, "search": r} for s in solutions]


#: Starts drawn per call of a search's sampler: a pooled arm (reuse) permutes its pool afresh at every call, so a
#: search's starts are distinct as long as it needs no more than this many (a 10 000-iteration search restarts
#: some tens of times).
START_BATCH = 256


def _starts(sample, alpha: float, rng: np.random.Generator, batch: int = START_BATCH) -> Callable[[], np.ndarray | None]:
    """The sampler's guesses one at a time, drawn ``batch`` at a time from ``rng``; None once a finite pool gives
    no more."""
    buffer: list[np.ndarray] = []
    exhausted = False

    def next_start() -> np.ndarray | None:
        nonlocal exhausted
        if not buffer and not exhausted:
            drawn = np.asarray(sample(alpha, batch, rng), float)
            exhausted = len(drawn) < batch
            buffer.extend(drawn)
        return buffer.pop(0) if buffer else None

    return next_start


def run_search(cell: Cell, r: int, sample, solver, lower: np.ndarray, upper: np.ndarray,
               variable_names: tuple[str, ...], hop_solver=None) -> tuple[list[dict], list[dict]]:
    """Search ``r`` of ``cell``: ``sample(alpha, n, rng)`` is the sampler, ``solver`` the local solver
    (``solver.solve(x0, alpha)`` → :class:`~amorgs.solvers.record.SolveRecord`, ``solver.options_hash``) and
    ``hop_solver`` the one that re-solves hops where it differs (``mbh_warm``); the generator
    ``default_rng([cell.seed, r])`` draws both the starts and the hops.  Returns its event rows (the cell's keys,
    ``search``, :class:`~amorgs.solvers.basin_hopping.SearchTrace`'s columns, ``stop``, the ``options_hash`` of
    the solver that solved it and the guess it started from as ``guess_<name>`` columns, so a sample can be
    re-solved and certified) and its feasible solutions (the cell's keys, ``search``, ``event``, ``objective``
    and the stored vector as named columns)."""
    settings = strategy_settings(cell.strategy, cell.hops)
    keys = {"sampler": cell.sampler, "strategy": cell.strategy, "alpha": cell.alpha}
    rng = np.random.default_rng([cell.seed, r])
    hop_solve = (lambda x0: hop_solver.solve(x0, cell.alpha)) if hop_solver is not None else None
    trace = search(lambda x0: solver.solve(x0, cell.alpha), _starts(sample, cell.alpha, rng), lower, upper,
                   settings, cell.budget, rng, hop_solve, variable_names)
    guess_names = [f"guess_{name}" for name in variable_names]

    def options_hash(kind: str) -> str:
        return (hop_solver if hop_solver is not None and kind == "hop" else solver).options_hash

    events = [{**keys, "search": r, **e, "stop": trace.stop, "options_hash": options_hash(e["kind"]),
               **dict(zip(guess_names, map(float, x0)))} for e, x0 in zip(trace.events, trace.guesses)]
    objective = {e["solve"]: e["objective"] for e in trace.events}
    solutions = [{**keys, "search": r, "event": i, "objective": objective[i], **dict(zip(variable_names, x))}
                 for i, x in trace.solutions]
    return events, solutions


def run_cell(cell: Cell, sample, solver, lower: np.ndarray, upper: np.ndarray,
             variable_names: tuple[str, ...], hop_solver=None) -> tuple[pd.DataFrame, pd.DataFrame]:
    """Every search of ``cell`` in this process (:func:`run_search`; a cell that :func:`repeats_search_0` solves
    search 0 only), as two tables: events and solutions."""
    events, solutions = [], []
    first = None
    for r in range(cell.searches):
        if first is not None and repeats_search_0(cell):
            e, s = as_search(first, r)
        else:
            e, s = first = run_search(cell, r, sample, solver, lower, upper, variable_names, hop_solver)
        events += e
        solutions += s
    return pd.DataFrame(events), pd.DataFrame(solutions)


def best_known(*objectives: Iterable[float]) -> float:
    """The lowest finite objective among the given collections (library rows, every search's feasible solutions);
    NaN if there is none."""
    values = [v for group in objectives for v in np.asarray(list(group), float).ravel() if math.isfinite(v)]
    return min(values) if values else math.nan


def hit_iterations(events: pd.DataFrame, target: float, budget: float = math.inf) -> pd.Series:
    """Per search (index): the cumulative iterations at which its best objective first reached ``target``
    (≤), infinity if it never did within ``budget`` iterations (the solve that crosses the budget runs to its end,
    but a hit beyond the budget does not count: every strategy gets the same iterations)."""
    reached = events[(events["best_objective"] <= target) & (events["cumulative_iterations"] <= budget)]
    first = reached.groupby("search")["cumulative_iterations"].min()
    return first.astype(float).reindex(sorted(events["search"].unique()), fill_value=math.inf)


def _spent(cell: pd.DataFrame, budget: float) -> np.ndarray:
    """Per search (sorted): the iterations it spent, at most ``budget``."""
    return np.minimum(cell.groupby("search")["cumulative_iterations"].max().sort_index().to_numpy(float), budget)


def expected_runtime(hits: np.ndarray, spent: np.ndarray) -> float:
    """ERT: iterations spent until success (``hits``, finite) or in all (``spent``, where ``hits`` is infinite),
    summed over searches, per successful search; infinity without one."""
    success = np.isfinite(hits)
    if not success.any():
        return math.inf
    return float((np.where(success, hits, spent)).sum() / success.sum())


def runtime_to_target(events: pd.DataFrame, best: float, deltas=DELTAS, n_boot: int = 2000,
                      seed: int = 0, budget: float = math.inf) -> pd.DataFrame:
    """One row per (sampler, strategy, α, δ): searches, successes, success rate, ERT with a percentile bootstrap
    95 % interval over searches (``n_boot`` resamples, ``default_rng(seed)``; infinite where a resample has no
    success), the median hit (iterations, over successful searches), ``best_known`` and the target objective."""
    rows = []
    for (sampler, strategy, alpha), cell in events.groupby(["sampler", "strategy", "alpha"], sort=True):
        spent = _spent(cell, budget)
        for delta in deltas:
            hits = hit_iterations(cell, best + delta, budget).to_numpy()
            rng = np.random.default_rng([seed, int(round(delta * 1000))])
            picks = rng.integers(0, len(hits), (n_boot, len(hits)))
            boot = np.array([expected_runtime(hits[p], spent[p]) for p in picks])
            ok = np.isfinite(hits)
            rows.append({
                "sampler": sampler, "strategy": strategy, "alpha": alpha, "delta": delta, "searches": len(hits),
                "successes": int(ok.sum()), "success_rate": float(ok.mean()),
                # Quantiles that pick a resample's value (no interpolation between a finite ERT and infinity).
                "ert": expected_runtime(hits, spent), "ert_lo": float(np.quantile(boot, 0.025, method="inverted_cdf")),
                "ert_hi": float(np.quantile(boot, 0.975, method="inverted_cdf")),
                "median_hit": float(np.median(hits[ok])) if ok.any() else math.inf,
                "best_known": best, "target": best + delta,
            })
    return pd.DataFrame(rows)


def ert_ratios(events: pd.DataFrame, best: float, deltas=DELTAS, baseline: tuple[str, str] = ("multistart", "uniform"),
               n_boot: int = 2000, seed: int = 0, budget: float = math.inf) -> pd.DataFrame:
    """ERT of each (strategy, sampler) cell ÷ ERT of the ``baseline`` (strategy, sampler) cell at the same α and
    δ, with a percentile bootstrap 95 % interval (each cell's searches resampled on their own, ``n_boot`` times):
    an interval below 1 says the cell reaches the target significantly faster.  Infinite where the cell never
    succeeded, NaN where the baseline never did."""
    rows = []
    for alpha, here in events.groupby("alpha", sort=True):
        cells = {key: cell for key, cell in here.groupby(["strategy", "sampler"], sort=True)}
        if baseline not in cells:
            continue
        for delta in deltas:
            rng = np.random.default_rng([seed, int(round(delta * 1000)), 1])

            def sample(cell):
                spent = _spent(cell, budget)
                hits = hit_iterations(cell, best + delta, budget).to_numpy()
                picks = rng.integers(0, len(hits), (n_boot, len(hits)))
                return (expected_runtime(hits, spent),
                        np.array([expected_runtime(hits[p], spent[p]) for p in picks]))

            base, base_boot = sample(cells[baseline])
            for (strategy, sampler), cell in cells.items():
                ert, boot = sample(cell)
                with np.errstate(invalid="ignore", divide="ignore"):
                    ratio = ert / base if np.isfinite(base) else math.nan
                    ratios = boot / base_boot
                # A resample in which neither cell succeeded says nothing: it counts against both ends (0 for the
                # lower, ∞ for the upper quantile), so rare successes widen the interval instead of narrowing it.
                if np.isfinite(base):
                    lo = float(np.quantile(np.nan_to_num(ratios, nan=0.0, posinf=np.inf), 0.025, method="inverted_cdf"))
                    hi = float(np.quantile(np.where(np.isnan(ratios), np.inf, ratios), 0.975, method="inverted_cdf"))
                else:
                    lo = hi = math.nan
                rows.append({"alpha": alpha, "delta": delta, "strategy": strategy, "sampler": sampler,
                             "baseline": " × ".join(baseline), "ratio": ratio, "ratio_lo": lo, "ratio_hi": hi})
    return pd.DataFrame(rows)


def paired_ratios(events: pd.DataFrame, best: float, deltas=DELTAS, n_boot: int = 2000, seed: int = 0,
                  budget: float = math.inf, reuse: str = REUSE_ARM) -> pd.DataFrame:
    """The two questions of a strategy × sampler study, as ERT ratios with :func:`ert_ratios`'s intervals:
    ``question`` "hopping" — each basin-hopping cell ÷ multi-start from the *same* sampler (does hopping pay?) —
    and "sampler" — each sampler's cell ÷ ``reuse``'s under the *same* strategy (does a sampler beat reuse, and
    does hopping change that answer?).  Columns of :func:`ert_ratios` plus ``question``."""
    parts = []
    cells = set(zip(events["strategy"], events["sampler"]))
    for strategy, sampler in sorted(cells):
        if strategy != "multistart" and ("multistart", sampler) in cells:
            r = ert_ratios(events[(events["sampler"] == sampler) & events["strategy"].isin(["multistart", strategy])],
                           best, deltas, ("multistart", sampler), n_boot, seed, budget)
            parts.append(r[r["strategy"] == strategy].assign(question="hopping"))
        if sampler != reuse and (strategy, reuse) in cells:
            r = ert_ratios(events[(events["strategy"] == strategy) & events["sampler"].isin([reuse, sampler])],
                           best, deltas, (strategy, reuse), n_boot, seed, budget)
            parts.append(r[r["sampler"] == sampler].assign(question="sampler"))
    if not parts:
        return pd.DataFrame(columns=["alpha", "delta", "strategy", "sampler", "baseline", "ratio", "ratio_lo",
                                     "ratio_hi", "question"])
    return pd.concat(parts, ignore_index=True).sort_values(["question", "alpha", "delta", "strategy", "sampler"],
                                                           ignore_index=True)


def runtime_ecdf(events: pd.DataFrame, best: float, deltas=DELTAS, budget: float = math.inf) -> pd.DataFrame:
    """The runtime ECDF per (sampler, strategy, α): for each hit of a (search, δ) pair within ``budget``, in order,
    the fraction of all its (search, δ) pairs reached by then (``iterations``, ``fraction``)."""
    rows = []
    for (sampler, strategy, alpha), cell in events.groupby(["sampler", "strategy", "alpha"], sort=True):
        hits = np.concatenate([hit_iterations(cell, best + d, budget).to_numpy() for d in deltas])
        finite = np.sort(hits[np.isfinite(hits)])
        rows += [{"sampler": sampler, "strategy": strategy, "alpha": alpha, "iterations": it,
                  "fraction": (k + 1) / len(hits)} for k, it in enumerate(finite)]
    return pd.DataFrame(rows, columns=["sampler", "strategy", "alpha", "iterations", "fraction"])


def distinct_near_best(solutions: pd.DataFrame, best: float, deltas=DELTAS,
                       params: DiversityParams = DiversityParams()) -> pd.DataFrame:
    """Per (sampler, strategy, α, δ): the feasible solutions within δ of the best known (``near_best``) and the
    size of an η-distinct subset of them (``distinct``; :func:`~amorgs.analysis.diversity.diverse_subset`)."""
    rows = []
    for (sampler, strategy, alpha), cell in solutions.groupby(["sampler", "strategy", "alpha"], sort=True):
        for delta in deltas:
            near = cell[cell["objective"] <= best + delta].reset_index(drop=True)
            distinct = diverse_subset(near, params).size if len(near) else 0
            rows.append({"sampler": sampler, "strategy": strategy, "alpha": alpha, "delta": delta,
                         "near_best": len(near), "distinct": int(distinct)})
    return pd.DataFrame(rows)
