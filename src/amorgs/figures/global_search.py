"""The runtime-ECDF figure of a global-search study (issue 41), in the COCO benchmarking platform's display:
for each (strategy, sampler), the fraction of (search, target δ) pairs reached against the IPOPT iterations spent.
Data in (the table of :func:`amorgs.ablation.global_search.runtime_ecdf`), matplotlib Figure out."""

from __future__ import annotations

import numpy as np
import pandas as pd
from matplotlib.figure import Figure

from amorgs.ablation.arms import arm_label


#: Line style and label per strategy.
STYLES = {"multistart": "--", "mbh": "-", "mbh_warm": ":"}
LABELS = {"multistart": "multi-start", "mbh": "MBH", "mbh_warm": "MBH, warm hops"}


def fig_runtime_ecdf(ecdf: pd.DataFrame, cells: pd.DataFrame, best_m_f: dict[float, float], deltas,
                     budget: int) -> Figure:
    """One panel per α of ``best_m_f`` (α → best known m_f, kg), one step curve per (strategy, sampler) of
    ``cells`` (columns alpha, strategy, sampler; a cell with no hit is drawn flat at 0): solid for basin hopping,
    dotted for basin hopping with warm hops, dashed for multi-start, one colour per sampler; x logarithmic to the budget (IPOPT iterations) or the latest
    hit beyond it."""
    alphas = sorted(best_m_f)
    fig = Figure(figsize=(7.5, 4.4 * len(alphas)), layout="constrained")
    axes = np.atleast_1d(fig.subplots(len(alphas), 1, squeeze=False).ravel())
    targets = ", ".join(f"{d:g}" for d in deltas)
    # A search's last solve may cross its budget: the axis ends at the latest hit or the budget.
    right = max([float(budget), *ecdf["iterations"].astype(float)]) * 1.05
    for ax, alpha in zip(axes, alphas):
        here = cells[cells["alpha"] == alpha][["strategy", "sampler"]].drop_duplicates()
        colours = {name: f"C{k % 10}" for k, name in enumerate(dict.fromkeys(here["sampler"]))}
        for strategy, sampler in here.itertuples(index=False):
            mine = ecdf[(ecdf["alpha"] == alpha) & (ecdf["strategy"] == strategy) & (ecdf["sampler"] == sampler)]
            mine = mine.sort_values("iterations")
            x = np.r_[1.0, mine["iterations"].to_numpy(float), right]
            y = np.r_[0.0, mine["fraction"].to_numpy(float), mine["fraction"].iloc[-1] if len(mine) else 0.0]
            ax.step(x, y, where="post", color=colours[sampler], linestyle=STYLES.get(strategy, "-."),
                    label=f"{LABELS.get(strategy, strategy)} · {arm_label(sampler)}")
        ax.set_xscale("log")
        ax.set_xlim(10, right)
        ax.set_ylim(0, 1)
        ax.set_xlabel("IPOPT iterations (cumulative, per search)")
        ax.set_ylabel("fraction of (search, δ) pairs reached")
        ax.set_title(f"α = {alpha:g} N: runtime to within δ ∈ {{{targets}}} kg of the best known m_f = "
                     f"{best_m_f[alpha]:.2f} kg", fontsize=10)
        ax.legend(fontsize=8, loc="upper left")
        ax.grid(alpha=0.3, which="both")
    return fig
