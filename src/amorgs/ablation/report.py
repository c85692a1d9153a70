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

from amorgs.ablation.statistics import capped_study, hyperplane_coverage, table6
from amorgs.analysis.hyperplanes import ModeParams, detect_modes, time_of_flight
from amorgs.figures.ablation import fig21_solve_time_histograms, fig22_capped_convergence, fig23_amorgs_diversity


def _key(text: str) -> str:
    return re.sub(r"[^0-9A-Za-z_.-]", "_", text)


def summarize(
    cells: pd.DataFrame,
    ground_truth_hq: pd.DataFrame,
    beta_kg: float,
    mode_params: ModeParams | None = None,
    n_boot: int = 2000,
    seed: int = 0,
) -> tuple[dict[str, float], dict[str, pd.DataFrame], dict[str, Figure]]:
    """Table 6, Fig. 22 capped study + search acceleration (bootstrap CI), hyperplane coverage, Figs. 21–23.

    ``cells``: concatenated ablation tables (column ``sampler``); ``ground_truth_hq``: the high-quality
    solution set (all α; rows at the test α are the ground truth of Fig. 23 and of the coverage count).
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
    tables = {
        "table6": t6,
        "capped": pd.concat(capped_tables.values(), ignore_index=True) if capped_tables else pd.DataFrame(),
        "coverage": pd.concat(coverage_tables.values(), ignore_index=True) if coverage_tables else pd.DataFrame(),
    }
    figures = {
        "fig21_solve_time_histograms": fig21_solve_time_histograms(cells, beta_kg),
        "fig22_capped_convergence": fig22_capped_convergence(capped_tables),
        "fig23_amorgs_diversity": fig23_amorgs_diversity(cells, ground_truth_hq, beta_kg),
    }
    metrics = {_key(k): float(v) for k, v in metrics.items() if v is not None and not (isinstance(v, float) and math.isnan(v))}
    return metrics, tables, figures


def table6_markdown(t6: pd.DataFrame) -> str:
    """Table 6 in the paper's orientation: one block per α, samplers as columns."""
    from amorgs.models.samplers import SAMPLER_LABELS, SAMPLER_NAMES

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
