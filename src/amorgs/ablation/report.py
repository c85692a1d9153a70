"""Everything the ablation report needs from the cell tables, in one call (paper Sec. V.B.7–8).

``summarize(cells, ground_truth_hq, beta_kg)`` returns an :class:`~amorgs.ablation.summary.AblationSummary`:
metrics (flat dict of numbers, MLflow-ready, keys from :func:`amorgs.alphas.metric_key`), tables (one per study of
:data:`amorgs.ablation.studies.STUDIES`: Table 6, the capped study per α, hyperplane coverage per α, the issue-11
statistics) and the data of Figs. 21–23, which :func:`amorgs.figures.ablation.ablation_figures` draws.  Each study
is one function ``(StudyInputs) -> (table, metrics)`` below, named by its record in the study table.  Pure: no file
IO, no plotting.

Metric keys: ``<name>/alpha_<label>[/<sampler>][/<qualifier>]``, e.g. ``percent_hq/alpha_0.150/amorgs``,
``acceleration/alpha_0.150``, ``aRT_iterations/alpha_0.150/amorgs`` (IPOPT iterations per high-quality
solution), ``rate_percent/alpha_0.150/amorgs/beta_435`` (at a swept β, kg),
``itcap_percent/alpha_0.150/amorgs/cap_200`` (under a 200-iteration cap), ``aRT_distinct_iterations/alpha_0.150/amorgs``
(IPOPT iterations per new η-distinct high-quality optimum, Eq. 12), ``reuse_pool_size/alpha_0.150/nearest_alpha``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from amorgs.ablation.arms import BASELINE_ARM, REUSE_ARM, SAMPLER_NAMES, arm_label
from amorgs.ablation.statistics import capped_study, high_quality, hyperplane_coverage, rates, reuse_pools, table6
from amorgs.ablation.running_time import (
    anytime_bands,
    anytime_curves,
    break_even,
    expected_running_time,
    iteration_capped,
    learning_curve,
    seed_spread,
)
from amorgs.ablation.studies import STUDIES
from amorgs.ablation.summary import AblationSummary
from amorgs.alphas import alpha_value, metric_key, rows_at, rows_at_any
from amorgs.analysis.hyperplanes import ModeParams, detect_modes, time_of_flight
from amorgs.models.names import resolve

Metrics = dict[str, float]


@dataclass(frozen=True)
class StudyInputs:
    """What every study reads: the full-data cells (learning-curve cells apart, in ``partial``), the ground truth,
    β (kg) and the report's settings, as :func:`summarize` documents them."""

    cells: pd.DataFrame
    partial: pd.DataFrame
    ground_truth_hq: pd.DataFrame
    beta_kg: float
    mode_params: ModeParams = field(default_factory=ModeParams)
    n_boot: int = 2000
    seed: int = 0
    betas: tuple[float, ...] = ()
    iteration_caps: tuple[int, ...] = ()
    max_iter: int | None = None
    upfront_cpu_s: dict[str, float] = field(default_factory=dict)
    break_even_solutions: tuple[int, ...] = ()
    eta: float | None = None


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
    """Every study of :data:`~amorgs.ablation.studies.STUDIES`: Table 6, Fig. 22 capped study + search
    acceleration (bootstrap CI), hyperplane coverage, the data of Figs. 21–23; and (issue 11) rates with Wilson
    intervals and Fisher tests, the β sweep, expected running time with bootstrap speed-ups, the iteration-capped
    Fig. 22 and anytime curves.

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
    cells = cells.assign(alpha=cells["alpha"].map(alpha_value))
    # learning-curve cells (models trained on a fraction of the data) feed only the learning curve
    fraction = cells["data_fraction"].fillna(1.0) if "data_fraction" in cells else pd.Series(1.0, index=cells.index)
    inputs = StudyInputs(
        cells=cells[fraction >= 1.0].drop(columns="data_fraction", errors="ignore").reset_index(drop=True),
        partial=cells[fraction < 1.0], ground_truth_hq=ground_truth_hq, beta_kg=float(beta_kg),
        mode_params=mode_params or ModeParams(), n_boot=n_boot, seed=seed,
        betas=tuple(sorted({float(beta_kg), *map(float, beta_sweep)})), iteration_caps=tuple(iteration_caps),
        max_iter=max_iter, upfront_cpu_s=dict(upfront_cpu_s or {}),
        break_even_solutions=tuple(break_even_solutions), eta=eta)
    metrics: Metrics = {}
    tables: dict[str, pd.DataFrame] = {}
    for study in STUDIES:
        tables[study.name], found = resolve(study.compute)(inputs)
        metrics.update(found)
    metrics = {k: float(v) for k, v in metrics.items() if v is not None and not math.isnan(float(v))}
    return AblationSummary(
        metrics=metrics, tables=tables, solves=inputs.cells.assign(high_quality=high_quality(inputs.cells, beta_kg)),
        ground_truth=rows_at_any(ground_truth_hq, inputs.cells["alpha"].unique()), beta_kg=float(beta_kg),
    )


# ------------------------------------------------------------------------------------------- the studies
def table6_study(s: StudyInputs) -> tuple[pd.DataFrame, Metrics]:
    """Table 6: % high quality and solve-time quantiles per (α, arm)."""
    t6 = table6(s.cells, s.beta_kg)
    metrics = {}
    for row in t6.itertuples(index=False):
        metrics[metric_key("percent_hq", row.alpha, row.sampler)] = row.percent_high_quality
        metrics[metric_key("time_median_s", row.alpha, row.sampler)] = row.time_median_s
    return t6, metrics


def capped_study_per_alpha(s: StudyInputs) -> tuple[pd.DataFrame, Metrics]:
    """Fig. 22: % within the time cap per arm, and the search acceleration with its bootstrap interval, per α."""
    tables, metrics = [], {}
    for alpha, g in s.cells.groupby("alpha"):
        capped, result = capped_study(g, s.beta_kg, n_boot=s.n_boot, seed=s.seed)
        capped.insert(0, "alpha", alpha)
        tables.append(capped)
        metrics[metric_key("cap_s", alpha)] = result["cap_s"]
        metrics[metric_key("acceleration", alpha)] = result["acceleration"]
        (metrics[metric_key("acceleration_ci95_low", alpha)],
         metrics[metric_key("acceleration_ci95_high", alpha)]) = result["acceleration_ci95"]
        for r in capped.itertuples(index=False):
            metrics[metric_key("percent_within_cap", alpha, r.sampler)] = r.percent_within_cap
    return (pd.concat(tables, ignore_index=True) if tables else pd.DataFrame()), metrics


def coverage_study(s: StudyInputs) -> tuple[pd.DataFrame, Metrics]:
    """Hyperplanes of the ground truth at each test α reached by each arm's high-quality solves."""
    tables, metrics = [], {}
    for alpha, g in s.cells.groupby("alpha"):
        truth = rows_at(s.ground_truth_hq, alpha)
        modes = detect_modes(time_of_flight(truth), s.mode_params) if len(truth) else np.array([])
        cov = hyperplane_coverage(g, s.beta_kg, modes, s.mode_params.delta)
        cov.insert(0, "alpha", alpha)
        tables.append(cov)
        for r in cov.itertuples(index=False):
            metrics[metric_key("hyperplanes_reached", alpha, r.sampler)] = r.hyperplanes_reached
        metrics[metric_key("hyperplanes_ground_truth", alpha)] = float(len(modes))
    return (pd.concat(tables, ignore_index=True) if tables else pd.DataFrame()), metrics


def beta_sweep_study(s: StudyInputs) -> tuple[pd.DataFrame, Metrics]:
    """Rates with Wilson intervals and one-sided Fisher tests at β and at every swept β."""
    sweep = rates(s.cells, s.betas)
    metrics = {}
    for r in sweep.itertuples(index=False):
        swept = () if r.beta_kg == s.beta_kg else (f"beta_{r.beta_kg:g}",)
        metrics[metric_key("rate_percent", r.alpha, r.sampler, *swept)] = r.percent
        metrics[metric_key("rate_ci95_low", r.alpha, r.sampler, *swept)] = r.ci95_low
        metrics[metric_key("rate_ci95_high", r.alpha, r.sampler, *swept)] = r.ci95_high
        for col in (f"p_gt_{BASELINE_ARM}", f"p_gt_{REUSE_ARM}", f"p_lt_{REUSE_ARM}"):
            metrics[metric_key(f"fisher_{col}", r.alpha, r.sampler, *swept)] = getattr(r, col, math.nan)
    return sweep, metrics


def rates_study(s: StudyInputs) -> tuple[pd.DataFrame, Metrics]:
    """The rates at β itself (the β sweep's rows at β; its metrics are the sweep's)."""
    return rates(s.cells, (s.beta_kg,)).reset_index(drop=True), {}


def ert_study(s: StudyInputs) -> tuple[pd.DataFrame, Metrics]:
    """aRT per high-quality solution (iterations, CPU s), speed-ups over the baseline and versus reuse."""
    ert = expected_running_time(s.cells, s.beta_kg, n_boot=s.n_boot, seed=s.seed)
    metrics = {}
    for r in ert.itertuples(index=False):
        metrics[metric_key(f"aRT_{r.unit}", r.alpha, r.sampler)] = r.aRT
        for column in ("speedup", "versus_reuse"):
            metrics[metric_key(f"{column}_{r.unit}", r.alpha, r.sampler)] = getattr(r, column)
            for suffix in ("_ci95_low", "_ci95_high"):
                metrics[metric_key(f"{column}{suffix}_{r.unit}", r.alpha, r.sampler)] = getattr(r, column + suffix)
    return ert, metrics


def ert_distinct_study(s: StudyInputs) -> tuple[pd.DataFrame, Metrics]:
    """aRT per new η-distinct high-quality optimum (paper Eq. 12)."""
    ert = expected_running_time(s.cells, s.beta_kg, n_boot=s.n_boot, seed=s.seed, target="distinct", eta=s.eta)
    metrics = {}
    for r in ert.itertuples(index=False):
        metrics[metric_key(f"aRT_distinct_{r.unit}", r.alpha, r.sampler)] = r.aRT
        metrics[metric_key("k_distinct", r.alpha, r.sampler)] = r.k_distinct
        for column in ("speedup", "versus_reuse"):
            for suffix in ("", "_ci95_low", "_ci95_high"):
                metrics[metric_key(f"{column}_distinct{suffix}_{r.unit}", r.alpha, r.sampler)] = getattr(
                    r, column + suffix)
    return ert, metrics


def reuse_pool_study(s: StudyInputs) -> tuple[pd.DataFrame, Metrics]:
    """How the reuse arms drew from their pool of training-α solutions."""
    pools = reuse_pools(s.cells)
    return pools, {metric_key("reuse_pool_size", r.alpha, r.sampler): r.pool_size
                   for r in pools.itertuples(index=False)}


def iteration_capped_study(s: StudyInputs) -> tuple[pd.DataFrame, Metrics]:
    """Fig. 22 under the iteration caps fixed in the config (empty without caps)."""
    if not s.iteration_caps:
        return pd.DataFrame(), {}
    capped = iteration_capped(s.cells, s.beta_kg, s.iteration_caps, s.max_iter, n_boot=s.n_boot, seed=s.seed)
    metrics = {}
    for r in capped.itertuples(index=False):
        cap = f"cap_{r.cap_iterations}"
        metrics[metric_key("itcap_percent", r.alpha, r.sampler, cap)] = r.percent_within_cap
        metrics[metric_key("itcap_percent_ratio", r.alpha, r.sampler, cap)] = getattr(r, "percent_ratio", math.nan)
        metrics[metric_key("itcap_throughput_ratio", r.alpha, r.sampler, cap)] = getattr(r, "throughput_ratio",
                                                                                        math.nan)
    return capped, metrics


def break_even_study(s: StudyInputs) -> tuple[pd.DataFrame, Metrics]:
    """New α after which each arm's up-front CPU is repaid (empty without ``break_even_solutions``)."""
    if not s.break_even_solutions:
        return pd.DataFrame(), {}
    even = break_even(s.cells, s.beta_kg, s.upfront_cpu_s, s.break_even_solutions, n_boot=s.n_boot, seed=s.seed)
    return even, {metric_key("break_even_new_alphas", r.alpha, r.sampler, f"K_{r.solutions_wanted}"):
                  r.break_even_new_alphas for r in even.itertuples(index=False)}


def learning_curve_study(s: StudyInputs) -> tuple[pd.DataFrame, Metrics]:
    """aRT of the learned arms against the fraction of the training data their models saw."""
    curve = learning_curve(s.cells, s.partial, s.beta_kg, n_boot=s.n_boot, seed=s.seed)
    return curve, {metric_key(f"aRT_{r.unit}", r.alpha, r.sampler, f"fraction_{r.data_fraction:g}"): r.aRT
                   for r in curve.itertuples(index=False)}


def seeds_study(s: StudyInputs) -> tuple[pd.DataFrame, Metrics]:
    """Per model-training seed: high quality k of n and aRT."""
    return seed_spread(s.cells, s.beta_kg), {}


def anytime_study(s: StudyInputs) -> tuple[pd.DataFrame, Metrics]:
    """Best m_f and η-distinct optima found against cumulative cost, per (α, arm)."""
    curves = anytime_curves(s.cells, s.beta_kg, s.eta)
    metrics = {}
    if len(curves):
        for r in curves.groupby(["alpha", "sampler"]).tail(1).itertuples(index=False):
            metrics[metric_key("best_m_f", r.alpha, r.sampler)] = r.best_m_f
            metrics[metric_key("distinct_optima", r.alpha, r.sampler)] = float(r.distinct_optima)
    return curves, metrics


def anytime_bands_study(s: StudyInputs) -> tuple[pd.DataFrame, Metrics]:
    """Bootstrap bands of the anytime curves."""
    return anytime_bands(s.cells, s.beta_kg, s.eta, n_boot=s.n_boot, seed=s.seed), {}


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
