"""After the solves: does a guess close to a known solution of the test α solve better?

The continuation and reuse-conditioned arms move reuse's guesses towards where the test α's solutions are
expected to lie (``benchmarks/secant_match.py``: the secant does put them closer).  Whether that helps depends
on whether closeness predicts the solve.  For every start of the committed frontier folds
(``reference/frontier/<fold>/starts.parquet``) of the reuse-based arms, the guess is scored by its distance to
the nearest high-quality library solution *at the test α* (the answer no arm may see; the library read now,
which may have grown since the fold ran) in the layout of ``secant_match.py`` — (τ_s, τ_i, τ_f, m_f, Cartesian
throttle vectors), each divided by its box width, root-mean-square over the 64 coordinates — and compared
with the start's outcome: high quality (converged, m_f ≥ β) and IPOPT iterations.

Printed per (fold, test α, arm): n, the median distance, the high-quality rate of the nearer and of the farther
half of the starts (split at the median distance) with the p-value of Fisher's exact test between the halves,
and Spearman's ρ between distance and iterations (positive: nearer guesses solve in fewer iterations).
Reproduce with::

    python benchmarks/closeness_vs_outcome.py            # reference/frontier, data/library, β = 415 kg
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
from scipy.stats import fisher_exact, spearmanr

from amorgs.ablation.statistics import high_quality
from amorgs.alphas import alpha_label
from amorgs.data.library import read_library
from amorgs.models.baselines import vanilla_vectors
from amorgs.problems import get_problem

FRONTIER = Path("reference/frontier")
LIBRARY = "data/library"
BETA = 415.0
ARMS = ("nearest_alpha", "continuation", "reuse_cvae")


def main() -> None:
    problem = get_problem("cr3bp")
    names = list(problem.variable_names)
    scale = np.concatenate([(problem.upper - problem.lower)[:4], np.full(len(names) - 4, 2.0)])
    print("| fold | test α | arm | n | median distance | HQ rate, nearer half | farther half | Fisher p | "
          "Spearman ρ (distance, iterations) |")
    print("|---|---|---|---|---|---|---|---|---|")
    for fold in sorted(p.parent for p in FRONTIER.glob("*/starts.parquet")):
        starts = pd.read_parquet(fold / "starts.parquet")
        for alpha, at in starts.groupby("alpha"):
            library = read_library(LIBRARY, "cr3bp", alpha_label(alpha))
            truth = vanilla_vectors(library[high_quality(library, BETA)][names].to_numpy()) / scale
            for arm in (a for a in ARMS if a in set(at["sampler"])):
                rows = at[at["sampler"] == arm]
                guesses = vanilla_vectors(rows[[f"guess_{n}" for n in names]].to_numpy()) / scale
                d = np.sqrt(((guesses[:, None, :] - truth[None]) ** 2).mean(-1)).min(1)
                ok = high_quality(rows, BETA).to_numpy()
                near = d <= np.median(d)
                table = [[ok[near].sum(), (~ok[near]).sum()], [ok[~near].sum(), (~ok[~near]).sum()]]
                rho = spearmanr(d, rows["iterations"].to_numpy())[0]
                print(f"| {fold.name} | {alpha:g} | {arm} | {len(rows)} | {np.median(d):.3f} | {ok[near].mean():.2f} | "
                      f"{ok[~near].mean():.2f} | {fisher_exact(table)[1]:.2g} | {rho:+.2f} |")


if __name__ == "__main__":
    main()
