"""Figures of the warm-start ablation (paper Figs. 21–23 and the issue-11 measures): data in, matplotlib Figure
out — object API (no pyplot state, no backend), no file IO, no statistics beyond drawing a density.

The data come from :func:`amorgs.ablation.report.summarize` (an :class:`~amorgs.ablation.summary.AblationSummary`):
``solves`` are the cell tables with a boolean ``high_quality`` column (converged and m_f ≥ β), the other tables
are its statistics.  Times in CPU seconds, masses in kg, times of flight in TU.  :func:`ablation_figures` draws
them all.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
from matplotlib.figure import Figure
from scipy.stats import gaussian_kde

from amorgs.ablation.arms import BASELINE_ARM, HEADLINE_ARM, REUSE_ARM, SAMPLER_NAMES, arm_label
from amorgs.ablation.summary import AblationSummary
from amorgs.alphas import distinct_alphas, rows_at, rows_at_any


def _samplers(df: pd.DataFrame) -> list[str]:
    present = set(df["sampler"])
    return [s for s in SAMPLER_NAMES if s in present] + sorted(present - set(SAMPLER_NAMES))


def fig21_solve_time_histograms(solves: pd.DataFrame, beta_kg: float) -> Figure:
    """Histogram + KDE of the solve time (CPU s) of high-quality solves, per α (rows) and sampler (cols).

    ``solves``: cell rows with ``alpha``, ``sampler``, ``cpu_s`` and the boolean ``high_quality``; ``beta_kg``
    (kg) only labels the figure."""
    alphas = distinct_alphas(solves["alpha"])
    samplers = _samplers(solves)
    fig = Figure(figsize=(3.2 * len(samplers), 2.6 * len(alphas)), layout="tight")
    axes = fig.subplots(len(alphas), len(samplers), squeeze=False, sharex="row")
    for i, alpha in enumerate(alphas):
        this_alpha = rows_at(solves, alpha)
        for j, sampler in enumerate(samplers):
            ax = axes[i, j]
            g = this_alpha[this_alpha["sampler"] == sampler]
            t = g.loc[g["high_quality"].astype(bool), "cpu_s"].to_numpy()
            if t.size:
                ax.hist(t, bins=min(20, max(5, t.size // 2)), density=True, alpha=0.5, color=f"C{j}")
                if t.size >= 3 and np.ptp(t) > 0:
                    grid = np.linspace(0, t.max() * 1.1, 200)
                    ax.plot(grid, gaussian_kde(t)(grid), color=f"C{j}")
            else:
                ax.text(0.5, 0.5, "no high-quality solve", ha="center", va="center", transform=ax.transAxes)
            ax.set_title(f"{arm_label(sampler)}\nα = {alpha:g}, n_HQ = {t.size}/{len(g)}",
                         fontsize=8)
            ax.set_xlabel("solve time (CPU s)")
            ax.set_ylabel("probability density (1/CPU s)", fontsize=8)
    fig.suptitle(f"Fig. 21 — solve time of starts converging into A(α, β = {beta_kg:g} kg): histogram and KDE")
    return fig


def fig22_capped_convergence(capped: pd.DataFrame) -> Figure:
    """High-quality rate within the per-solve cap: % of starts converging into A(α, β) (verified and m_f ≥ β)
    within the cap, with its 95 % Wilson interval, per sampler and α.

    ``capped``: the capped study (:func:`amorgs.ablation.statistics.capped_study`) of every α, column ``alpha``."""
    alphas = distinct_alphas(capped["alpha"]) if len(capped) else []
    fig = Figure(figsize=(5 * max(len(alphas), 1), 3.8), layout="tight")
    axes = fig.subplots(1, max(len(alphas), 1), squeeze=False)
    if not alphas:
        axes[0, 0].text(0.5, 0.5, "no ablation cells", ha="center", va="center", transform=axes[0, 0].transAxes)
    for ax, alpha in zip(axes[0], alphas):
        table = rows_at(capped, alpha)
        order = _samplers(table)
        t = table.set_index("sampler").loc[order]
        y = t["percent_within_cap"].to_numpy(dtype=float)
        ax.bar(range(len(t)), y, color=[f"C{i}" for i in range(len(t))], alpha=0.8)
        ax.errorbar(range(len(t)), y, yerr=[y - t["ci95_low"].to_numpy(float), t["ci95_high"].to_numpy(float) - y],
                    fmt="none", ecolor="k", capsize=3, lw=1)
        ax.set_xticks(range(len(t)), [arm_label(s) for s in t.index], rotation=30, ha="right", fontsize=8)
        ax.set_ylabel("high-quality rate within cap (%)\n(converged and m_f ≥ β; Wilson 95 %)", fontsize=8)
        ax.set_ylim(0, 100)
        ax.set_title(f"α = {alpha:g}, cap = {t['cap_s'].iloc[0]:.1f} CPU s, n = {int(t['n'].iloc[0])}")
    fig.suptitle(f"Fig. 22 — high-quality rate under a per-solve time cap "
                 f"({arm_label(HEADLINE_ARM)} median solve time)")
    return fig


def fig23_amorgs_diversity(solves: pd.DataFrame, ground_truth: pd.DataFrame, beta_kg: float,
                           sampler: str = HEADLINE_ARM) -> Figure:
    """Per test α: the sampler's guesses, their high-quality solutions, and the ground-truth HQ set,
    in (τ_s, TOF) coordinates (TU) coloured by m_f (kg) on ONE colour range shared by every panel: that of
    the high-quality solutions and the ground truth (guesses outside it saturate, the colour bar says so).

    ``solves``: cell rows with ``guess_*`` and solution columns and the boolean ``high_quality``;
    ``ground_truth``: the high-quality solution set (rows at other α are ignored); ``beta_kg`` labels panels."""
    from matplotlib.cm import ScalarMappable
    from matplotlib.colors import Normalize

    alphas = distinct_alphas(solves["alpha"])
    fig = Figure(figsize=(13, 3.6 * len(alphas)), layout="constrained")
    axes = fig.subplots(len(alphas), 3, squeeze=False, sharey="row")
    mine = solves[(solves["sampler"] == sampler) & solves["high_quality"].astype(bool)]["m_f"]
    truth = rows_at_any(ground_truth, alphas)["m_f"] if alphas else pd.Series(dtype=float)
    masses = pd.concat([mine, truth]).to_numpy(dtype=float)
    masses = masses[np.isfinite(masses)]
    norm = Normalize(*(masses.min(), masses.max()) if masses.size else (beta_kg, beta_kg + 1.0))
    for i, alpha in enumerate(alphas):
        this_alpha = rows_at(solves, alpha)
        g = this_alpha[this_alpha["sampler"] == sampler]
        sol = g[g["high_quality"].astype(bool)]
        gt = rows_at(ground_truth, alpha)
        panels = [
            ("samples", g["guess_tau_s"], g["guess_tau_s"] + g["guess_tau_i"] + g["guess_tau_f"], g["guess_m_f"]),
            ("solved (high quality)", sol["tau_s"], sol["tau_s"] + sol["tau_i"] + sol["tau_f"], sol["m_f"]),
            (f"ground truth A(α, β = {beta_kg:g} kg)", gt["tau_s"], gt["tau_s"] + gt["tau_i"] + gt["tau_f"],
             gt["m_f"]),
        ]
        for ax, (title, x, y, c) in zip(axes[i], panels):
            if len(x):
                ax.scatter(x, y, c=c, s=8, cmap="viridis", norm=norm)
            else:
                ax.text(0.5, 0.5, "none", ha="center", va="center", transform=ax.transAxes)
            ax.set_title(f"α = {alpha:g}: {title} (n = {len(x)})", fontsize=9)
            ax.set_xlabel("τ_s (TU)")
        axes[i, 0].set_ylabel("TOF (TU)")
    fig.colorbar(ScalarMappable(norm=norm, cmap="viridis"), ax=axes.ravel().tolist(), extend="both",
                 label="m_f (kg), one range for every panel")
    fig.suptitle(f"Fig. 23 — {arm_label(sampler)} samples, their solutions and the ground truth")
    return fig


# ------------------------------------------------------------------------- issue 11: new arms, new measures


#: Colours of the arms past the default cycle's ten (C0–C9), so that no two arms share one.
_MORE_COLOURS = ("indigo", "teal", "goldenrod", "navy")


def _colour(s: str) -> str:
    if s not in SAMPLER_NAMES:
        return "k"
    i = SAMPLER_NAMES.index(s)
    return f"C{i}" if i < 10 else _MORE_COLOURS[(i - 10) % len(_MORE_COLOURS)]


#: Rows of the speed-up figure: (aRT table: ``ert`` per high-quality solution or ``ert_distinct`` per new
#: η-distinct optimum, column of it, unit, what the ratio is against).
SPEEDUP_ROWS = (("ert", "speedup", "iterations", BASELINE_ARM), ("ert", "versus_reuse", "iterations", REUSE_ARM),
                ("ert_distinct", "versus_reuse", "iterations", REUSE_ARM), ("ert", "speedup", "cpu_s", BASELINE_ARM))
_PER = {"ert": ("HQ", "k_high_quality", "per high-quality solution"),
        "ert_distinct": ("distinct", "k_distinct", "per new η-distinct optimum")}


def _ratio_panel(ax, t: pd.DataFrame, column: str, found: str, tag: str) -> None:
    """Bars of ``column`` (a ratio of aRTs) per sampler of ``t`` with its bootstrap interval; log scale, ∞ drawn
    at the top; each bar says what the arm found (column ``found``, labelled ``tag``)."""
    order = _samplers(t.reset_index())
    finite = t[column].replace([np.inf, -np.inf], np.nan)
    top = float(np.nanmax([finite.max(), t[f"{column}_ci95_high"].replace(np.inf, np.nan).max(), 1.0]) * 2)
    for x, s in enumerate(order):
        v = t.loc[s, column]
        lo, hi = t.loc[s, f"{column}_ci95_low"], t.loc[s, f"{column}_ci95_high"]
        y = top if np.isinf(v) else v
        if np.isfinite(y) and y > 0:
            ax.bar(x, y, color=_colour(s), alpha=0.7)
        if np.isfinite(lo) and lo > 0:
            ax.plot([x, x], [lo, top if np.isinf(hi) else hi], color="k", lw=1.2)
        ax.text(x, y if np.isfinite(y) and y > 0 else 1, f"n_{tag}={int(t.loc[s, found])}",
                ha="center", va="bottom", fontsize=7)
    ax.axhline(1.0, color="grey", ls="--", lw=0.8)
    ax.set_yscale("log")
    ax.set_xticks(range(len(order)), [arm_label(s) for s in order], rotation=35, ha="right", fontsize=7)


def ablation_speedups(ert: pd.DataFrame, ert_distinct: pd.DataFrame) -> Figure:
    """aRT ratios with bootstrap 95 % intervals, per α (columns); rows: against uniform in iterations, against
    nearest-α reuse in iterations per high-quality solution and per new η-distinct optimum (Eq. 12; when the
    reuse arm ran; above 1 the arm beats reuse), against uniform in CPU s."""
    tables = {"ert": ert, "ert_distinct": ert_distinct}
    alphas = distinct_alphas(ert["alpha"])
    rows = [(name, c, u, who) for name, c, u, who in SPEEDUP_ROWS
            if len(tab := tables[name]) and u in set(tab["unit"]) and c in tab.columns
            and tab.loc[tab["unit"] == u, c].notna().any()]
    fig = Figure(figsize=(5 * len(alphas), 3.6 * len(rows)), layout="tight")
    axes = fig.subplots(len(rows), len(alphas), squeeze=False)
    for i, (name, column, unit, who) in enumerate(rows):
        tag, found, per = _PER[name]
        for j, alpha in enumerate(alphas):
            this_alpha = rows_at(tables[name], alpha)
            t = this_alpha[this_alpha["unit"] == unit].set_index("sampler")
            _ratio_panel(axes[i, j], t, column, found, tag)
            axes[i, j].set_ylabel(f"aRT({arm_label(who)}) ÷ aRT(arm), {per}\n"
                                  f"({'IPOPT iterations' if unit == 'iterations' else 'CPU s'})", fontsize=8)
            axes[i, j].set_title(f"α = {alpha:g}, n = {int(t['n'].max())} starts per arm", fontsize=9)
    fig.suptitle("Expected running time as ratios: above 1 the arm is faster (bootstrap 95 % CI)")
    return fig


def fig22_iteration_capped(capped: pd.DataFrame) -> Figure:
    """Fig. 22 done with a fixed iteration cap: per α (columns), as a function of the cap, the high-quality
    rate within the cap (Wilson 95 %, top), the paper's ratio of percentages (Katz 95 %, middle) and the
    throughput ratio (bootstrap 95 %, bottom), arm ÷ uniform; intervals as vertical bars (the arms side by
    side), an unbounded upper end as a bar to the panel's top with an arrow head."""
    if capped.empty:
        fig = Figure(figsize=(5, 3))
        ax = fig.subplots()
        ax.text(0.5, 0.5, "no iteration caps configured (ablation.iteration_caps)", ha="center", va="center")
        ax.set_axis_off()
        return fig
    alphas = distinct_alphas(capped["alpha"])
    fig = Figure(figsize=(5 * len(alphas), 10), layout="tight")
    axes = fig.subplots(3, len(alphas), squeeze=False, sharex=True)
    panels = (("percent_within_cap", "ci95_low", "ci95_high", "high-quality rate within cap (%)\n(Wilson 95 %)"),
              ("percent_ratio", "percent_ratio_ci95_low", "percent_ratio_ci95_high",
               f"% within cap ÷ {BASELINE_ARM}'s\n(Katz 95 %)"),
              ("throughput_ratio", "throughput_ratio_ci95_low", "throughput_ratio_ci95_high",
               f"HQ per iteration ÷ {BASELINE_ARM}'s\n(bootstrap 95 %)"))
    for j, alpha in enumerate(alphas):
        t = rows_at(capped, alpha)
        samplers = _samplers(t)
        for ax, (col, lo, hi, _) in zip(axes[:, j], panels):
            columns = [c for c in (col, lo, hi) if c in t]
            finite = t[columns].replace([np.inf, -np.inf], np.nan).to_numpy(dtype=float)
            top = 1.1 * np.nanmax(finite) if np.isfinite(finite).any() else 1.0
            for k, s in enumerate(samplers):
                g = t[t["sampler"] == s].sort_values("cap_iterations")
                y, low, high = (g[c].replace(np.inf, np.nan) if c in g else pd.Series(np.nan, index=g.index)
                                for c in (col, lo, hi))
                x = g["cap_iterations"] * 1.04 ** (k - (len(samplers) - 1) / 2)  # side by side on the log axis
                ax.plot(x, y, "o-", color=_colour(s), label=arm_label(s), ms=3)
                unbounded = np.isinf(g[hi]) if hi in g else pd.Series(False, index=g.index)
                ax.vlines(x, low, high.where(~unbounded, top), color=_colour(s), lw=1.2, alpha=0.7)
                ax.plot(x[unbounded & low.notna()], np.full(int((unbounded & low.notna()).sum()), top), "^",
                        color=_colour(s), ms=4)
        axes[0, j].set_title(f"α = {alpha:g}, n = {int(t['n'].max())} starts per arm", fontsize=9)
        for ax, (*_, label) in zip(axes[:, j], panels):
            ax.set_ylabel(label, fontsize=8)
        axes[-1, j].set_xlabel("iteration cap (fixed before the solves)")
        caps = t["cap_iterations"].to_numpy(dtype=float)
        for i, ax in enumerate(axes[:, j]):
            if i:
                ax.axhline(1.0, color="grey", ls="--", lw=0.8)
            ax.set_xscale("log")
            # explicit limits: with every ratio undefined (no high-quality start) no point is drawn
            ax.set_xlim(caps.min() / 1.3, caps.max() * 1.3)
    axes[0, 0].legend(fontsize=7)
    fig.suptitle("Fig. 22 (iteration cap) — high-quality rate, ratio of percentages and throughput ratio vs the "
                 "cap (∞ not drawn)")
    return fig


#: Panels of the anytime figure: (measure, cost unit, y label).
ANYTIME_PANELS = (("best_m_f", "iterations", "best high-quality m_f (kg)"),
                  ("best_m_f", "cpu_s", "best high-quality m_f (kg)"),
                  ("distinct_optima", "iterations", "new η-distinct HQ optima (Eq. 12)"),
                  ("distinct_optima", "cpu_s", "new η-distinct HQ optima (Eq. 12)"))
_ANYTIME_X = {"iterations": ("iterations_cumulative", "cumulative IPOPT iterations"),
              "cpu_s": ("cpu_s_cumulative", "cumulative CPU s")}


def ablation_anytime(curves: pd.DataFrame, bands: pd.DataFrame) -> Figure:
    """Anytime curves per α (rows): best high-quality m_f and the number of new η-distinct optima, each vs
    cumulative IPOPT iterations and CPU s (columns); the arm's starts in order (steps) with the bootstrap
    95 % band of :func:`amorgs.ablation.running_time.anytime_bands` (shaded)."""
    alphas = distinct_alphas(curves["alpha"])
    fig = Figure(figsize=(19, 3.8 * len(alphas)), layout="tight")
    axes = fig.subplots(len(alphas), len(ANYTIME_PANELS), squeeze=False)
    for i, alpha in enumerate(alphas):
        t, b = rows_at(curves, alpha), rows_at(bands, alpha) if len(bands) else bands
        for s in _samplers(t):
            g = t[t["sampler"] == s]
            for ax, (measure, unit, _) in zip(axes[i], ANYTIME_PANELS):
                x = _ANYTIME_X[unit][0]
                ax.step(g[x], g[measure], color=_colour(s), label=arm_label(s), where="post")
                if len(b):
                    band = b[(b["sampler"] == s) & (b["unit"] == unit) & (b["measure"] == measure)]
                    ax.fill_between(band["budget"], band["low"], band["high"], color=_colour(s), alpha=0.15,
                                    lw=0, step="post")
        for ax, (_, unit, ylabel) in zip(axes[i], ANYTIME_PANELS):
            ax.set_xlabel(_ANYTIME_X[unit][1])
            ax.set_ylabel(ylabel)
            ax.set_title(f"α = {alpha:g}", fontsize=9)
    axes[0, 0].legend(fontsize=7)
    fig.suptitle("Anytime performance of each arm (starts in order; shaded: bootstrap 95 % band)")
    return fig


def ablation_beta_sweep(sweep: pd.DataFrame) -> Figure:
    """High-quality rate (%) vs β with Wilson 95 % intervals, per α (columns) and arm."""
    alphas = distinct_alphas(sweep["alpha"])
    fig = Figure(figsize=(5 * len(alphas), 3.8), layout="tight")
    axes = fig.subplots(1, len(alphas), squeeze=False)
    for ax, alpha in zip(axes[0], alphas):
        t = rows_at(sweep, alpha)
        samplers = _samplers(t)
        for k, s in enumerate(samplers):
            g = t[t["sampler"] == s].sort_values("beta_kg")
            x = g["beta_kg"] + 0.25 * (k - len(samplers) / 2)
            ax.errorbar(x, g["percent"], yerr=[g["percent"] - g["ci95_low"], g["ci95_high"] - g["percent"]],
                        fmt="o-", color=_colour(s), label=arm_label(s), ms=3, capsize=2, lw=1)
        ax.set_xlabel("β (kg)")
        ax.set_ylabel("% of starts into A(α, β)")
        ax.set_title(f"α = {alpha:g}, n = {int(t['n'].max())} starts per arm", fontsize=9)
    axes[0, 0].legend(fontsize=7)
    fig.suptitle("High-quality rate vs the quality threshold β (Wilson 95 % intervals)")
    return fig


def ablation_figures(summary: AblationSummary) -> dict[str, Figure]:
    """Every ablation figure of one report, by name (the names of :data:`amorgs.layout.ABLATION_FIGURES`)."""
    solves, tables, beta_kg = summary.solves, summary.tables, summary.beta_kg
    return {
        "fig21_solve_time_histograms": fig21_solve_time_histograms(solves, beta_kg),
        "fig22_capped_convergence": fig22_capped_convergence(tables["capped"]),
        "fig23_amorgs_diversity": fig23_amorgs_diversity(solves, summary.ground_truth, beta_kg),
        "fig22_iteration_capped": fig22_iteration_capped(tables["iteration_capped"]),
        "ablation_speedups": ablation_speedups(tables["ert"], tables["ert_distinct"]),
        "ablation_beta_sweep": ablation_beta_sweep(tables["beta_sweep"]),
        "ablation_anytime": ablation_anytime(tables["anytime"], tables["anytime_bands"]),
    }
