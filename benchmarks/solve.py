"""Benchmark of the CR3BP local solver: verified converged solutions per core-hour.

Runs ``--starts`` uniform starts (spec §6) at each α on ONE core (one worker process, solves in series),
with the default solver options unless a variant is chosen, and prints and writes the table to
``docs/performance.md`` (section between the BENCHMARK markers).  Reproduce with::

    python benchmarks/solve.py                      # the default solver, 50 starts × α ∈ {0.1, 0.5, 1.0}
    python benchmarks/solve.py --variants --starts 12   # the comparison of transcription/solver variants
    python benchmarks/solve.py --scaling            # 1 → 2 worker processes

Throughput counts solve CPU time (``time.process_time`` inside the worker), not the one-off JIT build,
which is reported separately.  The iteration-cap table is computed from the same solves: a start that
converged in k ≤ cap iterations converges identically under that cap (IPOPT is deterministic), every other
start is charged cap × its own measured cost per iteration.
"""

from __future__ import annotations

import argparse
import json
import platform
import re
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd

from amorgs.solvers.multistart import run_multistart

ROOT = Path(__file__).resolve().parents[1]
DOC = ROOT / "docs" / "performance.md"
VARIANTS = {
    "default (single shooting, L-BFGS 30, RK8 24/seg (×√(0.3/α) below 0.3) + 320/coast)": {},
    "no α step scaling (24/seg at every α)": {"transcription": {"step_scaling_alpha": 0.0}},
    "fewer steps (RK8 12/seg + 240/coast)": {"transcription": {"steps_per_segment": 12, "steps_per_coast": 240}},
    "looser tolerances (tol 1e-5, acceptable 1e-3 × 5)": {"tol": 1e-5, "acceptable_tol": 1e-3, "acceptable_iter": 5},
    "L-BFGS history 10": {"lbfgs_memory": 10},
    "internal multiple shooting (8 coast pieces + every segment), L-BFGS": {
        "transcription": {"multiple_shooting": True}
    },
}


def summarize(df: pd.DataFrame) -> dict:
    conv = df[df.converged]
    cpu_h = df.cpu_s.sum() / 3600
    q = lambda s: "/".join(f"{v:.1f}" for v in np.quantile(s, [0.25, 0.5, 0.75])) if len(s) else "–"
    iters = df.iterations.sum()
    return {
        "alpha": df.alpha.iloc[0],
        "n": len(df),
        "verified %": 100 * len(conv) / len(df),
        "solver-only %": 100 * df.solver_success.mean(),
        "failed verification": int((df.solver_success & ~df.converged).sum()),
        "wall q25/50/75 converged (s)": q(conv.wall_s),
        "wall q25/50/75 all (s)": q(df.wall_s),
        "median iters converged": float(conv.iterations.median()) if len(conv) else float("nan"),
        "ms/iter": 1000 * df.cpu_s.sum() / max(iters, 1),
        "verified per core-hour": len(conv) / cpu_h if cpu_h else float("nan"),
        "best m_f (kg)": conv.m_f.max() if len(conv) else float("nan"),
        "TOF of converged (TU)": q(conv.tau_s + conv.tau_i + conv.tau_f),
        "max verify defect": conv.verify_defect.max() if len(conv) else float("nan"),
    }


def cap_table(df: pd.DataFrame, caps=(150, 300, 500, 750, 1000)) -> list[dict]:
    per_iter = df.cpu_s / df.iterations.clip(lower=1)
    rows = []
    for cap in caps:
        if cap > df.iterations.max() and cap > 1000:
            continue
        ok = df.converged & (df.iterations <= cap)
        cost = np.where(df.iterations <= cap, df.cpu_s, cap * per_iter).sum()
        rows.append({"alpha": df.alpha.iloc[0], "iteration cap": cap, "verified %": 100 * ok.mean(),
                     "verified per core-hour": ok.sum() / (cost / 3600)})
    return rows


def markdown(rows: list[dict]) -> str:
    df = pd.DataFrame(rows)
    fmt = lambda v: f"{v:.3g}" if isinstance(v, float) and abs(v) < 1e-2 and v != 0 else (f"{v:.1f}" if isinstance(v, float) else str(v))
    head = "| " + " | ".join(df.columns) + " |\n|" + "---|" * len(df.columns) + "\n"
    return head + "".join("| " + " | ".join(fmt(v) for v in r) + " |\n" for r in df.itertuples(index=False))


def write_section(name: str, text: str) -> None:
    DOC.parent.mkdir(exist_ok=True)
    doc = DOC.read_text() if DOC.exists() else "# Performance\n"
    begin, end = f"<!-- BENCHMARK:{name}:BEGIN -->", f"<!-- BENCHMARK:{name}:END -->"
    block = f"{begin}\n{text}\n{end}"
    if begin in doc:
        doc = re.sub(re.escape(begin) + ".*?" + re.escape(end), lambda _: block, doc, flags=re.S)
    else:
        doc = doc.rstrip() + "\n\n" + block + "\n"
    DOC.write_text(doc)


def machine() -> str:
    import casadi

    return f"{platform.processor() or platform.machine()}, Python {platform.python_version()}, casadi {casadi.__version__}"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--starts", type=int, default=50)
    ap.add_argument("--alphas", type=float, nargs="+", default=[0.1, 0.5, 1.0])
    ap.add_argument("--seed", type=int, default=2026)
    ap.add_argument("--variants", action="store_true", help="compare the variants instead of the default")
    ap.add_argument("--scaling", action="store_true", help="measure 1 → 2 worker scaling")
    ap.add_argument("--raw", type=Path, default=None, help="also save the raw rows as Parquet")
    args = ap.parse_args()
    cmd = "python benchmarks/solve.py " + " ".join(sys.argv[1:])

    if args.scaling:
        rows = []
        for workers in (1, 2):
            t0 = time.perf_counter()
            df = run_multistart("cr3bp", 1.0, args.seed, args.starts, workers=workers, progress=False)
            rows.append({"workers": workers, "starts": args.starts, "wall (s)": time.perf_counter() - t0,
                         "solve CPU (s)": df.cpu_s.sum()})
        rows[1]["speed-up"] = rows[0]["wall (s)"] / rows[1]["wall (s)"]
        text = f"Command: `{cmd}` — {machine()}; wall time includes each worker's JIT build.\n\n" + markdown(rows)
        print(text)
        write_section("scaling", text)
        return

    variants = VARIANTS if args.variants else {"default": {}}
    rows, caps, raw = [], [], []
    for label, opts in variants.items():
        for alpha in args.alphas:
            df = run_multistart("cr3bp", alpha, args.seed, args.starts, workers=1, solver_options=opts, progress=False)
            df["variant"] = label
            raw.append(df)
            row = {"variant": label, **summarize(df)} if args.variants else summarize(df)
            rows.append(row)
            caps += cap_table(df)
            print(json.dumps(row, default=str), flush=True)
    name = "variants" if args.variants else "default"
    text = f"Command: `{cmd}` — {machine()}; seed {args.seed}; one worker process.\n\n" + markdown(rows)
    if not args.variants:
        text += "\nIteration cap (computed from the same solves, see the script's docstring):\n\n" + markdown(caps)
    print(text)
    write_section(name, text)
    if args.raw:
        pd.concat(raw).to_parquet(args.raw)


if __name__ == "__main__":
    main()
