"""The frontier figure (issue 21 §1): does a learned sampler overtake reuse as the gap to the known α grows?
Data in (the table of :func:`amorgs.ablation.frontier.frontier_table`), matplotlib Figure out; no statistics.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
from matplotlib.figure import Figure
from matplotlib.ticker import FuncFormatter

from amorgs.ablation.arms import REUSE_ARM, arm_label

_MARKERS = "osD^vP*X"
#: x axes of the two panels: (column, label).
_GAPS = (("gap", "gap |Δα| to the nearest training α (N)"), ("gap_relative", "relative gap |Δα| / α"))


def _dodged(t: pd.DataFrame, column: str, arms: list[str], width: float) -> pd.Series:
    """x of each row of ``t``: its gap ``column``, moved sideways so that the points sharing one gap — every
    (run, test α) there, ascending α, each with its arms in ``arms`` order — sit side by side, ``width`` apart
    and centred on the gap (a gap with one point keeps its exact x)."""
    xs = t[column].astype(float).copy()
    for _, g in t.groupby(t[column].round(9)):
        combos = sorted(set(zip(g["alpha"], g["run"])))
        n_slots = len(combos) * len(arms)
        for idx, r in g.iterrows():
            slot = combos.index((r["alpha"], r["run"])) * len(arms) + arms.index(r["sampler"])
            xs[idx] = float(r[column]) + (slot - (n_slots - 1) / 2) * width
    return xs


def fig_frontier(table: pd.DataFrame, unit: str = "iterations", target: str = "high_quality",
                 reuse: str = REUSE_ARM) -> Figure:
    """aRT(learned) ÷ aRT(reuse) with its bootstrap 95 % interval (log y; below the line at 1 learning wins) against
    the absolute gap (left, N) and the relative gap (right), one point per (run, test α, learned arm): colour =
    design, marker = learned arm (the points at one gap side by side, ascending test α), ∞ drawn at the top edge as
    an open marker, the test α written once above its points, in its design's colour. ``unit``: cost in
    ``iterations`` (IPOPT) or ``cpu_s``; ``target``: per ``high_quality`` solution or per new ``distinct`` optimum.
    A grey bar at each test α marks the oracle bound of selection over reuse's candidates (the ``reuse`` row's
    ``oracle_to_reuse``, where the table has it): no selector over those candidates can go below it."""
    t = table[(table["unit"] == unit) & (table["target"] == target) & table["ratio_to_reuse"].notna()]
    oracle = table[(table["unit"] == unit) & (table["target"] == target) & (table["sampler"] == reuse)]
    oracle = oracle[np.isfinite(oracle["oracle_to_reuse"])] if "oracle_to_reuse" in oracle else oracle.iloc[:0]
    designs = sorted(t["design"].unique())
    arms = sorted(t["sampler"].unique())
    values = t[["ratio_to_reuse", "ratio_to_reuse_ci95_low", "ratio_to_reuse_ci95_high"]].to_numpy(dtype=float)
    shown = values[np.isfinite(values) & (values > 0)]
    lo, hi = (shown.min() / 2, shown.max() * 2) if shown.size else (0.1, 10.0)
    lo, hi = min(lo, 0.5), max(hi, 2.0)
    if len(oracle):
        lo = min(lo, float(oracle["oracle_to_reuse"].min()) / 1.5)
    fig = Figure(figsize=(11, 4.8), layout="constrained")
    axes = fig.subplots(1, 2, sharey=True)
    plain = FuncFormatter(lambda v, _: f"{v:g}")
    for ax, (column, xlabel) in zip(axes, _GAPS):
        dodge = 0.008 * float(t[column].max()) if len(t) else 0.0
        xs = _dodged(t, column, arms, dodge)
        tops: dict[tuple, tuple[list[float], float, int]] = {}  # (run, α) → (its x, top of its whiskers, colour)
        for i, design in enumerate(designs):
            for j, arm in enumerate(arms):
                g = t[(t["design"] == design) & (t["sampler"] == arm)]
                for r, x in zip(g.itertuples(index=False), xs[g.index]):
                    y = hi if np.isinf(r.ratio_to_reuse) else r.ratio_to_reuse
                    if not (np.isfinite(y) and y > 0):
                        continue
                    y_lo = r.ratio_to_reuse_ci95_low if r.ratio_to_reuse_ci95_low > 0 else lo
                    y_hi = hi if np.isinf(r.ratio_to_reuse_ci95_high) else r.ratio_to_reuse_ci95_high
                    if np.isfinite(y_lo) and np.isfinite(y_hi):
                        ax.plot([x, x], [y_lo, y_hi], color=f"C{i}", lw=1.2, alpha=0.8)
                    ax.plot([x], [y], marker=_MARKERS[j % len(_MARKERS)], color=f"C{i}", ls="none",
                            mfc="none" if np.isinf(r.ratio_to_reuse) else f"C{i}")
                    top = y_hi if np.isfinite(y_hi) else y
                    x_seen, top_seen, _ = tops.get((r.run, r.alpha), ([], 0.0, i))
                    tops[(r.run, r.alpha)] = (x_seen + [x], max(top_seen, top), i)
        for (_, alpha), (x_seen, top, i) in tops.items():  # the test α once, above its points' whiskers
            ax.annotate(f"{alpha:g}", (float(np.mean(x_seen)), min(top, hi)), textcoords="offset points",
                        xytext=(0, 2), fontsize=7, ha="center", va="bottom", color=f"C{i}")
        for r in oracle.itertuples(index=False):
            if r.oracle_to_reuse > 0:
                ax.plot([getattr(r, column)], [r.oracle_to_reuse], marker="_", ms=14, mew=2, color="grey")
        ax.axhline(1.0, color="grey", ls="--", lw=0.8)
        ax.set_yscale("log")
        ax.set_ylim(lo, hi)
        ax.yaxis.set_major_formatter(plain)
        ax.yaxis.set_minor_formatter(plain)
        ax.tick_params(axis="y", which="minor", labelsize=7)
        ax.set_xlim(0, 1.15 * float(xs.max()) if len(t) else 1.0)
        ax.set_xlabel(xlabel)
    per = "high-quality solution" if target == "high_quality" else "new η-distinct optimum"
    cost = "IPOPT iterations" if unit == "iterations" else "CPU s"
    axes[0].set_ylabel(f"aRT(learned) ÷ aRT(reuse)\n({cost} per {per})")
    handles = [axes[0].plot([], [], color=f"C{i}", lw=2, label=d)[0] for i, d in enumerate(designs)]
    handles += [axes[0].plot([], [], color="k", marker=_MARKERS[j % len(_MARKERS)], ls="none",
                             label=arm_label(a))[0] for j, a in enumerate(arms)]
    if len(oracle):
        handles.append(axes[0].plot([], [], color="grey", marker="_", ms=14, mew=2, ls="none",
                                    label="oracle bound of selecting reuse's candidates")[0])
    if handles:
        fig.legend(handles=handles, fontsize=7, loc="outside lower center", ncol=len(handles))  # off the points
    n = int(t["n"].min()) if len(t) else 0
    fig.suptitle(f"The frontier: below 1 the learned sampler beats reuse of the nearest α (bootstrap 95 %; "
                 f"≥ {n} starts per arm; labels: test α)", fontsize=10)
    return fig
