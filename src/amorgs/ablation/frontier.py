"""The frontier (issue 21 §1): at which gap between a test α and the nearest α the samplers may use does a
learned sampler overtake reuse of the nearest known α's solutions?

Two parts, both pure (no file IO):

- the *designs*, which α a fold trains on and tests at: :func:`leave_one_out` (each chosen library α in turn is
  the test α, the others train) and :func:`sparse_grid` (k training α spread over the library's range, tested
  at the library α nearest each mid-gap).  Each fold is one config run through the workflow's DAG; the models,
  the reuse pools and the arms' data see only its training α (:class:`Fold`, ``train``).
- the *aggregation* (:func:`frontier_table`): per (design, test α, arm) the starts n pooled over the model
  seeds, the expected running time aRT (IPOPT iterations, primary; CPU seconds) with a bootstrap interval,
  and the ratio aRT(learned) ÷ aRT(reuse) with its bootstrap interval (< 1: the learned arm needs less to
  find a high-quality solution than reuse does), against the gap Δα = |α_test − α_nearest| (N) and the
  relative gap Δα / α_test.  Every statistic comes from :mod:`amorgs.ablation.running_time`.

α identity is the three-decimal label of :mod:`amorgs.alphas` throughout.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pandas as pd

from amorgs.ablation.arms import BASELINE_ARM, REUSE_ARM
from amorgs.ablation.running_time import ERT_TARGETS, art_interval, expected_running_time
from amorgs.alphas import alpha_label, alpha_value, distinct_alphas, same_alpha
from amorgs.errors import InputError


@dataclass(frozen=True)
class Fold:
    """One run of the DAG: ``design`` (e.g. ``loo``, ``sparse-3``), its ``name`` (``loo-0.500``, ``sparse-3``:
    also the run's directory name), the training α (N) — all the models, the reuse pools and the arms' data
    may see — and the test α (N), never among them."""

    design: str
    name: str
    train: tuple[float, ...]
    test: tuple[float, ...]


def leave_one_out(alphas, held_out: float) -> Fold:
    """The fold of ``alphas`` (the library's α, N) that tests at ``held_out`` and trains on all the others."""
    pool = distinct_alphas(alphas)
    if not any(same_alpha(a, held_out) for a in pool):
        raise ValueError(f"α = {held_out:g} is not one of the library's α {pool}")
    train = tuple(a for a in pool if not same_alpha(a, held_out))
    return Fold("loo", f"loo-{alpha_label(held_out)}", train, (alpha_value(held_out),))


def _nearest(pool: list[float], target: float) -> float:
    """The α of ``pool`` closest to ``target`` (ties: the smaller)."""
    return min(pool, key=lambda a: (round(abs(a - target), 9), a))


def sparse_grid(alphas, k: int) -> Fold:
    """``k`` ≥ 2 training α: the library α nearest ``k`` evenly spaced points from the smallest to the largest
    library α; test α: per gap between neighbouring training α, the library α strictly inside it nearest the
    gap's middle (a gap with no library α inside is not tested).  Ties go to the smaller α."""
    pool = distinct_alphas(alphas)
    if not 2 <= k <= len(pool):
        raise ValueError(f"a sparse grid needs 2 ≤ k ≤ {len(pool)} training α (the library's), got {k}")
    train = sorted({_nearest(pool, t) for t in np.linspace(pool[0], pool[-1], k)})
    if len(train) < k:
        raise ValueError(f"the library α {pool} hold no {k} distinct α near an even grid")
    test = []
    for a, b in zip(train, train[1:]):
        inside = [c for c in pool if a < c < b]
        if inside:
            test.append(_nearest(inside, (a + b) / 2))
    if not test:
        raise ValueError(f"the sparse grid {train} leaves no library α between its training α to test at")
    return Fold(f"sparse-{k}", f"sparse-{k}", tuple(train), tuple(test))


def gap(test_alpha: float, train_alphas) -> tuple[float, float, float]:
    """(the training α nearest ``test_alpha`` — ties: the smaller —, the absolute gap |Δα| in N, the relative
    gap |Δα| / ``test_alpha``)."""
    usable = [a for a in distinct_alphas(train_alphas) if not same_alpha(a, test_alpha)]
    if not usable:
        raise ValueError(f"no training α other than the test α {test_alpha:g}")
    nearest = _nearest(usable, alpha_value(test_alpha))
    delta = abs(alpha_value(test_alpha) - nearest)
    return nearest, delta, delta / alpha_value(test_alpha)


@dataclass(frozen=True)
class FrontierRun:
    """One finished fold: its ``design`` and ``run`` names, training α (N), β (kg) and η (Eq. 12) of its
    config, and its ablation cell tables concatenated (every model seed; no learning-curve cells)."""

    design: str
    run: str
    train: tuple[float, ...]
    beta_kg: float
    eta: float
    cells: pd.DataFrame


def frontier_table(
    runs: list[FrontierRun], learned: tuple[str, ...] | None = None, reuse: str = REUSE_ARM,
    baseline: str = BASELINE_ARM, n_boot: int = 2000, seed: int = 0,
) -> pd.DataFrame:
    """One row per (design, run, test α, arm, target, unit): the frontier's data.

    Columns: ``design``, ``run``, ``alpha`` (test α, N), ``nearest_train_alpha``, ``gap`` (|Δα|, N),
    ``gap_relative`` (|Δα| / α), ``reuse_alpha`` (the α the reuse arm drew from: equals the nearest training
    α), ``sampler``, ``target`` (``high_quality``: aRT per high-quality solution; ``distinct``: per new
    η-distinct high-quality optimum, Eq. 12), ``unit`` (``iterations``: IPOPT iterations, primary;
    ``cpu_s``: CPU seconds), ``n`` (starts pooled over the ``model_seeds`` cells), ``k_found``, ``aRT`` with
    its bootstrap 95 % interval ``aRT_ci95_low/high`` (:func:`~amorgs.ablation.running_time.art_interval`),
    ``speedup`` = aRT(baseline) ÷ aRT(arm) with its interval, and — for the ``learned`` arms —
    ``ratio_to_reuse`` = aRT(arm) ÷ aRT(reuse) with its interval (< 1: the learned arm wins; NaN elsewhere).
    ``aRT_oracle`` is the arm's oracle bound, its aRT had it solved only the starts that found something, and
    ``oracle_to_reuse`` = aRT_oracle ÷ aRT(reuse): on the reuse row, the limit of any selector over reuse's
    retrieved candidates (issue 38 §4); a learned arm's ``ratio_to_reuse`` ÷ the reuse row's
    ``oracle_to_reuse`` is its distance to that limit.
    The reuse arm, the baseline and every arm in ``learned`` (default: every other arm of the first run) must
    be in each run's cells.  Bootstraps are seeded by ``seed``: one table from one set of runs.
    """
    if learned is None:
        learned = tuple(sorted(set(runs[0].cells["sampler"]) - {reuse, baseline})) if runs else ()
    rows = []
    for r in runs:
        cells = r.cells.assign(alpha=r.cells["alpha"].map(alpha_value))
        missing = {reuse, baseline, *learned} - set(cells["sampler"])
        if missing:
            raise InputError(f"run {r.run}: no cells of {sorted(missing)} (the frontier needs them; its arms: "
                             f"{', '.join(sorted(set(cells['sampler'])))})")
        for alpha, g in cells.groupby("alpha", sort=True):
            nearest, delta, rel = gap(alpha, r.train)
            reused = g.loc[g["sampler"] == reuse, "reuse_alpha"]
            where = {"design": r.design, "run": r.run, "alpha": alpha, "nearest_train_alpha": nearest,
                     "gap": delta, "gap_relative": rel,
                     "reuse_alpha": float(reused.iloc[0]) if len(reused) else math.nan}
            rows += _alpha_rows(g, where, r, learned, reuse, baseline, n_boot, seed)
    return pd.DataFrame(rows)


def _alpha_rows(g: pd.DataFrame, where: dict, r: FrontierRun, learned, reuse: str, baseline: str,
                n_boot: int, seed: int) -> list[dict]:
    """The rows of one test α of one run (see :func:`frontier_table`)."""
    rows = []
    for target in ERT_TARGETS:
        kw = dict(n_boot=n_boot, seed=seed, target=target, eta=r.eta)
        ert = expected_running_time(g, r.beta_kg, baseline=baseline, reuse=reuse, **kw)
        # expected_running_time's ratio to its `reuse` arm is aRT(reuse) ÷ aRT(row's arm): with a learned arm
        # in that place, the reuse arm's row holds aRT(learned) ÷ aRT(reuse), bootstrapped as it stands.
        versus = {arm: expected_running_time(g, r.beta_kg, baseline=baseline, reuse=arm, **kw)
                  .set_index(["sampler", "unit"]).loc[reuse] for arm in learned}
        intervals = art_interval(g, r.beta_kg, n_boot=n_boot, seed=seed, target=target, eta=r.eta)
        reuse_art = ert[ert["sampler"] == reuse].set_index("unit")["aRT"]
        for e in ert.itertuples(index=False):
            row = {**where, "sampler": e.sampler, "target": target, "unit": e.unit, "n": e.n,
                   "model_seeds": int(g.loc[g["sampler"] == e.sampler, "model_seed"].nunique())
                   if "model_seed" in g else 1,
                   "k_found": e.k_distinct if target == "distinct" else e.k_high_quality, "aRT": e.aRT,
                   "aRT_ci95_low": intervals[(e.sampler, e.unit)][0],
                   "aRT_ci95_high": intervals[(e.sampler, e.unit)][1],
                   "speedup": e.speedup, "speedup_ci95_low": e.speedup_ci95_low,
                   "speedup_ci95_high": e.speedup_ci95_high, "aRT_oracle": e.aRT_oracle,
                   "oracle_to_reuse": _ratio(e.aRT_oracle, reuse_art[e.unit]),
                   "ratio_to_reuse": math.nan, "ratio_to_reuse_ci95_low": math.nan,
                   "ratio_to_reuse_ci95_high": math.nan}
            if e.sampler in versus:
                v = versus[e.sampler].loc[e.unit]
                row.update(ratio_to_reuse=v["versus_reuse"], ratio_to_reuse_ci95_low=v["versus_reuse_ci95_low"],
                           ratio_to_reuse_ci95_high=v["versus_reuse_ci95_high"])
            rows.append(row)
    return rows


def _ratio(a: float, b: float) -> float:
    """a ÷ b for aRTs (∞ allowed): NaN when both are ∞ or b is 0."""
    if math.isinf(a) and math.isinf(b) or b == 0:
        return math.nan
    return a / b


def frontier_metrics(table: pd.DataFrame) -> dict[str, float]:
    """MLflow metrics of a frontier table: ``frontier_ratio/<run>/alpha_<label>/<arm>[/distinct]_<unit>`` and
    its interval (aRT learned ÷ reuse), finite values only."""
    out: dict[str, float] = {}
    rows = table[table["ratio_to_reuse"].notna()]
    for r in rows.itertuples(index=False):
        what = ("distinct_" if r.target == "distinct" else "") + r.unit
        for suffix, v in (("", r.ratio_to_reuse), ("_ci95_low", r.ratio_to_reuse_ci95_low),
                          ("_ci95_high", r.ratio_to_reuse_ci95_high)):
            if math.isfinite(v):
                out[f"frontier_ratio{suffix}/{r.run}/alpha_{alpha_label(r.alpha)}/{r.sampler}/{what}"] = float(v)
    return out


#: Measured test points whose relative gap lies within this factor of the nearest one are pooled by
#: :func:`choose_sampler` (near-equal gaps are one measurement, not a choice between noisy neighbours).
POOL_FACTOR = 1.25


@dataclass(frozen=True)
class SamplerChoice:
    """What :func:`choose_sampler` picked: the ``sampler``, a one-paragraph ``reason`` a designer can read, the
    requested α's ``nearest_train_alpha`` (N), ``gap`` (N) and ``gap_relative``, and the frontier rows it
    rests on (``evidence``: design, run, α, gap_relative, sampler, ratio_to_reuse and its interval)."""

    sampler: str
    reason: str
    nearest_train_alpha: float
    gap: float
    gap_relative: float
    evidence: tuple[dict, ...] = ()


def choose_sampler(frontier: pd.DataFrame, alpha: float, train_alphas, available: tuple[str, ...] | None = None,
                   reuse: str = REUSE_ARM, unit: str = "iterations", target: str = "high_quality") -> SamplerChoice:
    """The sampler the measured frontier recommends at ``alpha`` given the α whose solutions are known
    (``train_alphas``, N): reuse (``reuse``) unless a learned arm measured *significantly* better than reuse
    at the relative gap nearest this one.

    The rule: with the relative gap g = |α − nearest known α| / α, take the frontier's rows (``unit``,
    ``target``, arms with a ratio to reuse, restricted to ``available`` when given) at the measured relative
    gap nearest g on a log scale, pooling every measured point within a factor :data:`POOL_FACTOR` of it. An
    arm wins when the upper end of its 95 % interval of aRT(arm) ÷ aRT(reuse) is below 1 at every pooled
    point; among winners the one with the lowest geometric-mean ratio is chosen. At g = 0 (α is known) or
    without measurements it is reuse.
    """
    known = distinct_alphas(train_alphas)
    target_alpha = alpha_value(alpha)
    if any(same_alpha(a, target_alpha) for a in known):
        return SamplerChoice(reuse, f"α = {target_alpha:g} N is a library α: its own high-quality solutions are "
                             f"reused ({reuse}).", target_alpha, 0.0, 0.0)
    nearest, delta, rel = gap(target_alpha, known)
    rows = frontier[(frontier["unit"] == unit) & (frontier["target"] == target)
                    & frontier["ratio_to_reuse"].notna() & (frontier["gap_relative"] > 0)]
    if available is not None:
        rows = rows[rows["sampler"].isin(available)]
    where = f"α = {target_alpha:g} N is {delta:.3g} N ({rel:.1%}) from the nearest library α {nearest:g}"
    if rows.empty:
        return SamplerChoice(reuse, f"{where}; no frontier measurement of a learned arm: reuse ({reuse}).",
                             nearest, delta, rel)
    distance = np.abs(np.log(rows["gap_relative"].to_numpy(float) / rel))
    pooled = rows[distance <= distance.min() + math.log(POOL_FACTOR)]
    points = sorted({(r.run, alpha_label(r.alpha), r.gap_relative) for r in pooled.itertuples()}, key=lambda p: p[2])
    at = ", ".join(f"{label} in {run} ({g:.1%})" for run, label, g in points)
    evidence = tuple(pooled[["design", "run", "alpha", "gap_relative", "sampler", "ratio_to_reuse",
                             "ratio_to_reuse_ci95_low", "ratio_to_reuse_ci95_high"]].to_dict("records"))
    summary = []
    winners = {}
    for arm, g in pooled.groupby("sampler", sort=True):
        ratio = float(np.exp(np.log(g["ratio_to_reuse"].clip(lower=1e-12)).mean()))
        summary.append(f"{arm} ÷ reuse {ratio:.2g} (95 % upper ends {', '.join(f'{v:.2g}' for v in g['ratio_to_reuse_ci95_high'])})")
        if (g["ratio_to_reuse_ci95_high"] < 1).all():
            winners[arm] = ratio
    measured = f"{where}; nearest measured relative gap: test α {at}: " + "; ".join(summary)
    if not winners:
        return SamplerChoice(reuse, f"{measured}. No learned arm beat reuse significantly there: reuse ({reuse}).",
                             nearest, delta, rel, evidence)
    best = min(winners, key=winners.get)
    return SamplerChoice(best, f"{measured}. {best} beat reuse significantly there: {best}.", nearest, delta, rel,
                         evidence)
