"""Figures of the warm-start ablation (paper Figs. 21–23): data in, matplotlib Figure out, no file IO."""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
import pandas as pd
from matplotlib.figure import Figure
from scipy.stats import gaussian_kde

from amorgs.ablation.statistics import high_quality
from amorgs.models.samplers import SAMPLER_LABELS, SAMPLER_NAMES


def _samplers(df: pd.DataFrame) -> list[str]:
    present = set(df["sampler"])
    return [s for s in SAMPLER_NAMES if s in present] + sorted(present - set(SAMPLER_NAMES))


def fig21_solve_time_histograms(df: pd.DataFrame, beta_kg: float) -> Figure:
    """Histogram + KDE of the solve time (CPU s) of high-quality solves, per α (rows) and sampler (cols)."""
    alphas = sorted(df["alpha"].unique())
    samplers = _samplers(df)
    fig, axes = plt.subplots(len(alphas), len(samplers), figsize=(3.2 * len(samplers), 2.6 * len(alphas)),
                             squeeze=False, sharex="row")
    for i, alpha in enumerate(alphas):
        for j, sampler in enumerate(samplers):
            ax = axes[i, j]
            g = df[(df["alpha"] == alpha) & (df["sampler"] == sampler)]
            t = g.loc[high_quality(g, beta_kg), "cpu_s"].to_numpy()
            if t.size:
                ax.hist(t, bins=min(20, max(5, t.size // 2)), density=True, alpha=0.5, color=f"C{j}")
                if t.size >= 3 and np.ptp(t) > 0:
                    grid = np.linspace(0, t.max() * 1.1, 200)
                    ax.plot(grid, gaussian_kde(t)(grid), color=f"C{j}")
            else:
                ax.text(0.5, 0.5, "no high-quality solve", ha="center", va="center", transform=ax.transAxes)
            ax.set_title(f"{SAMPLER_LABELS.get(sampler, sampler)}\nα = {alpha:g}, n_HQ = {t.size}/{len(g)}", fontsize=8)
            ax.set_xlabel("solve time (CPU s)")
    fig.suptitle(f"Fig. 21 — solve time of starts converging into A(α, β = {beta_kg:g} kg)")
    fig.tight_layout()
    return fig


def fig22_capped_convergence(capped: dict[float, pd.DataFrame]) -> Figure:
    """% of starts converging into the high-quality set within the per-solve cap, per sampler and α."""
    fig, axes = plt.subplots(1, len(capped), figsize=(5 * len(capped), 3.8), squeeze=False)
    for ax, (alpha, table) in zip(axes[0], sorted(capped.items())):
        order = [s for s in _samplers(table)]
        t = table.set_index("sampler").loc[order]
        ax.bar(range(len(t)), t["percent_within_cap"], color=[f"C{i}" for i in range(len(t))])
        ax.set_xticks(range(len(t)), [SAMPLER_LABELS.get(s, s) for s in t.index], rotation=30, ha="right", fontsize=8)
        ax.set_ylabel("% converged within cap")
        ax.set_title(f"α = {alpha:g}, cap = {t['cap_s'].iloc[0]:.1f} CPU s, n = {int(t['n'].iloc[0])}")
    fig.suptitle("Fig. 22 — convergence under a per-solve time cap (AmorGS median solve time)")
    fig.tight_layout()
    return fig


def fig23_amorgs_diversity(ablation: pd.DataFrame, ground_truth: pd.DataFrame, beta_kg: float,
                           sampler: str = "amorgs") -> Figure:
    """Per test α: the sampler's guesses, their high-quality solutions, and the ground-truth HQ set,
    in (τ_s, TOF) coordinates coloured by m_f."""
    alphas = sorted(ablation["alpha"].unique())
    fig, axes = plt.subplots(len(alphas), 3, figsize=(13, 3.6 * len(alphas)), squeeze=False, sharey="row")
    for i, alpha in enumerate(alphas):
        g = ablation[(ablation["alpha"] == alpha) & (ablation["sampler"] == sampler)]
        sol = g[high_quality(g, beta_kg)]
        gt = ground_truth[np.isclose(ground_truth["alpha"], alpha)]
        panels = [
            ("samples", g["guess_tau_s"], g["guess_tau_s"] + g["guess_tau_i"] + g["guess_tau_f"], g["guess_m_f"]),
            ("solved (high quality)", sol["tau_s"], sol["tau_s"] + sol["tau_i"] + sol["tau_f"], sol["m_f"]),
            ("ground truth A(α, β)", gt["tau_s"], gt["tau_s"] + gt["tau_i"] + gt["tau_f"], gt["m_f"]),
        ]
        for ax, (title, x, y, c) in zip(axes[i], panels):
            if len(x):
                sc = ax.scatter(x, y, c=c, s=8, cmap="viridis")
                fig.colorbar(sc, ax=ax, label="m_f (kg)")
            else:
                ax.text(0.5, 0.5, "none", ha="center", va="center", transform=ax.transAxes)
            ax.set_title(f"α = {alpha:g}: {title} (n = {len(x)})", fontsize=9)
            ax.set_xlabel("τ_s (TU)")
        axes[i, 0].set_ylabel("TOF (TU)")
    fig.suptitle(f"Fig. 23 — {SAMPLER_LABELS.get(sampler, sampler)} samples, their solutions and the ground truth")
    fig.tight_layout()
    return fig
