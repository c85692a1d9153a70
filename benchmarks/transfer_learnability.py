"""What the transfer data say about why the selector wins at 2 frontier points and not at 5 (issue 38).

Reads a transfer table (default: the one shipped beside the selector, ``data/models/cr3bp/selector.transfer.parquet``
— high-quality library solutions of one library α solved as warm starts at another, ``config/selector-model.yaml``)
and prints, in Markdown:

1. the high-quality rate (converged, m_f ≥ β) and mean IPOPT iterations of a transfer by relative gap
   |α − α₀| / α and by the source solution's time of flight τ_s + τ_i + τ_f (TU), with Wilson 95 % intervals;
2. leave-one-target-α-out: for each α, the selector (:class:`amorgs.models.selector.TransferSelector`, its own
   features and settings) is fitted on the transfers that touch neither that α as target nor as source, and
   scores the transfers *into* it — what a frontier fold's selector faces.  Per α: n, the high-quality rate,
   the within-α AUC of P(high quality) and of a time-of-flight-only ranking (shorter first), Spearman's ρ of
   predicted against actual iterations, and the *selection gain*: the iterations per high-quality solution of
   the better-scored half of the candidates ÷ that of all of them (below 1: ranking pays);
3. the ten frontier points side by side: aRT per high-quality solution ÷ reuse's (95 % bootstrap) of the three
   learned generators (``reference/frontier/frontier.csv``, 3 model seeds) and of the selector
   (``reference/selector-frontier/frontier.csv``), beside the oracle bound of reuse's own candidates — bold
   where the interval lies below 1.

Reproduce with::

    python benchmarks/transfer_learnability.py            # data/models/cr3bp/selector.transfer.parquet, β = 415 kg
"""

from __future__ import annotations

import argparse
import math

import numpy as np
import pandas as pd
from scipy.stats import norm, spearmanr
from sklearn.metrics import roc_auc_score

from amorgs.models.selector import TransferSelector, training_set, transfer_labels
from amorgs.problems import get_problem
from amorgs.problems.cr3bp import BETA_KG

DEFAULT_TABLE = "data/models/cr3bp/selector.transfer.parquet"
FRONTIER = "reference/frontier/frontier.csv"
SELECTOR_FRONTIER = "reference/selector-frontier/frontier.csv"
LEARNED = ("amorgs", "continuation", "reuse_cvae")
GAP_BINS = (0.0, 0.1, 0.25, 0.5, 1.0, np.inf)
TOF_BINS = (0.0, 20.0, 30.0, 40.0, 50.0, np.inf)


def wilson(k: int, n: int, z: float = norm.ppf(0.975)) -> tuple[float, float]:
    """Wilson score interval of a proportion k / n."""
    if n == 0:
        return math.nan, math.nan
    p = k / n
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / (1 + z * z / n)
    return centre - half, centre + half


def rates_by(table: pd.DataFrame, hq: np.ndarray, values: np.ndarray, bins, label: str) -> str:
    rows = [f"| {label} | n | high quality (95 %) | mean iterations |", "|---|---|---|---|"]
    cut = pd.cut(values, bins, right=False)
    for interval, idx in pd.Series(np.arange(len(table))).groupby(cut, observed=True):
        k, n = int(hq[idx].sum()), len(idx)
        lo, hi = wilson(k, n)
        rows.append(f"| {interval.left:g}–{interval.right:g} | {n} | {k / n:.2f} ({lo:.2f}–{hi:.2f}) | "
                    f"{table['iterations'].to_numpy()[idx].mean():.0f} |")
    return "\n".join(rows)


def per_iteration(hq: np.ndarray, iterations: np.ndarray) -> float:
    """Iterations spent per high-quality solution (aRT) of a set of solves."""
    return iterations.sum() / hq.sum() if hq.any() else math.inf


def auc(labels: np.ndarray, scores: np.ndarray) -> float:
    return roc_auc_score(labels, scores) if 0 < labels.sum() < len(labels) else math.nan


def leave_one_alpha_out(table: pd.DataFrame, names, beta: float) -> pd.DataFrame:
    rows = []
    for alpha in sorted(table["alpha"].unique()):
        train = table[(table["alpha"] != alpha) & (table["source_alpha"] != alpha)]
        test = table[table["alpha"] == alpha]
        selector = TransferSelector(beta_kg=beta).fit(train, names)
        x = training_set(test, names)
        p, k_pred = selector.predict(x)
        score = selector.score(x)
        hq, k = transfer_labels(test, beta)
        tof = test[["guess_tau_s", "guess_tau_i", "guess_tau_f"]].sum(axis=1).to_numpy()
        better = score <= np.median(score)
        rows.append({"alpha": alpha, "n": len(test), "train_rows": len(train), "hq_rate": hq.mean(),
                     "auc_selector": auc(hq, p), "auc_tof_only": auc(hq, -tof),
                     "rho_iterations": spearmanr(k_pred, k).statistic,
                     "gain": per_iteration(hq[better], k[better]) / per_iteration(hq, k)})
    return pd.DataFrame(rows)


def side_by_side(frontier: pd.DataFrame, selector: pd.DataFrame) -> str:
    """Markdown: a row per frontier point (fold, α), the learned arms' and the selector's ratio to reuse."""
    def pick(table: pd.DataFrame) -> pd.DataFrame:
        return table[(table["target"] == "high_quality") & (table["unit"] == "iterations")]

    def text(row) -> str:
        t = f"{row.ratio_to_reuse:.2f} ({row.ratio_to_reuse_ci95_low:.2f}–{row.ratio_to_reuse_ci95_high:.2f})"
        return f"**{t}**" if row.ratio_to_reuse_ci95_high < 1 else t

    f, s = pick(frontier), pick(selector).replace({"run": {"selector-pilot": "loo-0.300"}})
    lines = ["| fold | α | gap | oracle ÷ reuse | " + " | ".join(LEARNED) + " | selector |",
             "|---|---|---|---|" + "---|" * (len(LEARNED) + 1)]
    for (run, alpha), cell in f.groupby(["run", "alpha"], sort=True):
        reuse = cell[cell["sampler"] == "nearest_alpha"].iloc[0]
        arms = [text(cell[cell["sampler"] == a].iloc[0]) for a in LEARNED]
        sel = s[(s["run"] == run) & np.isclose(s["alpha"], alpha) & (s["sampler"] == "selector")]
        lines.append(f"| {run} | {alpha:g} | {reuse.gap_relative:.0%} | {reuse.oracle_to_reuse:.2f} | "
                     + " | ".join(arms) + f" | {text(sel.iloc[0]) if len(sel) else '–'} |")
    return "\n".join(lines)


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--table", default=DEFAULT_TABLE)
    parser.add_argument("--beta", type=float, default=BETA_KG)
    parser.add_argument("--frontier", default=FRONTIER)
    parser.add_argument("--selector-frontier", default=SELECTOR_FRONTIER)
    args = parser.parse_args(argv)
    names = get_problem("cr3bp").variable_names
    table = pd.read_parquet(args.table)
    hq, _ = transfer_labels(table, args.beta)
    tof = table[["guess_tau_s", "guess_tau_i", "guess_tau_f"]].sum(axis=1).to_numpy()
    print(f"{args.table}: {len(table)} transfers among {table['alpha'].nunique()} α, high quality {hq.mean():.2f}\n")
    print(rates_by(table, hq, table["gap_relative"].to_numpy(), GAP_BINS, "relative gap"), end="\n\n")
    print(rates_by(table, hq, tof, TOF_BINS, "source TOF (TU)"), end="\n\n")
    cv = leave_one_alpha_out(table, names, args.beta)
    print("| α | transfers into it | training rows | high quality | AUC selector | AUC TOF only | ρ(iterations) | "
          "selection gain (better half ÷ all) |")
    print("|---|---|---|---|---|---|---|---|")
    for r in cv.itertuples():
        print(f"| {r.alpha:g} | {r.n} | {r.train_rows} | {r.hq_rate:.2f} | {r.auc_selector:.2f} | {r.auc_tof_only:.2f} "
              f"| {r.rho_iterations:.2f} | {r.gain:.2f} |")
    print(f"\nmedian over α: AUC selector {cv['auc_selector'].median():.2f}, TOF only {cv['auc_tof_only'].median():.2f}, "
          f"ρ(iterations) {cv['rho_iterations'].median():.2f}, selection gain {cv['gain'].median():.2f} "
          f"(range {cv['gain'].min():.2f}–{cv['gain'].max():.2f})")
    print()
    print(side_by_side(pd.read_csv(args.frontier), pd.read_csv(args.selector_frontier)))


if __name__ == "__main__":
    main()
