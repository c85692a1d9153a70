"""Everything the ablation report needs from the cell tables, in one call (paper Sec. V.B.7–8).

``summarize(cells, ground_truth_hq, beta_kg)`` returns an :class:`~amorgs.ablation.summary.AblationSummary`:
metrics (flat dict of numbers, MLflow-ready, keys from :func:`amorgs.alphas.metric_key`), tables (Table 6, the
capped study per α, hyperplane coverage per α, the issue-11 statistics) and the data of Figs. 21–23, which
:func:`amorgs.figures.ablation.ablation_figures` draws.  Pure: no file IO, no plotting.

Metric keys: ``<name>/alpha_<label>[/<sampler>][/<qualifier>]``, e.g. ``percent_hq/alpha_0.150/amorgs``,
``acceleration/alpha_0.150``, ``aRT_iterations/alpha_0.150/amorgs`` (IPOPT iterations per high-quality
solution), ``rate_percent/alpha_0.150/amorgs/beta_435`` (at a swept β, kg),
``itcap_percent/alpha_0.150/amorgs/cap_200`` (under a 200-iteration cap), ``aRT_distinct_iterations/alpha_0.150/amorgs``
(IPOPT iterations per new η-distinct high-quality optimum, Eq. 12), ``reuse_pool_size/alpha_0.150/nearest_alpha``.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from amorgs.ablation.arms import BASELINE_ARM, REUSE_ARM, SAMPLER_NAMES, arm_label
from amorgs.ablation.statistics import (
    anytime_bands,
    anytime_curves,
    break_even,
    capped_study,
    expected_running_time,
    high_quality,
    hyperplane_coverage,
    iteration_capped,
    learning_curve,
    rates,
    reuse_pools,
    seed_spread,
    table6,
)
from amorgs.ablation.summary import AblationSummary
from amorgs.alphas import alpha_value, metric_key, rows_at, rows_at_any
from amorgs.analysis.hyperplanes import ModeParams, detect_modes, time_of_flight


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
    upfront_cpu_s: dict[str, float] | None = None,
    break_even_solutions: tuple[int, ...] = (),
    eta: float | None = None,
) -> AblationSummary:
    """Table 6, Fig. 22 capped study + search acceleration (bootstrap CI), hyperplane coverage, the data of
    Figs. 21–23; and (issue 11) rates with Wilson intervals and Fisher tests, the β sweep, expected running time
    with bootstrap speed-ups, the iteration-capped Fig. 22 and anytime curves.

    ``cells``: concatenated ablation tables (column ``sampler``); ``ground_truth_hq``: the high-quality
    solution set (all α; rows at the test α are the ground truth of Fig. 23 and of the coverage count);
    ``beta_kg`` (kg); ``beta_sweep`` (kg, β itself added), ``iteration_caps`` (fixed in config before the
    solves; none: the iteration-capped study is empty) and ``max_iter`` (the solver's cap, an upper bound for
    them); ``upfront_cpu_s`` (arm → CPU seconds spent before the first new α: data, training) and
    ``break_even_solutions`` (high-quality solutions wanted per new α; none: no break-even table); ``eta``: η
    of the η-distinct optima (Eq. 12, dimensionless; none: the default of
    :class:`~amorgs.analysis.diversity.DiversityParams`).  Every bootstrap is drawn from ``seed``.  α are
    grouped by label (:mod:`amorgs.alphas`).
    """
    mode_params = mode_params or ModeParams()
    cells = cells.assign(alpha=cells["alpha"].map(alpha_value))
    # learning-curve cells (models trained on a fraction of the data) feed only the learning curve
    fraction = cells["data_fraction"].fillna(1.0) if "data_fraction" in cells else pd.Series(1.0, index=cells.index)
    partial = cells[fraction < 1.0]
    cells = cells[fraction >= 1.0].drop(columns="data_fraction", errors="ignore").reset_index(drop=True)
    metrics: dict[str, float] = {}
    t6 = table6(cells, beta_kg)
    for row in t6.itertuples(index=False):
        metrics[metric_key("percent_hq", row.alpha, row.sampler)] = row.percent_high_quality
        metrics[metric_key("time_median_s", row.alpha, row.sampler)] = row.time_median_s
    capped_tables, coverage_tables = [], []
    for alpha, g in cells.groupby("alpha"):
        capped, result = capped_study(g, beta_kg, n_boot=n_boot, seed=seed)
        capped.insert(0, "alpha", alpha)
        capped_tables.append(capped)
        metrics[metric_key("cap_s", alpha)] = result["cap_s"]
        metrics[metric_key("acceleration", alpha)] = result["acceleration"]
        (metrics[metric_key("acceleration_ci95_low", alpha)],
         metrics[metric_key("acceleration_ci95_high", alpha)]) = result["acceleration_ci95"]
        for r in capped.itertuples(index=False):
            metrics[metric_key("percent_within_cap", alpha, r.sampler)] = r.percent_within_cap
        truth = rows_at(ground_truth_hq, alpha)
        modes = detect_modes(time_of_flight(truth), mode_params) if len(truth) else np.array([])
        cov = hyperplane_coverage(g, beta_kg, modes, mode_params.delta)
        cov.insert(0, "alpha", alpha)
        coverage_tables.append(cov)
        for r in cov.itertuples(index=False):
            metrics[metric_key("hyperplanes_reached", alpha, r.sampler)] = r.hyperplanes_reached
        metrics[metric_key("hyperplanes_ground_truth", alpha)] = float(len(modes))
    betas = tuple(sorted({float(beta_kg), *map(float, beta_sweep)}))
    sweep = rates(cells, betas)
    ert = expected_running_time(cells, beta_kg, n_boot=n_boot, seed=seed)
    ert_distinct = expected_running_time(cells, beta_kg, n_boot=n_boot, seed=seed, target="distinct", eta=eta)
    pools = reuse_pools(cells)
    capped_it = (iteration_capped(cells, beta_kg, iteration_caps, max_iter, n_boot=n_boot, seed=seed)
                 if iteration_caps else pd.DataFrame())
    curves = anytime_curves(cells, beta_kg, eta)
    bands = anytime_bands(cells, beta_kg, eta, n_boot=n_boot, seed=seed)
    even = (break_even(cells, beta_kg, upfront_cpu_s or {}, break_even_solutions, n_boot=n_boot, seed=seed)
            if break_even_solutions else pd.DataFrame())
    curve = learning_curve(cells, partial, beta_kg, n_boot=n_boot, seed=seed)
    for r in curve.itertuples(index=False):
        metrics[metric_key(f"aRT_{r.unit}", r.alpha, r.sampler, f"fraction_{r.data_fraction:g}")] = r.aRT
    for r in even.itertuples(index=False):
        metrics[metric_key("break_even_new_alphas", r.alpha, r.sampler, f"K_{r.solutions_wanted}")] = (
            r.break_even_new_alphas)
    for r in sweep.itertuples(index=False):
        swept = () if r.beta_kg == beta_kg else (f"beta_{r.beta_kg:g}",)
        metrics[metric_key("rate_percent", r.alpha, r.sampler, *swept)] = r.percent
        metrics[metric_key("rate_ci95_low", r.alpha, r.sampler, *swept)] = r.ci95_low
        metrics[metric_key("rate_ci95_high", r.alpha, r.sampler, *swept)] = r.ci95_high
        for col in (f"p_gt_{BASELINE_ARM}", f"p_gt_{REUSE_ARM}", f"p_lt_{REUSE_ARM}"):
            metrics[metric_key(f"fisher_{col}", r.alpha, r.sampler, *swept)] = getattr(r, col, math.nan)
    for r in ert.itertuples(index=False):
        metrics[metric_key(f"aRT_{r.unit}", r.alpha, r.sampler)] = r.aRT
        metrics[metric_key(f"speedup_{r.unit}", r.alpha, r.sampler)] = r.speedup
        metrics[metric_key(f"speedup_ci95_low_{r.unit}", r.alpha, r.sampler)] = r.speedup_ci95_low
        metrics[metric_key(f"speedup_ci95_high_{r.unit}", r.alpha, r.sampler)] = r.speedup_ci95_high
        metrics[metric_key(f"versus_reuse_{r.unit}", r.alpha, r.sampler)] = r.versus_reuse
        metrics[metric_key(f"versus_reuse_ci95_low_{r.unit}", r.alpha, r.sampler)] = r.versus_reuse_ci95_low
        metrics[metric_key(f"versus_reuse_ci95_high_{r.unit}", r.alpha, r.sampler)] = r.versus_reuse_ci95_high
    for r in ert_distinct.itertuples(index=False):
        metrics[metric_key(f"aRT_distinct_{r.unit}", r.alpha, r.sampler)] = r.aRT
        metrics[metric_key("k_distinct", r.alpha, r.sampler)] = r.k_distinct
        for column in ("speedup", "versus_reuse"):
            for suffix in ("", "_ci95_low", "_ci95_high"):
                metrics[metric_key(f"{column}_distinct{suffix}_{r.unit}", r.alpha, r.sampler)] = getattr(
                    r, column + suffix)
    for r in pools.itertuples(index=False):
        metrics[metric_key("reuse_pool_size", r.alpha, r.sampler)] = r.pool_size
    for r in capped_it.itertuples(index=False):
        cap = f"cap_{r.cap_iterations}"
        metrics[metric_key("itcap_percent", r.alpha, r.sampler, cap)] = r.percent_within_cap
        metrics[metric_key("itcap_percent_ratio", r.alpha, r.sampler, cap)] = getattr(r, "percent_ratio", math.nan)
        metrics[metric_key("itcap_throughput_ratio", r.alpha, r.sampler, cap)] = getattr(r, "throughput_ratio",
                                                                                        math.nan)
    if len(curves):
        last = curves.groupby(["alpha", "sampler"]).tail(1)
        for r in last.itertuples(index=False):
            metrics[metric_key("best_m_f", r.alpha, r.sampler)] = r.best_m_f
            metrics[metric_key("distinct_optima", r.alpha, r.sampler)] = float(r.distinct_optima)
    tables = {
        "rates": sweep[sweep["beta_kg"] == float(beta_kg)].reset_index(drop=True),
        "beta_sweep": sweep,
        "ert": ert,
        "ert_distinct": ert_distinct,
        "reuse_pool": pools,
        "iteration_capped": capped_it,
        "anytime": curves,
        "anytime_bands": bands,
        "break_even": even,
        "learning_curve": curve,
        "seeds": seed_spread(cells, beta_kg),
        "table6": t6,
        "capped": pd.concat(capped_tables, ignore_index=True) if capped_tables else pd.DataFrame(),
        "coverage": pd.concat(coverage_tables, ignore_index=True) if coverage_tables else pd.DataFrame(),
    }
    metrics = {k: float(v) for k, v in metrics.items() if v is not None and not math.isnan(float(v))}
    return AblationSummary(
        metrics=metrics, tables=tables, solves=cells.assign(high_quality=high_quality(cells, beta_kg)),
        ground_truth=rows_at_any(ground_truth_hq, cells["alpha"].unique()), beta_kg=float(beta_kg),
    )


def table6_markdown(t6: pd.DataFrame) -> str:
    """Table 6 in the paper's orientation: one block per α, samplers as columns."""
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
        out.append("| | " + " | ".join(arm_label(s) for s in order) + " |")
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
    "ert": f"Expected running time aRT = cost spent ÷ high-quality found; speed-up = aRT({BASELINE_ARM}) ÷ "
           f"aRT(arm); versus_reuse = aRT({REUSE_ARM}) ÷ aRT(arm), > 1: the arm beats reuse; bootstrap 95 %; the "
           "reuse arms drawn as ablation_reuse_pool states",
    "ert_distinct": "What a designer wants: aRT = cost spent ÷ new η-distinct high-quality optima (paper Eq. 12; "
                    "each arm's starts in order, a solution counts when farther than η from every one counted "
                    "before — repeats find nothing new); speed-up and versus_reuse as in ablation_ert, "
                    "bootstrap 95 %",
    "reuse_pool": "Reuse arms: the training α reused, its pool of high-quality rows, and the draw every table of "
                  "this report counts — without replacement until the pool is exhausted, then with replacement",
    "iteration_capped": "Fig. 22 with a fixed iteration cap: % within cap (Wilson 95 %), throughput, ratios to "
                        f"{BASELINE_ARM} (ratio of percentages: Katz 95 %; throughput ratio: bootstrap 95 %)",
    "learning_curve": "Learning curve: aRT of the learned arms vs the fraction of the training data their models "
                      f"saw; speed-up = aRT({BASELINE_ARM}) ÷ aRT(arm), bootstrap 95 %",
    "seeds": "Per model-training seed: high quality k of n (Wilson 95 %) and aRT in iterations; the other "
             "tables pool the seeds",
    "break_even": "Break-even: new α after which an arm's up-front CPU (data; training) is repaid by the CPU it "
                  f"saves over {BASELINE_ARM}, for K high-quality solutions per α (bootstrap 95 %)",
}
