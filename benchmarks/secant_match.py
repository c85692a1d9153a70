"""Before any solve: does the continuation arm put its guesses nearer the target α's solutions than reuse?

For each fold of the frontier (training α = the library α of the fold, test α held out), both arms draw the
whole pool of the nearest training α once (the same rows, in the same order: the continuation arm draws as
``nearest_alpha`` does, then moves each row by its secant).  Each guess is scored by its distance to the
nearest high-quality library solution *at the test α* — the answer neither arm may see — in the layout the
continuation arm matches in: (τ_s, τ_i, τ_f, m_f, Cartesian throttle vectors), each divided by its box width,
root-mean-square over the 64 coordinates (dimensionless).  Printed per fold: pool size, median distance of
the reused and of the moved guesses, and the share of guesses the secant moved closer / farther.  A smaller
distance is no promise of fewer IPOPT iterations; the frontier's solves measure that.  Reproduce with::

    python benchmarks/secant_match.py            # data/library, β = 415 kg
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from amorgs.ablation.frontier import leave_one_out, sparse_grid
from amorgs.ablation.statistics import high_quality
from amorgs.alphas import alpha_label
from amorgs.data.library import read_library
from amorgs.frontier import library_alphas
from amorgs.models.cr3bp_models import vanilla_vectors
from amorgs.models.samplers import ContinuationSampler, NearestAlphaSampler
from amorgs.problems import get_problem

LIBRARY = "data/library"
BETA = 415.0


def main() -> None:
    problem = get_problem("cr3bp")
    names = list(problem.variable_names)
    alphas = library_alphas(LIBRARY)
    tables = {a: read_library(LIBRARY, "cr3bp", alpha_label(a)) for a in alphas}
    hq = {a: t[high_quality(t, BETA)] for a, t in tables.items()}
    scale = np.concatenate([(problem.upper - problem.lower)[:4], np.full(len(names) - 4, 2.0)])
    folds = [leave_one_out(alphas, a) for a in (0.1, 0.5, 0.85, 1.0)] + [sparse_grid(alphas, 3)]
    print("| fold | test α | a₀ → a₁ | pool | median distance, reused | moved | moved closer | moved farther |")
    print("|---|---|---|---|---|---|---|---|")
    for fold in folds:
        train = {a: hq[a] for a in fold.train}
        pool = pd.concat(train.values(), ignore_index=True)
        for alpha in fold.test:
            reuse = NearestAlphaSampler(problem, pool, fold.train)
            move = ContinuationSampler(problem, pool, fold.train)
            a0, n = reuse.pool(alpha)
            truth = vanilla_vectors(hq[alpha][names].to_numpy()) / scale
            d = {}
            for name, sampler in (("reused", reuse), ("moved", move)):
                v = vanilla_vectors(sampler.sample(alpha, n, np.random.default_rng(0))) / scale
                d[name] = np.sqrt(((v[:, None, :] - truth[None]) ** 2).mean(-1)).min(1)
            closer, farther = np.mean(d["moved"] < d["reused"] - 1e-12), np.mean(d["moved"] > d["reused"] + 1e-12)
            print(f"| {fold.name} | {alpha:g} | {a0:g} → {move.partner(alpha):g} | {n} | {np.median(d['reused']):.3f} | "
                  f"{np.median(d['moved']):.3f} | {closer:.0%} | {farther:.0%} |")


if __name__ == "__main__":
    main()
