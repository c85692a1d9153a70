"""Everything the ablation report needs from the cell tables, in one call (paper Sec. V.B.7–8).

``summarize(cells, ground_truth_hq, beta_kg)`` returns metrics (flat dict of numbers, MLflow-ready), tables
(Table 6, the capped study per α, hyperplane coverage per α) and figures (Figs. 21–23).  Pure: no file IO.
"""

from __future__ import annotations

import math
import re

import numpy as np
import pandas as pd
from matplotlib.figure import Figure

from amorgs.ablation.statistics import (
    anytime_curves,
    capped_study,
    expected_running_time,
    hyperplane_coverage,
    iteration_capped,
    rates,
    table6,
)
from amorgs.analysis.hyperplanes import ModeParams, detect_modes, time_of_flight
from amorgs.figures.ablation import (
    ablation_anytime,
    ablation_beta_sweep,
    ablation_speedups,
    fig21_solve_time_histograms,
    fig22_capped_convergence,
    fig22_iteration_capped,
    fig23_amorgs_diversity,
)


def _key(text: str) -> str:
    return re.sub(r"[^0-9A-Za-z_.-]", "_", text)


def summarize(
    cells: pd.DataFrame,
    ground_truth_hq: pd.DataFrame,
    beta_kg: float,
    mode_params: ModeParams | None = None,
    n_boot: int = 2000,
    seed: int = 0,
    beta_sweep: tuple[float, ...] = (),
    iteration_caps: tuple[int, ...] = (),
    max_iter: int | None = None,
) -> tuple[dict[str, float], dict[str, pd.DataFrame], dict[str, Figure]]:
    """Table 6, Fig. 22 capped study + search acceleration (bootstrap CI), hyperplane coverage, Figs. 21–23;
    and (issue 11) rates with Wilson intervals and Fisher tests, the β sweep, expected running time with
    bootstrap speed-ups, the iteration-capped Fig. 22 and anytime curves.

    ``cells``: concatenated ablation tables (column ``sampler``); ``ground_truth_hq``: the high-quality
    solution set (all α; rows at the test α are the ground truth of Fig. 23 and of the coverage count);
    ``beta_sweep`` (kg, β itself added), ``iteration_caps`` (fixed in config before the solves; none:
    the iteration-capped study is empty) and ``max_iter`` (the solver's cap, an upper bound for them).
    """
    mode_params = mode_params or ModeParams()
    metrics: dict[str, float] = {}
    t6 = table6(cells, beta_kg)
    for row in t6.itertuples(index=False):
        tag = f"a{row.alpha:.3f}_{row.sampler}"
        metrics[f"percent_hq_{tag}"] = row.percent_high_quality
        metrics[f"time_median_s_{tag}"] = row.time_median_s
    capped_tables, coverage_tables = {}, {}
    for alpha, g in cells.groupby("alpha"):
        capped, result = capped_study(g, beta_kg, n_boot=n_boot, seed=seed)
        capped.insert(0, "alpha", alpha)
        capped_tables[alpha] = capped
        tag = f"a{alpha:.3f}"
        metrics[f"cap_s_{tag}"] = result["cap_s"]
        metrics[f"acceleration_{tag}"] = result["acceleration"]
        metrics[f"acceleration_ci95_low_{tag}"], metrics[f"acceleration_ci95_high_{tag}"] = result["acceleration_ci95"]
        for r in capped.itertuples(index=False):
            metrics[f"percent_within_cap_{tag}_{r.sampler}"] = r.percent_within_cap
        truth = ground_truth_hq[np.isclose(ground_truth_hq["alpha"], alpha)]
        modes = detect_modes(time_of_flight(truth), mode_params) if len(truth) else np.array([])
        cov = hyperplane_coverage(g, beta_kg, modes, mode_params.delta)
        cov.insert(0, "alpha", alpha)
        coverage_tables[alpha] = cov
        for r in cov.itertuples(index=False):
            metrics[f"hyperplanes_reached_{tag}_{r.sampler}"] = r.hyperplanes_reached
        metrics[f"hyperplanes_ground_truth_{tag}"] = float(len(modes))
    betas = tuple(sorted({float(beta_kg), *map(float, beta_sweep)}))
    sweep = rates(cells, betas)
    ert = expected_running_time(cells, beta_kg, n_boot=n_boot, seed=seed)
    capped_it = iteration_capped(cells, beta_kg, iteration_caps, max_iter) if iteration_caps else pd.DataFrame()
    curves = anytime_curves(cells, beta_kg)
    for r in sweep.itertuples(index=False):
        tag = f"a{r.alpha:.3f}_{r.sampler}" + ("" if r.beta_kg == beta_kg else f"_beta{r.beta_kg:g}")
        metrics[f"rate_percent_{tag}"] = r.percent
        metrics[f"rate_ci95_low_{tag}"], metrics[f"rate_ci95_high_{tag}"] = r.ci95_low, r.ci95_high
        for col in ("p_gt_uniform", "p_gt_nearest_alpha"):
            metrics[f"fisher_{col}_{tag}"] = getattr(r, col, math.nan)
    for r in ert.itertuples(index=False):
        tag = f"{r.unit}_a{r.alpha:.3f}_{r.sampler}"
        metrics[f"aRT_{tag}"] = r.aRT
        metrics[f"speedup_{tag}"] = r.speedup
        metrics[f"speedup_ci95_low_{tag}"], metrics[f"speedup_ci95_high_{tag}"] = r.speedup_ci95_low, r.speedup_ci95_high
    for r in capped_it.itertuples(index=False):
        tag = f"a{r.alpha:.3f}_cap{r.cap_iterations}_{r.sampler}"
        metrics[f"itcap_percent_{tag}"] = r.percent_within_cap
        metrics[f"itcap_percent_ratio_{tag}"] = getattr(r, "percent_ratio", math.nan)
        metrics[f"itcap_throughput_ratio_{tag}"] = getattr(r, "throughput_ratio", math.nan)
    if len(curves):
        last = curves.groupby(["alpha", "sampler"]).tail(1)
        for r in last.itertuples(index=False):
            tag = f"a{r.alpha:.3f}_{r.sampler}"
            metrics[f"best_m_f_{tag}"] = r.best_m_f
            metrics[f"distinct_optima_{tag}"] = float(r.distinct_optima)
    tables = {
        "rates": sweep[sweep["beta_kg"] == float(beta_kg)].reset_index(drop=True),
        "beta_sweep": sweep,
        "ert": ert,
        "iteration_capped": capped_it,
        "anytime": curves,
        "table6": t6,
        "capped": pd.concat(capped_tables.values(), ignore_index=True) if capped_tables else pd.DataFrame(),
        "coverage": pd.concat(coverage_tables.values(), ignore_index=True) if coverage_tables else pd.DataFrame(),
    }
    figures = {
        "fig21_solve_time_histograms": fig21_solve_time_histograms(cells, beta_kg),
        "fig22_capped_convergence": fig22_capped_convergence(capped_tables),
        "fig23_amorgs_diversity": fig23_amorgs_diversity(cells, ground_truth_hq, beta_kg),
        "ablation_speedups": ablation_speedups(ert),
        "ablation_beta_sweep": ablation_beta_sweep(sweep),
        "ablation_anytime": ablation_anytime(curves),
        "fig22_iteration_capped": fig22_iteration_capped(capped_it),
    }
    metrics = {_key(k): float(v) for k, v in metrics.items() if v is not None and not math.isnan(float(v))}
    return metrics, tables, figures


def table6_markdown(t6: pd.DataFrame) -> str:
    """Table 6 in the paper's orientation: one block per α, samplers as columns."""
    from amorgs.ablation.arms import SAMPLER_LABELS, SAMPLER_NAMES

    out = []
    rows = [
        ("Percentage (%)", "percent_high_quality", "{:.1f}"),
        ("95% CI (%)", None, None),
        ("Mean (s)", "time_mean_s", "{:.2f}"),
        ("Minimum (s)", "time_min_s", "{:.2f}"),
        ("25% (s)", "time_q25_s", "{:.2f}"),
        ("50% median (s)", "time_median_s", "{:.2f}"),
    ]
    for alpha, g in t6.groupby("alpha"):
        g = g.set_index("sampler")
        order = [s for s in SAMPLER_NAMES if s in g.index] + [s for s in g.index if s not in SAMPLER_NAMES]
        out.append(f"**α = {alpha:g}** (n = {int(g['n'].max())} starts per sampler)\n")
        out.append("| | " + " | ".join(SAMPLER_LABELS.get(s, s) for s in order) + " |")
        out.append("|---|" + "---|" * len(order))
        for label, col, fmt in rows:
            if col is None:
                cells = [f"{g.loc[s, 'ci95_low']:.0f}–{g.loc[s, 'ci95_high']:.0f}" for s in order]
            else:
                cells = ["–" if pd.isna(g.loc[s, col]) else fmt.format(g.loc[s, col]) for s in order]
            out.append(f"| {label} | " + " | ".join(cells) + " |")
        out.append("")
    return "\n".join(out)


def _fmt(v, spec: str = "{:.3g}") -> str:
    if v is None or (isinstance(v, float) and math.isnan(v)):
        return "–"
    if isinstance(v, float) and math.isinf(v):
        return "∞"
    return spec.format(v)


def markdown_table(df: pd.DataFrame, title: str = "") -> str:
    """A plain Markdown rendering of a statistics table (∞, – for NaN, three significant digits)."""
    if df is None or df.empty:
        return f"{title}\n\n(no rows)\n" if title else "(no rows)\n"
    lines = [title, ""] if title else []
    lines.append("| " + " | ".join(df.columns) + " |")
    lines.append("|" + "---|" * len(df.columns))
    for row in df.itertuples(index=False):
        lines.append("| " + " | ".join(_fmt(v) if isinstance(v, float) else str(v) for v in row) + " |")
    return "\n".join(lines) + "\n"


#: Titles of the issue-11 Markdown tables (``results/tables/<name>.md``).
MARKDOWN_TITLES = {
    "rates": "High-quality rate per arm: k of n starts, Wilson 95 % interval, one-sided Fisher p (arm > reference)",
    "beta_sweep": "High-quality rate vs β per arm (Wilson 95 %, one-sided Fisher p)",
    "ert": "Expected running time aRT = cost spent ÷ high-quality found; speed-up = aRT(uniform) ÷ aRT(arm), bootstrap 95 %",
    "iteration_capped": "Fig. 22 with a fixed iteration cap: % within cap, throughput, ratios to uniform",
}
