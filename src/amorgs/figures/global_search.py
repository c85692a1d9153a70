"""The runtime-ECDF figure of a global-search study (issue 41), in the COCO benchmarking platform's display:
for each (strategy, sampler), the fraction of (search, target δ) pairs reached against the IPOPT iterations spent.
Data in (the table of :func:`amorgs.ablation.global_search.runtime_ecdf`), matplotlib Figure out."""

from __future__ import annotations

import numpy as np
import pandas as pd
from matplotlib.figure import Figure

from amorgs.ablation.arms import arm_label


def fig_runtime_ecdf(ecdf: pd.DataFrame, cells: pd.DataFrame, best_m_f: float, deltas, budget: int) -> Figure:
    """One step curve per (strategy, sampler) of ``cells`` (columns strategy, sampler; a cell with no hit is
    drawn flat at 0): solid for basin hopping, dashed for multi-start; x logarithmic up to ``budget``."""
    fig = Figure(figsize=(7.5, 4.6), layout="constrained")
    ax = fig.subplots()
    for k, (strategy, sampler) in enumerate(cells[["strategy", "sampler"]].drop_duplicates().itertuples(index=False)):
        mine = ecdf[(ecdf["strategy"] == strategy) & (ecdf["sampler"] == sampler)].sort_values("iterations")
        x = np.r_[1.0, mine["iterations"].to_numpy(float), budget]
        y = np.r_[0.0, mine["fraction"].to_numpy(float), mine["fraction"].iloc[-1] if len(mine) else 0.0]
        ax.step(x, y, where="post", color=f"C{k % 10}", linestyle="-" if strategy == "mbh" else "--",
                label=f"{'MBH' if strategy == 'mbh' else 'multi-start'} · {arm_label(sampler)}")
    ax.set_xscale("log")
    ax.set_xlim(10, budget)
    ax.set_ylim(0, 1)
    ax.set_xlabel("IPOPT iterations (cumulative, per search)")
    ax.set_ylabel("fraction of (search, δ) pairs reached")
    targets = ", ".join(f"{d:g}" for d in deltas)
    ax.set_title(f"Runtime to within δ ∈ {{{targets}}} kg of the best known m_f = {best_m_f:.2f} kg", fontsize=10)
    ax.legend(fontsize=8, loc="upper left")
    ax.grid(alpha=0.3, which="both")
    return fig
