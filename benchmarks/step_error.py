"""Integration error of the NLP's RK8 grid at the library's verified solutions, per α and steps per segment.

For a sample of verified converged library solutions at each α, the single-shooting match-point defect of
the stored vector is computed with ``steps`` RK8 steps per thrust segment (coasts as the default
transcription reads them) and with a 200-step reference grid; the error is the max-abs difference over the 7
components (DU, VU, tonnes).  A solution converged on a grid closes there to 1e-8, so its independent
DOP853 re-propagation defect is about this error: a grid whose error exceeds the verification tolerance
(1e-5) at a solution loses that solution to the check.  The law of the default grid (24 steps per segment
at α ≥ 0.3, ⌈24·√(0.3/α)⌉ below) is the first count of each α.  Reproduce with::

    python benchmarks/step_error.py            # 400 solutions per α, writes docs/performance.md (step_error)
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
import pandas as pd

from amorgs.data.library import read_library
from amorgs.problems import get_problem
from amorgs.solvers.options import TranscriptionOptions

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(Path(__file__).resolve().parent))
from solve import machine, markdown, write_section  # noqa: E402

#: α → step counts per thrust segment to test (the default law's count first).
GRIDS = {0.1: [42, 36, 32, 30, 14], 0.13: [37, 33, 30, 14], 0.2: [30, 28, 26, 24, 14], 0.3: [24, 22, 20, 14],
         0.6: [24, 20, 14], 1.0: [24, 20, 14, 12]}
REFERENCE_STEPS = 200


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--per-alpha", type=int, default=400, help="verified solutions sampled per α")
    ap.add_argument("--library-dir", type=Path, default=ROOT / "data" / "library")
    ap.add_argument("--seed", type=int, default=0, help="seed of the sample")
    args = ap.parse_args()
    problem = get_problem("cr3bp")
    names = list(problem.variable_names)
    grid = lambda n: problem.transcribe(TranscriptionOptions(steps_per_segment=n, step_scaling_alpha=0.0))
    reference = grid(REFERENCE_STEPS)
    rows = []
    for alpha, counts in GRIDS.items():
        lib = read_library(args.library_dir, "cr3bp", f"{alpha:.3f}")
        conv = lib[lib.converged]
        sample = conv.sample(n=min(args.per_alpha, len(conv)), random_state=args.seed)
        grids = {n: grid(n) for n in counts}
        errors = {n: [] for n in counts}
        for x in sample[names].to_numpy():
            ref = reference.match_defect(x, alpha)
            for n, tr in grids.items():
                errors[n].append(float(np.max(np.abs(tr.match_defect(x, alpha) - ref))))
        for n in counts:
            e = np.array(errors[n])
            g = lambda v: f"{v:.2g}"
            rows.append({"alpha": f"{alpha:g}", "steps per segment": n, "n": len(e),
                         "τ_s q50/q90 (TU)": "/".join(f"{v:.1f}" for v in np.quantile(sample.tau_s, [0.5, 0.9])),
                         "error q50": g(np.median(e)), "error q90": g(np.quantile(e, 0.9)),
                         "error q99": g(np.quantile(e, 0.99)), "error max": g(e.max()),
                         "> 1e-6": int((e > 1e-6).sum()), "> 1e-5 (would fail the check)": int((e > 1e-5).sum())})
            print(rows[-1], flush=True)
    cmd = " ".join(["python benchmarks/step_error.py", *sys.argv[1:]])
    text = (f"Command: `{cmd}` — {machine()}; sample seed {args.seed}; reference grid {REFERENCE_STEPS} steps per "
            "segment.\n\n" + markdown(rows))
    print(text)
    write_section("step_error", text)


if __name__ == "__main__":
    pd.set_option("display.width", 200)
    main()
