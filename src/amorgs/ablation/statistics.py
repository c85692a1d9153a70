"""Statistics of the warm-start ablation: Table 6, the capped-time convergence of Fig. 22, the search
acceleration with a bootstrap interval, and hyperplane coverage at equal CPU time (paper Sec. V.B.7–8).

Input everywhere: the concatenation of ablation cell tables (columns ``alpha, sampler, converged, m_f,
tau_s, tau_i, tau_f, cpu_s, wall_s, start``).  "Solve time" is the solve's CPU seconds (one thread per
solve, so it equals wall time on an idle core and is robust to a loaded machine); "high quality" means
converged (verified) and m_f ≥ β.

The capped study is computed post hoc from the uncapped solves: IPOPT is deterministic, so a solve that
converged within time c also converges under a cap c, and a capped solve costs min(t, c).
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd


def high_quality(df: pd.DataFrame, beta_kg: float) -> pd.Series:
    """Converged and m_f ≥ β."""
    return df["converged"].astype(bool) & (df["m_f"] >= beta_kg)


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


def time_cap(df: pd.DataFrame, beta_kg: float, reference: str = "amorgs") -> float:
    """The paper's per-solve cap: the median solve time of the reference sampler's high-quality solves."""
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
    reference: str = "amorgs",
    baseline: str = "uniform",
    n_boot: int = 2000,
    seed: int = 0,
) -> tuple[pd.DataFrame, dict]:
    """Fig. 22 and the headline number for ONE α.

    Returns a table per sampler (% converging into the HQ set within the cap, HQ found per CPU-hour) and a
    dict with the cap and the search acceleration (reference ÷ baseline HQ per CPU-second) with a
    bootstrap 95% interval (rows resampled within each sampler).
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
        rows.append(
            {
                "sampler": sampler,
                "n": len(idx),
                "cap_s": cap,
                "percent_within_cap": 100 * float((hq & (t <= cap)).mean()) if math.isfinite(cap) else math.nan,
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
