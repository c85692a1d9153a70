"""The cost side of the warm-start ablation: the expected running time (aRT, the COCO platform's measure) of
each arm in IPOPT iterations (primary: deterministic) and CPU seconds, per high-quality solution or per *new*
η-distinct high-quality optimum (paper Eq. 12), with bootstrap intervals and speed-ups (issues 11 and 21); the
oracle bound a perfect selector would reach (issue 38); the spread over model seeds, the learning curve and the
break-even of an arm's up-front CPU; Fig. 22 with an iteration cap fixed before the solves; and the anytime
curves.  Rates and their intervals are :mod:`amorgs.ablation.statistics`; the input is the same concatenation
of ablation cell tables.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from amorgs.ablation.arms import BASELINE_ARM, REUSE_ARM
from amorgs.ablation.statistics import fisher_greater, high_quality, ratio_of_rates_interval, wilson_interval


def _order(df: pd.DataFrame) -> pd.DataFrame:
    keys = [c for c in ("model_seed", "start") if c in df.columns]
    return df.sort_values(keys, kind="stable") if keys else df


#: Cost units of the expected running time: IPOPT iterations (deterministic, primary) and CPU seconds.
COST_UNITS = ("iterations", "cpu_s")


def solve_costs(df: pd.DataFrame, unit: str) -> np.ndarray:
    """Per-row cost in ``unit`` (``iterations`` or ``cpu_s``); a row without a value (a crashed or killed
    worker) is charged the largest value in ``df``."""
    if unit not in COST_UNITS:
        raise ValueError(f"unknown cost unit {unit!r}; choose one of {COST_UNITS}")
    c = df[unit].astype(float).to_numpy()
    fill = np.nanmax(c) if np.isfinite(c).any() else 0.0
    return np.where(np.isfinite(c), c, fill)


#: What the expected running time counts as found: a high-quality solution, or a *new* η-distinct
#: high-quality optimum (paper Eq. 12, :func:`amorgs.analysis.diversity.first_come_diverse`).
ERT_TARGETS = ("high_quality", "distinct")


def _ert(cost: np.ndarray, hq: np.ndarray) -> float:
    """aRT per high-quality solution of one arm (``hq``: its per-start flags)."""
    return _art(cost, _found_counter(hq))


def _new_optima(hq: np.ndarray, features: np.ndarray, eta: float):
    """``flags(index)``: per start of ``index`` (positions in one arm, 1-D or one resample per row), True
    where it found a *new* η-distinct high-quality optimum, the starts taken in the order of ``index``
    (:func:`amorgs.analysis.diversity.first_come_diverse` on the diversity coordinates ``features``)."""
    from amorgs.analysis.diversity import conflicts, first_come_diverse

    position = np.full(len(hq), -1)
    position[hq] = np.arange(int(hq.sum()))
    close = conflicts(features[hq], eta)
    return lambda index: first_come_diverse(close, position[index])


def _found_flags(hq: np.ndarray, features: np.ndarray | None = None, eta: float = math.nan) -> np.ndarray:
    """Per start of one arm, in its draw order: did it find something — a high-quality solution, or with
    ``features`` a new η-distinct high-quality optimum (:func:`_new_optima`)?"""
    if features is None:
        return np.asarray(hq, bool)
    return _new_optima(hq, features, eta)(np.arange(len(hq)))


def _oracle_art(cost: np.ndarray, flags: np.ndarray) -> float:
    """The oracle bound of an arm's aRT: its cost had it solved only the starts that found something (a perfect
    selector over the same starts, knowing the outcomes in advance) ÷ what they found; ∞ when nothing was."""
    k = int(flags.sum())
    return float(cost[flags].sum()) / k if k else math.inf


def _found_counter(hq: np.ndarray, features: np.ndarray | None = None, eta: float = math.nan):
    """``count(index)``: what the starts ``index`` (positions in one arm; 1-D → a number, 2-D → one per row)
    found — high-quality solutions, or with ``features`` (the diversity coordinates of every start) the new
    η-distinct high-quality optima (:func:`_found_flags`)."""
    return _counter(_found_flags(hq, features, eta))


def _counter(flags: np.ndarray):
    """``count(index)`` over per-start ``flags`` (:func:`_found_counter`).

    Each start's flag is fixed by the arm's own draw order, and a resample counts the flags of the starts it
    holds.  Recomputing the flags per resample would count a start drawn twice once — a duplicate no real
    rerun produces at the bootstrap's rate (≈ 37 % of a resample's draws repeat one) — and bias every
    resampled aRT per distinct optimum upward, past its own point estimate."""
    return lambda index: flags[index].sum(-1)


def _art(cost: np.ndarray, count) -> float:
    """aRT of one arm: its total cost ÷ what its starts, in order, found (``count``: :func:`_found_counter`)."""
    k = int(count(np.arange(len(cost))))
    return float(cost.sum()) / k if k else math.inf


def _ratio_boot(cb, count_b, ca, count_a, n_boot: int, rng: np.random.Generator) -> tuple[float, float]:
    """Percentile 95 % interval of aRT_b ÷ aRT_a, rows resampled with replacement within each arm
    (``count_*``: :func:`_found_counter` of the arm)."""
    ib = rng.integers(0, len(cb), size=(n_boot, len(cb)))
    ia = rng.integers(0, len(ca), size=(n_boot, len(ca)))
    kb, kc_b = count_b(ib), cb[ib].sum(1)
    ka, kc_a = count_a(ia), ca[ia].sum(1)
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = (kc_b * ka) / (kb * kc_a)  # (C_b / k_b) / (C_a / k_a)
    ratio = np.where((kb == 0) & (ka > 0), np.inf, ratio)
    ratio = ratio[~np.isnan(ratio)]  # both arms found nothing: no information about the ratio
    if not ratio.size:
        return (math.nan, math.nan)
    q = np.quantile(ratio, [0.025, 0.975], method="inverted_cdf")
    return (float(q[0]), float(q[1]))


def _versus(cost_all, counters, base, idx, n_boot: int, rng: np.random.Generator) -> tuple[float, float, float]:
    """aRT_base ÷ aRT_arm (> 1: the arm is faster) and its bootstrap 95 % interval; 0 when only the base
    found anything, ∞ when only the arm did.  ``base``, ``idx``: (name, row positions) of the two arms."""
    (b_name, b_idx), (a_name, a_idx) = base, idx
    found_b, found_a = counters[b_name], counters[a_name]
    ert, ert_b = _art(cost_all[a_idx], found_a), _art(cost_all[b_idx], found_b)
    ratio = ert_b / ert if math.isfinite(ert) else (0.0 if math.isfinite(ert_b) else math.nan)
    return (ratio, *_ratio_boot(cost_all[b_idx], found_b, cost_all[a_idx], found_a, n_boot, rng))


def expected_running_time(
    df: pd.DataFrame, beta_kg: float, baseline: str = BASELINE_ARM, reuse: str = REUSE_ARM,
    n_boot: int = 2000, seed: int = 0, target: str = "high_quality", eta: float | None = None,
) -> pd.DataFrame:
    """COCO-style expected running time per (α, sampler, unit): aRT = (all cost spent) ÷ (what was found), in
    IPOPT iterations (primary: deterministic) and CPU seconds; ∞ when nothing was found.
    ``speedup`` = aRT_baseline ÷ aRT_arm, and ``versus_reuse`` = aRT_reuse ÷ aRT_arm (> 1: the arm beats
    reusing the nearest training α's solutions; < 1: reuse is faster by 1/versus_reuse), each with a seeded
    bootstrap 95 % interval (rows resampled within each arm, 0/0 resamples dropped, ∞ kept; the two
    comparisons draw from separate streams, so adding one does not move the other).

    ``target`` (:data:`ERT_TARGETS`): ``"high_quality"`` counts high-quality solutions; ``"distinct"`` counts
    what a designer wants, the *new η-distinct* high-quality optima (paper Eq. 12; η of the ``times``
    metric of :mod:`amorgs.analysis.diversity`, ``eta`` or its default): each arm's starts in order
    (model_seed, start), a high-quality solution counts when it is farther than η from every one counted
    before — a repeat of a solved start, or a solution in a basin already found, costs its iterations and
    finds nothing new.  A bootstrap resample takes its starts in the order drawn.  That table adds
    ``k_distinct`` and ``eta``.  ``aRT_oracle`` is the arm's oracle bound (issue 38 §4): its aRT had it solved
    only the starts that found something — what a perfect selector over the same starts would spend."""
    from amorgs.analysis.diversity import DiversityParams, diversity_features

    if target not in ERT_TARGETS:
        raise ValueError(f"unknown aRT target {target!r}; choose one of {ERT_TARGETS}")
    params = DiversityParams() if eta is None else DiversityParams(eta=float(eta))
    rng = np.random.default_rng(seed)
    rng_reuse = np.random.default_rng([seed, 1])
    rows = []
    for alpha, ga in df.groupby("alpha", sort=True):
        if target == "distinct":
            ga = _order(ga)
        groups = ga.groupby("sampler", sort=False).indices
        hq_all = high_quality(ga, beta_kg).to_numpy()
        feats = diversity_features(ga, params) if target == "distinct" else None
        flags = {s: _found_flags(hq_all[idx], None if feats is None else feats[idx], params.eta)
                 for s, idx in groups.items()}
        counters = {s: _counter(f) for s, f in flags.items()}
        for unit in COST_UNITS:
            cost_all = solve_costs(ga, unit)
            for sampler, idx in sorted(groups.items()):
                row = {"alpha": alpha, "sampler": sampler, "unit": unit, "n": len(idx),
                       "k_high_quality": int(hq_all[idx].sum())}
                if target == "distinct":
                    row.update(k_distinct=int(counters[sampler](np.arange(len(idx)))), eta=params.eta)
                row.update(cost_total=float(cost_all[idx].sum()), aRT=_art(cost_all[idx], counters[sampler]),
                           aRT_oracle=_oracle_art(cost_all[idx], flags[sampler]))
                for column, name, stream in (("speedup", baseline, rng), ("versus_reuse", reuse, rng_reuse)):
                    base = groups.get(name)
                    values = ((math.nan,) * 3 if base is None else
                              _versus(cost_all, counters, (name, base), (sampler, idx), n_boot, stream))
                    row.update(zip((column, f"{column}_ci95_low", f"{column}_ci95_high"), values))
                rows.append(row)
    return pd.DataFrame(rows)


def art_interval(
    df: pd.DataFrame, beta_kg: float, n_boot: int = 2000, seed: int = 0, target: str = "high_quality",
    eta: float | None = None,
) -> dict[tuple[str, str], tuple[float, float]]:
    """(sampler, unit) → percentile bootstrap 95 % interval of the aRT of :func:`expected_running_time` (same
    ``target`` and ``eta``; unit :data:`COST_UNITS`) for the cells of ONE α: each arm's starts resampled with
    replacement (taken in the order drawn), one resample serving both units; a resample that found nothing
    has aRT ∞ (an interval may end at ∞).  Seeded: ``seed``."""
    from amorgs.analysis.diversity import DiversityParams, diversity_features

    if df["alpha"].map(float).nunique() != 1:
        raise ValueError("art_interval takes the cells of one α")
    params = DiversityParams() if eta is None else DiversityParams(eta=float(eta))
    df = _order(df) if target == "distinct" else df
    hq_all = high_quality(df, beta_kg).to_numpy()
    feats = diversity_features(df, params) if target == "distinct" else None
    rng = np.random.default_rng([seed, 4])
    out = {}
    for sampler, idx in sorted(df.groupby("sampler", sort=False).indices.items()):
        found = _found_counter(hq_all[idx], None if feats is None else feats[idx], params.eta)
        index = rng.integers(0, len(idx), size=(n_boot, len(idx)))
        k = found(index)
        for unit in COST_UNITS:
            spent = solve_costs(df, unit)[idx][index].sum(1)
            with np.errstate(divide="ignore", invalid="ignore"):
                art = np.where(k > 0, spent / np.maximum(k, 1), np.inf)
            q = np.quantile(art, [0.025, 0.975], method="inverted_cdf")
            out[(sampler, unit)] = (float(q[0]), float(q[1]))
    return out


def seed_spread(df: pd.DataFrame, beta_kg: float) -> pd.DataFrame:
    """Per (α, sampler, model-training seed): starts n, high-quality k, rate (%) with its Wilson 95 % interval,
    and aRT in IPOPT iterations — how far an arm moves between the seeds its models were trained with (the
    pooled tables average over them; the model-free arms show the spread of the starts alone).  Empty when
    the cells carry a single model seed."""
    if "model_seed" not in df.columns or df["model_seed"].nunique() < 2:
        return pd.DataFrame()
    hq_all = high_quality(df, beta_kg).to_numpy()
    cost_all = solve_costs(df, "iterations")
    rows = []
    for (alpha, sampler, mseed), idx in sorted(df.groupby(["alpha", "sampler", "model_seed"]).indices.items()):
        k, n = int(hq_all[idx].sum()), len(idx)
        lo, hi = wilson_interval(k, n)
        rows.append({"alpha": alpha, "sampler": sampler, "model_seed": int(mseed), "n": n, "k_high_quality": k,
                     "percent": 100 * k / n, "ci95_low": lo, "ci95_high": hi,
                     "aRT_iterations": _ert(cost_all[idx], hq_all[idx])})
    return pd.DataFrame(rows)


def learning_curve(
    full: pd.DataFrame, partial: pd.DataFrame, beta_kg: float, baseline: str = BASELINE_ARM,
    reuse: str = REUSE_ARM, n_boot: int = 2000, seed: int = 0,
) -> pd.DataFrame:
    """The expected running time of each learned arm against the fraction of the training data its models saw
    (issue 11 §4): :func:`expected_running_time` of the arm's cells at each ``data_fraction`` of ``partial``
    and of its full-data cells in ``full`` (fraction 1), each against the same ``baseline`` and ``reuse``
    cells of ``full``; columns as there plus ``data_fraction``.  Empty without partial-data cells."""
    if partial.empty:
        return pd.DataFrame()
    arms = sorted(partial["sampler"].unique())
    curves = pd.concat([full[full["sampler"].isin(arms)].assign(data_fraction=1.0), partial], ignore_index=True)
    references = full[full["sampler"].isin((baseline, reuse))]
    out = []
    for fraction, g in curves.groupby("data_fraction", sort=True):
        ert = expected_running_time(pd.concat([references, g.drop(columns="data_fraction")], ignore_index=True),
                                    beta_kg, baseline=baseline, reuse=reuse, n_boot=n_boot, seed=seed)
        ert = ert[~ert["sampler"].isin((baseline, reuse))]
        ert.insert(2, "data_fraction", float(fraction))
        out.append(ert)
    return pd.concat(out, ignore_index=True).sort_values(["alpha", "sampler", "unit", "data_fraction"],
                                                          ignore_index=True)


def break_even(
    df: pd.DataFrame, beta_kg: float, upfront_cpu_s: dict[str, float], solutions: tuple[int, ...],
    baseline: str = BASELINE_ARM, n_boot: int = 2000, seed: int = 0,
) -> pd.DataFrame:
    """After how many new α does an arm's up-front CPU pay for itself (issue 11 §5)?

    A designer who wants ``K`` high-quality solutions at a new α spends K·aRT(arm) CPU seconds with the arm
    and K·aRT(baseline) with uniform multi-start (aRT in CPU seconds per high-quality solution, as in
    :func:`expected_running_time`).  The arm's ``upfront_cpu_s`` (the data it draws on, and for the learned
    arms the training of their models; 0 for the baseline) is repaid after
    ``break_even_new_alphas = upfront ÷ (K · (aRT_baseline − aRT_arm))`` new α — ∞ when the arm saves
    nothing.  The 95 % interval resamples the starts of both arms (seeded), as for the speed-ups; one row per
    (α, arm other than the baseline, K).
    """
    rng = np.random.default_rng(seed)
    rows = []
    for alpha, ga in df.groupby("alpha", sort=True):
        groups = ga.groupby("sampler").indices
        if baseline not in groups:
            continue
        hq, cost = high_quality(ga, beta_kg).to_numpy(), solve_costs(ga, "cpu_s")
        base = groups[baseline]
        ib = rng.integers(0, len(base), size=(n_boot, len(base)))
        boot_base = _boot_ert(cost[base], hq[base], ib)
        for sampler, idx in sorted(groups.items()):
            if sampler == baseline:
                continue
            ia = rng.integers(0, len(idx), size=(n_boot, len(idx)))
            saving = _ert(cost[base], hq[base]) - _ert(cost[idx], hq[idx])
            with np.errstate(invalid="ignore"):
                boot_saving = boot_base - _boot_ert(cost[idx], hq[idx], ia)
            boot_saving = boot_saving[~np.isnan(boot_saving)]  # ∞ − ∞: no information
            upfront = float(upfront_cpu_s.get(sampler, 0.0))
            for k in solutions:
                row = {"alpha": alpha, "sampler": sampler, "n": len(idx), "n_baseline": len(base),
                       "solutions_wanted": int(k), "upfront_cpu_h": upfront / 3600,
                       "saving_cpu_s_per_solution": saving,
                       "break_even_new_alphas": _alphas_to_repay(upfront, k, saving),
                       "ci95_low": math.nan, "ci95_high": math.nan}
                if boot_saving.size:
                    n_star = np.array([_alphas_to_repay(upfront, k, v) for v in boot_saving])
                    row["ci95_low"], row["ci95_high"] = (float(q) for q in np.quantile(n_star, [0.025, 0.975],
                                                                                        method="inverted_cdf"))
                rows.append(row)
    return pd.DataFrame(rows)


def _boot_ert(cost: np.ndarray, hq: np.ndarray, index: np.ndarray) -> np.ndarray:
    """aRT of each bootstrap resample (rows ``index``, one resample per row of it); ∞ where none is found."""
    k, c = hq[index].sum(1), cost[index].sum(1)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(k > 0, c / np.maximum(k, 1), np.inf)


def _alphas_to_repay(upfront_cpu_s: float, solutions: int, saving_per_solution: float) -> float:
    """New α needed before ``solutions`` per α, each saving ``saving_per_solution`` CPU s, repay the up-front
    CPU (0 with nothing up front, ∞ without a saving)."""
    if upfront_cpu_s <= 0:
        return 0.0
    if not saving_per_solution > 0:
        return math.inf
    return upfront_cpu_s / (solutions * saving_per_solution)


def iteration_capped(
    df: pd.DataFrame, beta_kg: float, caps, max_iter: int | None = None, baseline: str = BASELINE_ARM,
    n_boot: int = 2000, seed: int = 0,
) -> pd.DataFrame:
    """The paper's Fig. 22 measure with an iteration cap fixed *before* the scored solves (config
    ``ablation.iteration_caps``), enforced as a real cap: a start succeeds under cap c iff it reached the
    high-quality set in ≤ c iterations; every other start is charged min(its iterations, c).  IPOPT is
    deterministic, so a solve that converged in k ≤ c iterations converges identically under ``max_iter = c``
    and one that needed k > c is stopped at c; the only difference from a real re-solve is that IPOPT may
    declare the iterate at the cap "acceptable" — we count it as failed, so the measure is conservative
    (tests/integration/test_ablation.py checks the equivalence on a real solve).  Caps above the solver's
    ``max_iter`` are rejected.

    Per (α, cap, sampler): % within cap (Wilson 95 %), high-quality per 1000 iterations (throughput), and the
    ratios to ``baseline``: ``percent_ratio`` (the paper's ratio of percentages, Katz 95 % interval
    :func:`ratio_of_rates_interval`) and ``throughput_ratio`` (a seeded bootstrap 95 % interval, starts
    resampled within each arm as for :func:`expected_running_time`).
    """
    caps = sorted(int(c) for c in caps)
    if max_iter is not None and caps and caps[-1] > max_iter:
        raise ValueError(f"iteration cap {caps[-1]} exceeds the solver's max_iter = {max_iter}: not a real cap")
    rng = np.random.default_rng([seed, 3])
    rows = []
    for alpha, ga in df.groupby("alpha", sort=True):
        it_all = solve_costs(ga, "iterations")
        hq_all = high_quality(ga, beta_kg).to_numpy()
        groups = ga.groupby("sampler").indices
        for cap in caps:
            per = {}
            ok_all, spent_all = hq_all & (it_all <= cap), np.minimum(it_all, cap)
            for sampler, idx in groups.items():
                ok, spent = ok_all[idx], spent_all[idx].sum()
                lo, hi = wilson_interval(int(ok.sum()), len(idx))
                per[sampler] = {"alpha": alpha, "cap_iterations": cap, "sampler": sampler, "n": len(idx),
                                "k_within_cap": int(ok.sum()), "percent_within_cap": 100 * ok.mean(),
                                "ci95_low": lo, "ci95_high": hi, "iterations_spent": float(spent),
                                "hq_per_1000_iterations": 1000 * ok.sum() / spent if spent else math.nan}
            b = per.get(baseline)
            for sampler, row in sorted(per.items()):
                if b is not None:
                    row["percent_ratio"] = (row["percent_within_cap"] / b["percent_within_cap"]
                                            if b["percent_within_cap"] > 0 else math.inf if row["percent_within_cap"] > 0 else math.nan)
                    row["percent_ratio_ci95_low"], row["percent_ratio_ci95_high"] = ratio_of_rates_interval(
                        row["k_within_cap"], row["n"], b["k_within_cap"], b["n"])
                    bt = b["hq_per_1000_iterations"]
                    row["throughput_ratio"] = (row["hq_per_1000_iterations"] / bt
                                               if bt > 0 else math.inf if row["hq_per_1000_iterations"] > 0 else math.nan)
                    b_idx, a_idx = groups[baseline], groups[sampler]
                    row["throughput_ratio_ci95_low"], row["throughput_ratio_ci95_high"] = _ratio_boot(
                        spent_all[b_idx], _found_counter(ok_all[b_idx]), spent_all[a_idx],
                        _found_counter(ok_all[a_idx]), n_boot, rng)
                    row["p_gt_baseline"] = (fisher_greater(row["k_within_cap"], row["n"], b["k_within_cap"], b["n"])
                                            if sampler != baseline else math.nan)
                rows.append(row)
    return pd.DataFrame(rows)


def anytime_curves(df: pd.DataFrame, beta_kg: float, eta: float | None = None) -> pd.DataFrame:
    """Per (α, sampler), the starts in order (model_seed, start) with cumulative CPU seconds and iterations,
    the best m_f among the high-quality solutions found so far, and the number of *new η-distinct optima* so
    far: high-quality solutions farther than η (paper Eq. 12, the ``times`` surrogate metric of
    :mod:`amorgs.analysis.diversity`) from every earlier counted one — an η-diverse set by construction,
    grown in discovery order so the count never decreases (:func:`amorgs.analysis.diversity.first_come_diverse`,
    the count :func:`expected_running_time` divides by with ``target="distinct"``)."""
    from amorgs.analysis.diversity import DiversityParams, diversity_features

    params = DiversityParams() if eta is None else DiversityParams(eta=float(eta))
    frames = []
    for (alpha, sampler), g in df.groupby(["alpha", "sampler"], sort=True):
        g = _order(g).reset_index(drop=True)
        hq = high_quality(g, beta_kg).to_numpy()
        new = _new_optima(hq, diversity_features(g, params), params.eta)(np.arange(len(g)))
        best = g["m_f"].where(hq).cummax().ffill()  # NaN until the first high-quality solution
        frames.append(pd.DataFrame({
            "alpha": alpha, "sampler": sampler, "solve": np.arange(1, len(g) + 1),
            "cpu_s_cumulative": np.cumsum(solve_costs(g, "cpu_s")),
            "iterations_cumulative": np.cumsum(solve_costs(g, "iterations")),
            "best_m_f": best.to_numpy(dtype=float), "distinct_optima": np.cumsum(new),
        }))
    return pd.concat(frames, ignore_index=True) if frames else pd.DataFrame()


def anytime_bands(
    df: pd.DataFrame, beta_kg: float, eta: float | None = None, n_boot: int = 2000, seed: int = 0,
    points: int = 60,
) -> pd.DataFrame:
    """Bootstrap 95 % bands of the anytime curves (:func:`anytime_curves`): per (α, sampler, cost unit,
    measure), ``points`` budgets evenly spaced from 0 to the arm's total cost (``budget``, in the unit:
    IPOPT iterations or CPU s) and, at each, the 2.5 / 50 / 97.5 % quantiles (``low``, ``median``, ``high``)
    over ``n_boot`` resamples of the arm's starts (with replacement, taken in the order drawn; seeded) of
    what was found within that budget: the best high-quality m_f (kg; NaN while none is found — such
    resamples count below every m_f) and the number of new η-distinct high-quality optima.  A resample
    whose starts cost less than the budget holds its final value."""
    from amorgs.analysis.diversity import DiversityParams, diversity_features

    params = DiversityParams() if eta is None else DiversityParams(eta=float(eta))
    rng = np.random.default_rng([seed, 2])
    rows = []
    for (alpha, sampler), g in df.groupby(["alpha", "sampler"], sort=True):
        g = _order(g).reset_index(drop=True)
        hq = high_quality(g, beta_kg).to_numpy()
        index = rng.integers(0, len(g), size=(n_boot, len(g)))
        mass = np.where(hq, g["m_f"].to_numpy(dtype=float), -np.inf)[index]
        values = {"best_m_f": np.maximum.accumulate(mass, axis=1),
                  "distinct_optima": np.cumsum(_new_optima(hq, diversity_features(g, params), params.eta)(index),
                                               axis=1).astype(float)}
        for unit in COST_UNITS:
            cost = solve_costs(g, unit)
            spent = np.cumsum(cost[index], axis=1)
            budget = np.linspace(0.0, float(cost.sum()), points)
            done = np.stack([np.searchsorted(row, budget, side="right") for row in spent]) - 1  # last start done
            for measure, v in values.items():
                at = np.where(done >= 0, np.take_along_axis(v, np.maximum(done, 0), axis=1),
                              -np.inf if measure == "best_m_f" else 0.0)
                q = np.quantile(at, [0.025, 0.5, 0.975], axis=0, method="inverted_cdf")
                q = np.where(np.isfinite(q), q, np.nan)
                rows.append(pd.DataFrame({"alpha": alpha, "sampler": sampler, "unit": unit, "measure": measure,
                                          "budget": budget, "low": q[0], "median": q[1], "high": q[2]}))
    return pd.concat(rows, ignore_index=True) if rows else pd.DataFrame()
