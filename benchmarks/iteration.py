"""Where an IPOPT iteration goes: CasADi's per-function CPU times of real solves, per iteration.

For each solver (the default, the library config's, and ``--mumps``'s candidates) and α, solves the same
uniform starts in this process, one after another, and splits each solve's CPU time (``SolveRecord.cpu_s``,
the ``nlpsol`` call only) into the constraint Jacobian (``nlp_jac_g``), the constraints (``nlp_g``), the
objective and its gradient, and the rest: IPOPT's own work (the KKT factorisations and the L-BFGS update).
Prints the table and writes it to ``docs/performance.md`` (section ``iteration``).  Reproduce with::

    python benchmarks/iteration.py --starts 12 --alphas 1.0 0.1
    python benchmarks/iteration.py --per-call --alphas 1.0 0.1      # section iteration_calls

``--per-call`` times the two functions IPOPT calls most, the constraints and the constraint Jacobian
(``nlp_g`` and ``nlp_jac_g`` of the built solver, compiled as the solver runs them), per call at ``--starts``
uniform points (best of 5 rounds of 10 calls per point, CPU time): the measure of a change to how they are
evaluated, run on the code before and after it.

The solves are deterministic, so the iterations repeat to the unit from run to run; the times move with the load.
"""

from __future__ import annotations

import argparse
import sys
import time

import numpy as np

from amorgs.problems import get_problem

sys.path.insert(0, str(__import__("pathlib").Path(__file__).resolve().parent))
from solve import DEFAULTS, MUMPS, machine, markdown, write_section  # noqa: E402

#: The default block's two solvers, then ``--mumps``'s candidates (each set of options once).
SOLVERS = {**DEFAULTS, **{k: v for k, v in MUMPS.items() if v not in DEFAULTS.values()}}


def profile(options, alpha: float, guesses: np.ndarray) -> dict:
    """Per-iteration CPU (ms) of each part, summed over the solves of ``guesses`` at ``alpha``."""
    problem = get_problem("cr3bp")
    solver = problem.make_local_solver(options)
    solver.build(alpha)
    nlpsol = solver._nlp(alpha)[1]
    total = jac = g = f = 0.0
    iterations = converged = 0
    per_solve = []
    for x0 in guesses:
        record = solver.solve(x0, alpha)
        stats = nlpsol.stats()
        iterations += int(stats["iter_count"])
        converged += bool(record.converged)
        total += record.cpu_s
        jac += stats["t_proc_nlp_jac_g"]
        g += stats["t_proc_nlp_g"]
        f += stats["t_proc_nlp_f"] + stats["t_proc_nlp_grad_f"]
        per_solve.append(record.cpu_s / max(int(stats["iter_count"]), 1))
    ms = lambda seconds: 1000 * seconds / max(iterations, 1)  # noqa: E731
    return {"alpha": alpha, "starts": len(guesses), "verified": converged, "iterations": iterations,
            "ms/iter": ms(total), "median ms/iter": 1000 * float(np.median(per_solve)),
            "constraint Jacobian": ms(jac), "constraints": ms(g), "objective + gradient": ms(f),
            "IPOPT's own": ms(total - jac - g - f)}


def per_call(options, alpha: float, points: np.ndarray) -> dict:
    """CPU ms per call of the built solver's ``nlp_g`` and ``nlp_jac_g`` at ``points`` (stored layout)."""
    problem = get_problem("cr3bp")
    solver = problem.make_local_solver(options)
    tr, nlpsol = solver._nlp(alpha)[:2]
    w = [tr.to_internal(x, alpha) for x in points]
    row = {"alpha": alpha, "points": len(points)}
    for name in ("nlp_g", "nlp_jac_g"):
        f = nlpsol.get_function(name)
        for x in w:
            f(x, alpha)
        rounds = []
        for _ in range(5):
            t0 = time.process_time()
            for x in w:
                for _ in range(10):
                    f(x, alpha)
            rounds.append((time.process_time() - t0) / (10 * len(w)))
        row[f"{name} (ms/call)"] = f"{1000 * min(rounds):.3f}"
    return row


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--starts", type=int, default=12)
    ap.add_argument("--alphas", type=float, nargs="+", default=[1.0, 0.1])
    ap.add_argument("--seed", type=int, default=2026)
    ap.add_argument("--per-call", action="store_true", help="time nlp_g and nlp_jac_g per call instead of solves")
    args = ap.parse_args()
    cmd = "python benchmarks/iteration.py " + " ".join(sys.argv[1:])
    problem = get_problem("cr3bp")
    # --per-call: the two functions per call, the default block's solvers; else real solves, every solver.
    measure, solvers = (per_call, DEFAULTS) if args.per_call else (profile, SOLVERS)
    rows = []
    for alpha in args.alphas:
        points = problem.sample_uniform(alpha, args.starts, np.random.default_rng(args.seed))
        for label, options in solvers.items():
            rows.append({"solver": label, **measure(options, alpha, points)})
            print(rows[-1], flush=True)
    if args.per_call:
        what = "one process; CPU ms per call, best of 5 rounds of 10 calls at each point"
    else:
        what = ("one process, the solves in series; CPU ms per IPOPT iteration (CasADi's `t_proc_nlp_*` statistics; "
                "IPOPT's own = the solve's CPU less those)")
    text = f"Command: `{cmd}` — {machine()}; seed {args.seed}; {what}.\n\n" + markdown(rows)
    print(text)
    write_section("iteration_calls" if args.per_call else "iteration", text)


if __name__ == "__main__":
    main()
