"""The quality report of a filtered solution table.

What "high quality" means belongs to each problem family: its quality filter
(:class:`~amorgs.problems.base.QualityFilter`: :class:`~amorgs.problems.cr3bp.Cr3bpFilter`, m_f ≥ β kg;
:class:`~amorgs.problems.dejong.DejongFilter`, J ≤ a bound), which the workflow's filter step and
``amorgs design`` apply.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd


def _stats(values: pd.Series, prefix: str) -> dict[str, float]:
    v = values.dropna().to_numpy(dtype=float)
    if v.size == 0:
        return {f"{prefix}_{k}": math.nan for k in ("min", "median", "p90", "max")}
    return {
        f"{prefix}_min": float(v.min()),
        f"{prefix}_median": float(np.median(v)),
        f"{prefix}_p90": float(np.quantile(v, 0.9)),
        f"{prefix}_max": float(v.max()),
    }


def quality_report(df: pd.DataFrame, hq: pd.DataFrame, thresholds: dict[str, float | None]) -> dict:
    """Per-α convergence and quality summary of all solves ``df`` and the filtered ``hq``.

    Per α: solve count, converged count and fraction, high-quality count and fraction, the objective over
    converged solves (min/median/p90/max) and, where the table has ``m_f`` (CR3BP, kg), the final mass over
    converged solves — ``m_f_max`` is the best.  Iterations and wall seconds are medians over converged solves.
    """
    per_alpha = []
    for alpha, group in df.groupby("alpha", sort=True):
        conv = group[group["converged"].astype(bool)]
        n_hq = int((hq["alpha"] == alpha).sum())
        entry = {
            "alpha": float(alpha),
            "n": int(len(group)),
            "converged": int(len(conv)),
            "converged_fraction": len(conv) / len(group),
            "high_quality": n_hq,
            "high_quality_fraction": n_hq / len(group),
            **_stats(conv["objective"], "objective"),
            "iterations_median": float(conv["iterations"].median()) if len(conv) else math.nan,
            "wall_s_median": float(conv["wall_s"].median()) if len(conv) else math.nan,
        }
        if "m_f" in df.columns:
            entry.update(_stats(conv["m_f"], "m_f"))
        per_alpha.append(entry)
    return {
        "thresholds": thresholds,
        "n": int(len(df)),
        "converged": int(df["converged"].astype(bool).sum()),
        "high_quality": int(len(hq)),
        "per_alpha": per_alpha,
    }
