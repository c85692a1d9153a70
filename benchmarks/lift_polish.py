"""Is a lifted record a local optimum at the α it is lifted to, and does a local solve from it climb? (issue 41)

A trajectory flown at maximum thrust α_s with throttles ρ flies unchanged at α_t with ρ' = ρ α_s / α_t where every
ρ' ≤ 1 (:func:`amorgs.data.best_known.lift`).  In terms of the thrust α ρ the two NLPs differ only in the upper
bound α on it: where the throttle never reaches 1 at α_s that bound is inactive, so a KKT point at α_s stays one at
every higher α_t — the lifted trajectory is a local optimum there, nothing to climb.  Where ρ reaches 1 somewhere,
more thrust is allowed at α_t and a local solve may climb.

For every α of the record (and ``--alphas``): the best known trajectory there (:func:`best_entry_lifted`), its
source α and whether its throttle saturates there (max ρ at α_s ≥ 1 − 1e-6), then one re-solve from it with the
global-search studies' solver options (``reference/global-search/sparse-5/alpha=0.600/study.json``: L-BFGS,
1000-iteration cap; a cold IPOPT start) and one with the warm-start options of ``mbh_warm``
(:data:`amorgs.solvers.basin_hopping.WARM_HOP_IPOPT`).  Prints a markdown table: m_f (kg) and IPOPT iterations
of each re-solve, ✓ where it converged and passed the independent check.  Nothing is written.  Reproduce with::

    python benchmarks/lift_polish.py
"""

from __future__ import annotations

import argparse
import json
import math

import numpy as np

from amorgs.alphas import alpha_label
from amorgs.data import best_known as bk
from amorgs.problems import get_problem
from amorgs.solvers.basin_hopping import hop_solver_options
from amorgs.solvers.options import IpoptOptions, as_options

STUDY = "reference/global-search/sparse-5/alpha=0.600/study.json"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--record", default=bk.DEFAULT_PATH)
    parser.add_argument("--alphas", type=float, nargs="*", default=[], help="more α (N) beside the record's")
    args = parser.parse_args()

    record = bk.read_record(args.record)
    options = as_options(IpoptOptions, json.load(open(STUDY))["solver"])
    problem = get_problem("cr3bp")
    cold = problem.make_local_solver(options)
    warm = problem.make_local_solver(hop_solver_options("mbh_warm", options))
    alphas = sorted({float(e["alpha"]) for e in record["alphas"].values()} | set(args.alphas))
    print("| α (N) | best known (kg) | from α | saturates there | cold re-solve: m_f, iterations | "
          "warm re-solve: m_f, iterations |")
    print("|---|---|---|---|---|---|")
    for alpha in alphas:
        entry = bk.best_entry_lifted(record, alpha)
        if entry is None:
            continue
        x = np.asarray(entry["x"], float)
        alpha_s = float(entry["source"].get("from_alpha", alpha)) if entry["source"].get("kind") == "lift" else alpha
        saturated = float(x[6::3].max()) * alpha / alpha_s >= 1 - 1e-6  # the throttle at α_s
        cells = []
        for solver in (cold, warm):
            r = solver.solve(x, alpha)
            m_f = -r.objective if math.isfinite(r.objective) else math.nan
            cells.append(f"{m_f:.3f}{' ✓' if r.converged else ''}, {r.iterations}")
        print(f"| {alpha_label(alpha)} | {entry['m_f_kg']:.3f} | {alpha_label(alpha_s)} | "
              f"{'yes' if saturated else 'no'} | {cells[0]} | {cells[1]} |", flush=True)


if __name__ == "__main__":
    main()
