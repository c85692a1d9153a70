"""What the independent re-propagation (spec §6) costs a solve, with the array and the constant-thrust right-hand side.

Every solver success is re-propagated with scipy's DOP853 at rtol = atol = 1e-12 before it counts as converged
(``IpoptSolver.solve``), and the library's gate does it once more for every row it admits.  ``SolveRecord.cpu_s``
times the ``nlpsol`` call alone, so the throughput tables elsewhere in docs/performance.md leave this cost out.
For ``--starts`` uniform starts per α (``default_rng(seed)``, the library config's solver, one process), this
script measures each start's whole CPU (``time.process_time`` around ``solve``: IPOPT plus the re-propagation with
today's :func:`~amorgs.problems.cr3bp.dynamics.constant_thrust_rhs`), and re-propagates each success once more
with the array :func:`~amorgs.problems.cr3bp.dynamics.powered_rhs` (the code before it) and once with today's,
interleaved; the two defects must agree bit for bit.  "Before" charges each start its solve CPU with the array
re-propagation instead of today's.  Verified per core-hour = converged starts ÷ CPU; the ratio after ÷ before has
a paired bootstrap over starts (2000 resamples, the seed).  Prints the table and writes it to
``docs/performance.md`` (section ``verification``).  Reproduce with::

    python benchmarks/verification.py --starts 20 --alphas 1.0 0.5 0.1
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np
from scipy.integrate import solve_ivp

from amorgs.config import load_config
from amorgs.problems import get_problem
from amorgs.problems.cr3bp import propagation
from amorgs.problems.cr3bp.dynamics import powered_rhs

sys.path.insert(0, str(Path(__file__).resolve().parent))
from solve import machine, markdown, write_section  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
BOOTSTRAP = 2000


def _array_arc(state, duration, thrust_vec_nd, mdot_per_thrust, dense, rtol, atol):
    """``propagation._arc`` as it was: :func:`powered_rhs` with the thrust passed per call."""
    if duration == 0.0:
        return np.array([0.0]), state[:, None]
    sol = solve_ivp(powered_rhs, (0.0, duration), state, method="DOP853", rtol=rtol, atol=atol,
                    args=(thrust_vec_nd, mdot_per_thrust))
    if not sol.success:
        raise FloatingPointError(sol.message)
    return sol.t, sol.y


def _timed_defect(problem, x, alpha, arc) -> tuple[np.ndarray, float]:
    today = propagation._arc
    propagation._arc = arc
    try:
        t0 = time.process_time()
        d = propagation.match_defect(x, alpha, problem.initial_state, problem.terminal_state)
        return d, time.process_time() - t0
    finally:
        propagation._arc = today


def measure(alpha: float, starts: int, seed: int) -> list[dict]:
    """One row per start: CPU of the whole solve (s), of IPOPT alone, and of the two re-propagations."""
    problem = get_problem("cr3bp")
    solver = problem.make_local_solver(load_config(ROOT / "config" / "library.yaml").problems.cr3bp.solver)
    guesses = problem.sample_uniform(alpha, starts, np.random.default_rng(seed))
    solver.solve(guesses[0], alpha)  # load the compiled NLP outside the timings
    rows = []
    for i, guess in enumerate(guesses):
        t0 = time.process_time()
        record = solver.solve(guess, alpha)
        whole = time.process_time() - t0
        row = {"alpha": alpha, "start": i, "converged": record.converged, "whole_s": whole, "ipopt_s": record.cpu_s,
               "verify_after_s": 0.0, "verify_before_s": 0.0}
        if record.solver_success:
            # interleaved: the order alternates from start to start
            runs = [("after", propagation._arc), ("before", _array_arc)]
            for name, arc in runs if i % 2 else runs[::-1]:
                d, dt = _timed_defect(problem, record.x, alpha, arc)
                row[f"verify_{name}_s"], row[f"defect_{name}"] = dt, d
            if not np.array_equal(row.pop("defect_after"), row.pop("defect_before")):
                raise SystemExit(f"α = {alpha}, start {i}: the two right-hand sides give different defects")
        rows.append(row)
    return rows


def summarize(rows: list[dict], seed: int) -> dict:
    conv = np.array([r["converged"] for r in rows], float)
    after = np.array([r["whole_s"] for r in rows])
    before = after - np.array([r["verify_after_s"] for r in rows]) + np.array([r["verify_before_s"] for r in rows])
    succ = [r for r in rows if r["verify_before_s"] > 0]
    idx = np.random.default_rng(seed).integers(0, len(rows), size=(BOOTSTRAP, len(rows)))
    boot = before[idx].sum(axis=1) / after[idx].sum(axis=1)  # same converged count: the rate ratio is the CPU ratio
    lo, hi = np.quantile(boot, [0.025, 0.975])
    vb = np.mean([r["verify_before_s"] for r in succ]) if succ else float("nan")
    va = np.mean([r["verify_after_s"] for r in succ]) if succ else float("nan")
    return {"alpha": rows[0]["alpha"], "n": len(rows), "successes re-propagated": len(succ),
            "verified": int(conv.sum()),
            "re-propagation ms, before": 1000 * vb, "re-propagation ms, after": 1000 * va,
            "its share of the CPU, before %": 100 * sum(r["verify_before_s"] for r in rows) / before.sum(),
            "its share, after %": 100 * sum(r["verify_after_s"] for r in rows) / after.sum(),
            "verified per core-hour, before": 3600 * conv.sum() / before.sum(),
            "verified per core-hour, after": 3600 * conv.sum() / after.sum(),
            "verified per core-hour, after ÷ before": f"{before.sum() / after.sum():.2f}",
            "95 % interval": f"{lo:.2f}–{hi:.2f}"}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--starts", type=int, default=20)
    ap.add_argument("--alphas", type=float, nargs="+", default=[1.0, 0.5, 0.1])
    ap.add_argument("--seed", type=int, default=2026)
    ap.add_argument("--note", default="", help="what else ran on the machine (written beside the table)")
    args = ap.parse_args()
    cmd = f"python benchmarks/verification.py --starts {args.starts} --alphas {' '.join(map(str, args.alphas))}"
    table = []
    for alpha in args.alphas:
        table.append(summarize(measure(alpha, args.starts, args.seed), args.seed))
        print(table[-1], flush=True)
    text = (f"Command: `{cmd}` — {machine()}; seed {args.seed}; one process, CPU time; the library config's solver; "
            f"the two re-propagations of each success agree bit for bit. {args.note}\n\n" + markdown(table))
    print(text)
    write_section("verification", text)


if __name__ == "__main__":
    main()
