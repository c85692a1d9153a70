"""What the ablation report computes (paper Sec. V.B.7–8): plain data for the summary, tables and figures.

:func:`amorgs.ablation.report.summarize` computes an :class:`AblationSummary`;
:func:`amorgs.figures.ablation.ablation_figures` draws Figs. 21–23 from it.  Only the data type lives here
(pandas and the standard library), so the figures can name it without importing the statistics.
"""

from __future__ import annotations

from dataclasses import dataclass

import pandas as pd


@dataclass
class AblationSummary:
    """The ablation report of a set of cells.

    metrics: flat ``{key: float}`` (keys from :func:`amorgs.alphas.metric_key`; NaN left out, ∞ kept, e.g. an
        acceleration over a baseline that found nothing).
    tables: ``table6``, ``capped``, ``coverage``, ``rates``, ``beta_sweep``, ``ert``, ``ert_distinct``,
        ``reuse_pool``, ``iteration_capped``, ``anytime``, ``anytime_bands``, ``break_even``, ``learning_curve``,
        ``seeds`` (column ``alpha`` holds :func:`amorgs.alphas.alpha_value`, e.g. 0.15).
    solves: the cells (one row per start) with a boolean ``high_quality`` column (converged and m_f ≥ β).
    ground_truth: the rows of the high-quality solution set at the test α (the α of the cells).
    beta_kg: the quality threshold β (kg).
    """

    metrics: dict[str, float]
    tables: dict[str, pd.DataFrame]
    solves: pd.DataFrame
    ground_truth: pd.DataFrame
    beta_kg: float
