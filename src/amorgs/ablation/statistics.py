"""Rates and their intervals in the warm-start ablation: Table 6, the capped-time convergence of Fig. 22 and
hyperplane coverage at equal CPU time (paper Sec. V.B.7–8); and (issue 11) statistics that hold at modest n:
:func:`rates` (Wilson intervals, one-sided Fisher exact tests vs uniform and vs nearest_alpha, the β sweep),
Katz intervals of a ratio of rates, and how the reuse arms drew from their pool (:func:`reuse_pools`).  The
costs — the expected running time (aRT) and everything built on it — are :mod:`amorgs.ablation.running_time`.
All pure functions of the cell tables.

Input everywhere: the concatenation of ablation cell tables (columns ``alpha, sampler, converged, m_f,
tau_s, tau_i, tau_f, cpu_s, wall_s, start``).  "Solve time" is the solve's CPU seconds (one thread per
solve, so it equals wall time on an idle core and is robust to a loaded machine); "high quality" means
converged (verified) and m_f ≥ β, the CR3BP family's quality filter (:class:`amorgs.problems.cr3bp.Cr3bpFilter`)
at the β given.

The arms compared against default to the roles of the table of arms (:mod:`amorgs.ablation.arms`):
``baseline`` its baseline (uniform multi-start), ``reuse`` its reuse arm (nearest_alpha) and the time cap's
``reference`` its headline arm (AmorGS).

The capped study is computed post hoc from the uncapped solves: IPOPT is deterministic, so a solve that
converged within time c also converges under a cap c, and a capped solve costs min(t, c).
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from amorgs.ablation.arms import BASELINE_ARM, HEADLINE_ARM, REUSE_ARM
from amorgs.problems.cr3bp import Cr3bpFilter


def high_quality(df: pd.DataFrame, beta_kg: float) -> pd.Series:
    """Per row: converged and m_f ≥ β (``beta_kg``, kg) — :class:`~amorgs.problems.cr3bp.Cr3bpFilter`'s mask."""
    return Cr3bpFilter(min_final_mass_kg=beta_kg).mask(df)


def wilson_interval(k: int, n: int, z: float = 1.96) -> tuple[float, float]:
    """95% Wilson score interval for a proportion k/n (in percent)."""
    if n == 0:
        return (math.nan, math.nan)
    p = k / n
    d = 1 + z * z / n
    c = (p + z * z / (2 * n)) / d
    h = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / d
    return (100 * (c - h), 100 * (c + h))


def table6(df: pd.DataFrame, beta_kg: float) -> pd.DataFrame:
    """Per (α, sampler): % of starts converging into the high-quality set (with 95% CI) and the mean,
    minimum, 25% and median solve time (s) of those solves."""
    rows = []
    for (alpha, sampler), g in df.groupby(["alpha", "sampler"], sort=True):
        hq = g[high_quality(g, beta_kg)]
        lo, hi = wilson_interval(len(hq), len(g))
        t = hq["cpu_s"]
        rows.append(
            {
                "alpha": alpha,
                "sampler": sampler,
                "n": len(g),
                "percent_high_quality": 100 * len(hq) / len(g),
                "ci95_low": lo,
                "ci95_high": hi,
                "percent_converged": 100 * g["converged"].mean(),
                "time_mean_s": t.mean() if len(t) else math.nan,
                "time_min_s": t.min() if len(t) else math.nan,
                "time_q25_s": t.quantile(0.25) if len(t) else math.nan,
                "time_median_s": t.median() if len(t) else math.nan,
            }
        )
    return pd.DataFrame(rows)


def time_cap(df: pd.DataFrame, beta_kg: float, reference: str = HEADLINE_ARM) -> float:
    """The paper's per-solve cap (CPU s): the median solve time of the reference sampler's high-quality solves
    (default: the headline arm of :mod:`amorgs.ablation.arms`)."""
    ref = df[(df["sampler"] == reference) & high_quality(df, beta_kg)]
    if ref.empty:
        return math.nan
    return float(ref["cpu_s"].median())


def _rate(hq: np.ndarray, t: np.ndarray, cap: float) -> float:
    """High-quality solutions found per CPU-second when every solve is capped at ``cap`` seconds."""
    found = (hq & (t <= cap)).sum()
    return found / np.minimum(t, cap).sum()


def capped_study(
    df: pd.DataFrame,
    beta_kg: float,
    cap_s: float | None = None,
    reference: str = HEADLINE_ARM,
    baseline: str = BASELINE_ARM,
    n_boot: int = 2000,
    seed: int = 0,
) -> tuple[pd.DataFrame, dict]:
    """Fig. 22 and the headline number for ONE α.

    Returns a table per sampler (% converging into the HQ set within the cap with its 95 % Wilson interval,
    HQ found per CPU-hour) and a dict with the cap and the search acceleration (reference ÷ baseline HQ per
    CPU-second) with a bootstrap 95% interval (rows resampled within each sampler).
    """
    if df["alpha"].nunique() != 1:
        raise ValueError("capped_study takes the cells of one α")
    cap = time_cap(df, beta_kg, reference) if cap_s is None else float(cap_s)
    t_all = df["cpu_s"].fillna(np.inf).to_numpy()
    hq_all = high_quality(df, beta_kg).to_numpy()
    rows = []
    for sampler, idx in df.groupby("sampler").indices.items():
        hq, t = hq_all[idx], t_all[idx]
        capped_t = np.minimum(t, cap) if math.isfinite(cap) else t
        k = int((hq & (t <= cap)).sum()) if math.isfinite(cap) else 0
        lo, hi = wilson_interval(k, len(idx)) if math.isfinite(cap) else (math.nan, math.nan)
        rows.append(
            {
                "sampler": sampler,
                "n": len(idx),
                "cap_s": cap,
                "k_within_cap": k,
                "percent_within_cap": 100 * k / len(idx) if math.isfinite(cap) else math.nan,
                "ci95_low": lo,
                "ci95_high": hi,
                "hq_per_cpu_hour": 3600 * _rate(hq, t, cap) if math.isfinite(cap) else math.nan,
                "cpu_s_total": float(capped_t[np.isfinite(capped_t)].sum()),
            }
        )
    out = pd.DataFrame(rows)
    result = {"cap_s": cap, "acceleration": math.nan, "acceleration_ci95": (math.nan, math.nan)}
    groups = df.groupby("sampler").indices
    if math.isfinite(cap) and reference in groups and baseline in groups:
        r_idx, b_idx = groups[reference], groups[baseline]
        base = _rate(hq_all[b_idx], t_all[b_idx], cap)
        result["acceleration"] = _rate(hq_all[r_idx], t_all[r_idx], cap) / base if base > 0 else math.inf
        rng = np.random.default_rng(seed)
        boots = []
        for _ in range(n_boot):
            rr = rng.choice(r_idx, len(r_idx))
            bb = rng.choice(b_idx, len(b_idx))
            r, b = _rate(hq_all[rr], t_all[rr], cap), _rate(hq_all[bb], t_all[bb], cap)
            if b > 0 or r > 0:  # 0/0 resamples carry no information about the ratio
                boots.append(r / b if b > 0 else np.inf)
        if boots:
            q = np.quantile(boots, [0.025, 0.975], method="inverted_cdf")
            result["acceleration_ci95"] = (float(q[0]), float(q[1]))
    return out, result


def hyperplane_coverage(df: pd.DataFrame, beta_kg: float, modes: np.ndarray, delta: float = 0.25) -> pd.DataFrame:
    """Distinct ground-truth hyperplanes (TOF modes) reached by each sampler's HQ solutions at equal CPU.

    The CPU budget is the smallest total solve time over the samplers; each sampler's solves are taken in
    start order until that budget is spent.  A solution reaches the mode T if |TOF − T| ≤ δ.
    """
    modes = np.asarray(modes, float)
    budgets = df.groupby("sampler")["cpu_s"].sum()
    budget = float(budgets.min()) if len(budgets) else 0.0
    rows = []
    for sampler, g in df.sort_values("start").groupby("sampler"):
        spent = g["cpu_s"].fillna(0).cumsum()
        within = g[(spent <= budget) & high_quality(g, beta_kg)]
        tof = (within["tau_s"] + within["tau_i"] + within["tau_f"]).to_numpy()
        reached = set()
        if modes.size and tof.size:
            dist = np.abs(tof[:, None] - modes[None, :])
            nearest = dist.argmin(axis=1)
            reached = set(nearest[dist[np.arange(len(tof)), nearest] <= delta].tolist())
        rows.append({"sampler": sampler, "cpu_budget_s": budget, "hq_solutions": len(within),
                     "hyperplanes_reached": len(reached), "hyperplanes_total": int(modes.size)})
    return pd.DataFrame(rows)


# ----------------------------------------------------------------------------------------------------
# Statistics that hold at modest n (issue 11): rates with Wilson intervals and Fisher exact tests, a
# β sweep, COCO-style expected running time with bootstrap speed-ups, an iteration cap fixed before the
# scored solves, and anytime curves.  Rows are ordered by (model_seed, start) where order matters.
# ----------------------------------------------------------------------------------------------------


def fisher_greater(k1: int, n1: int, k2: int, n2: int) -> float:
    """One-sided Fisher exact p-value for "rate 1 (k1/n1) is higher than rate 2 (k2/n2)"."""
    from scipy.stats import fisher_exact

    if n1 == 0 or n2 == 0:
        return math.nan
    return float(fisher_exact([[k1, n1 - k1], [k2, n2 - k2]], alternative="greater").pvalue)


def rates(df: pd.DataFrame, betas, references: tuple[str, ...] = (BASELINE_ARM, REUSE_ARM)) -> pd.DataFrame:
    """Per (α, sampler, β): high-quality count k of n starts, rate (%), 95 % Wilson interval, and the one-sided
    Fisher exact p-values of "this arm's rate is higher than the reference's" (``p_gt_<reference>``) and
    "… lower than the reference's" (``p_lt_<reference>``) for each reference present (NaN for the reference
    itself).  With one β this is the rate table; with several, the β sweep."""
    rows = []
    for alpha, ga in df.groupby("alpha", sort=True):
        for beta in betas:
            hq = high_quality(ga, float(beta))
            k = hq.groupby(ga["sampler"]).sum().astype(int)
            n = ga.groupby("sampler").size()
            for sampler in n.index:
                lo, hi = wilson_interval(int(k[sampler]), int(n[sampler]))
                row = {"alpha": alpha, "sampler": sampler, "beta_kg": float(beta), "n": int(n[sampler]),
                       "k_high_quality": int(k[sampler]), "percent": 100 * k[sampler] / n[sampler],
                       "ci95_low": lo, "ci95_high": hi}
                mine = (int(k[sampler]), int(n[sampler]))
                for ref in references:
                    if ref not in n.index or ref == sampler:
                        row[f"p_gt_{ref}"] = row[f"p_lt_{ref}"] = math.nan
                        continue
                    theirs = (int(k[ref]), int(n[ref]))
                    row[f"p_gt_{ref}"] = fisher_greater(*mine, *theirs)
                    row[f"p_lt_{ref}"] = fisher_greater(*theirs, *mine)
                rows.append(row)
    return pd.DataFrame(rows)


def reuse_pools(df: pd.DataFrame) -> pd.DataFrame:
    """How the reuse arms drew their guesses (:class:`~amorgs.models.samplers.NearestAlphaSampler`): per
    (α, sampler) with a ``reuse_pool_size`` column, the training α reused (``reuse_alpha``), its pool of
    high-quality rows (``pool_size``), the starts ``n`` pooled over the ``cells`` (one per model seed: slices
    of one seeded draw, ``start`` numbering the draw), how many of them were drawn without replacement
    (start < pool size: each a pool row not drawn before) and with replacement after the pool ran out, and
    ``draw`` in words — the draw every other table of the report counts.  Empty without reuse cells."""
    if "reuse_pool_size" not in df.columns or df["reuse_pool_size"].isna().all():
        return pd.DataFrame()
    rows = []
    for (alpha, sampler), g in df[df["reuse_pool_size"].notna()].groupby(["alpha", "sampler"], sort=True):
        pool, n = int(g["reuse_pool_size"].iloc[0]), len(g)
        fresh = int((g["start"] < pool).sum())
        draw = ("without replacement" if fresh == n else
                f"without replacement for the first {pool} starts (the whole pool), then with replacement")
        rows.append({"alpha": alpha, "sampler": sampler, "reuse_alpha": float(g["reuse_alpha"].iloc[0]),
                     "pool_size": pool, "n": n,
                     "cells": g["model_seed"].nunique() if "model_seed" in g.columns else 1,
                     "starts_without_replacement": fresh, "starts_with_replacement": n - fresh, "draw": draw})
    return pd.DataFrame(rows)


def ratio_of_rates_interval(k1: int, n1: int, k2: int, n2: int, z: float = 1.96) -> tuple[float, float]:
    """95 % Katz log interval of the ratio of two proportions (k1/n1) ÷ (k2/n2); NaN when either k is 0."""
    if min(k1, k2) == 0 or min(n1, n2) == 0:
        return (math.nan, math.nan)
    ratio = (k1 / n1) / (k2 / n2)
    half = z * math.sqrt(1 / k1 - 1 / n1 + 1 / k2 - 1 / n2)
    return (ratio * math.exp(-half), ratio * math.exp(half))


