"""The runtime figure (issue 40 §1): where the workflow's time went, per rule.  Data in (the table of
:func:`amorgs.runtime_report.runtime_by_rule`), matplotlib Figure out; no statistics."""

from __future__ import annotations

import numpy as np
import pandas as pd
from matplotlib.figure import Figure


def fig_runtime_by_rule(rules: pd.DataFrame) -> Figure:
    """Horizontal bars per rule, the most expensive on top: job-minutes of wall time and CPU-minutes side by
    side (left), and each rule's peak resident memory (right); each bar labelled with its job count."""
    r = rules.iloc[::-1].reset_index(drop=True)
    y = np.arange(len(r))
    fig = Figure(figsize=(10, 0.35 * len(r) + 1.6), layout="constrained")
    left, right = fig.subplots(1, 2, sharey=True, width_ratios=(3, 1))
    left.barh(y + 0.2, r["wall_min"], height=0.4, label="wall (job-minutes)", color="C0")
    left.barh(y - 0.2, r["cpu_min"], height=0.4, label="CPU (minutes)", color="C1")
    for yi, (jobs, wall) in enumerate(zip(r["jobs"], r["wall_min"])):
        left.annotate(f"{jobs} job{'s' if jobs != 1 else ''}", (wall, yi + 0.2), xytext=(3, 0),
                      textcoords="offset points", va="center", fontsize=7)
    left.set_yticks(y, r["rule"], fontsize=8)
    left.set_xlabel("minutes")
    left.legend(fontsize=8, loc="lower right")
    right.barh(y, r["max_rss_mb"].fillna(0), color="C2")
    right.set_xlabel("peak RSS per job (MB)")
    fig.suptitle(f"Where the workflow's time went: {int(r['jobs'].sum())} jobs, {r['wall_min'].sum():.1f} "
                 f"job-minutes, {r['cpu_min'].sum():.1f} CPU-minutes", fontsize=10)
    return fig
