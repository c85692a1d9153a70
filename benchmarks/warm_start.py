"""Warm starts from library solutions: IPOPT's cold-start settings against settings for a start near a solution.

Takes ``--starts`` converged library solutions at a training α (the best ``--pool`` by final mass, a seeded
sample of them) and solves from each at the target α values with the default solver (``IpoptOptions()``: the
solver of ``design`` and of the ablation's warm-started arms) and with the same solver plus IPOPT settings for a
start near a solution (``NEAR_SOLUTION``: bound-active controls stay where they are instead of being pushed 1e-2
inside the box, the barrier starts small).  Same starts for both, one process, the solves in series.  Prints the
table and writes it to ``docs/performance.md`` (section ``warm_start``).  Reproduce with::

    python benchmarks/warm_start.py --from-alpha 0.5 --alphas 0.5 0.55 0.6 --starts 24
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
import pandas as pd

from amorgs.data.library import read_library
from amorgs.problems import get_problem
from amorgs.solvers.options import IpoptOptions

sys.path.insert(0, str(Path(__file__).resolve().parent))
from solve import ROOT, machine, markdown, ratio_bootstrap, write_section  # noqa: E402

#: IPOPT started near a solution: keep bound-active variables at their bounds, start the barrier small.
NEAR_SOLUTION = {"mu_init": 1e-6, "bound_push": 1e-8, "bound_frac": 1e-8, "bound_mult_init_method": "mu-based"}
SOLVERS = {"default solver (cold-start IPOPT settings)": IpoptOptions(),
           "default solver + near-solution IPOPT settings": IpoptOptions(ipopt_options=NEAR_SOLUTION)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--from-alpha", type=float, default=0.5, help="the library α whose solutions are the starts")
    ap.add_argument("--alphas", type=float, nargs="+", default=[0.5, 0.55, 0.6], help="the α solved at")
    ap.add_argument("--starts", type=int, default=24)
    ap.add_argument("--pool", type=int, default=400, help="sample the starts from this many best solutions")
    ap.add_argument("--seed", type=int, default=2026)
    args = ap.parse_args()
    cmd = "python benchmarks/warm_start.py " + " ".join(sys.argv[1:])
    problem = get_problem("cr3bp")
    library = read_library(ROOT / "data" / "library", "cr3bp", f"{args.from_alpha:.3f}")
    best = library[library.converged].sort_values("objective").head(args.pool)
    chosen = best.sample(args.starts, random_state=args.seed)
    starts = chosen[list(problem.variable_names)].to_numpy()
    rows, raw = [], []
    for alpha in args.alphas:
        for label, options in SOLVERS.items():
            solver = problem.make_local_solver(options)
            records = [solver.solve(x, alpha) for x in starts]
            raw += [{"variant": label, "alpha": alpha, "start": i, "converged": r.converged, "cpu_s": r.cpu_s,
                     "iterations": r.iterations} for i, r in enumerate(records)]
            verified = [r for r in records if r.converged]
            cpu = sum(r.cpu_s for r in records)
            rows.append({"solver": label, "from α": f"{args.from_alpha:g}", "alpha": f"{alpha:g}",
                         "starts": len(records), "verified": len(verified),
                         "median iterations": float(np.median([r.iterations for r in records])),
                         "CPU (s)": cpu, "verified per core-hour": len(verified) / (cpu / 3600),
                         "mean m_f of verified (kg)": (float(np.mean([r.x[3] for r in verified])) if verified
                                                       else float("nan"))})
            print(rows[-1], flush=True)
    text = (f"Command: `{cmd}` — {machine()}; the best {args.pool} converged library solutions at α = "
            f"{args.from_alpha}, {args.starts} sampled (seed {args.seed}); one process, the solves in series.\n\n"
            + markdown(rows))
    cold, near = SOLVERS
    ratios = [{**r, "alpha": f"{r['alpha']:g}"} for r in ratio_bootstrap(pd.DataFrame(raw), {near: cold}, args.seed)]
    text += ("\nRatio of verified per core-hour (near-solution / cold-start settings) on the same starts; 95 % "
             f"interval from a paired bootstrap over starts (seed {args.seed}; `solve.ratio_bootstrap`):\n\n"
             + markdown(ratios))
    print(text)
    write_section("warm_start", text)


if __name__ == "__main__":
    main()
