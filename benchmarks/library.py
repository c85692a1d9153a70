"""Production throughput of the CR3BP solver, measured on the committed library: verified per core-hour.

`benchmarks/solve.py` times a few dozen starts per α on one core; the library holds thousands of solves made
by ``amorgs library-grow`` with the default solver (uniform starts, spec §6), each with its own solve CPU
time (``cpu_s``, ``time.process_time`` inside the worker, so machine load and ``nice`` barely change it).
This script reads every library row through the manifest check (``amorgs.data.library.read_library``) and
prints, per α and in total: solves, verified converged, CPU-hours, **verified per core-hour** with a seeded
bootstrap 95 % interval (rows resampled within α), the CPU share of unconverged solves and the median
iterations; then writes the table to ``docs/performance.md`` (section ``library``).  Reproduce with::

    python benchmarks/library.py                 # data/library, 2000 bootstrap resamples, seed 2026

Issue 9's targets are ≥ 2000 verified per core-hour at α = 1.0 and ≥ 800 at α = 0.1.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
import pandas as pd

from amorgs.data.library import read_library, read_manifest

sys.path.insert(0, str(Path(__file__).resolve().parent))
from solve import markdown, write_section  # noqa: E402  (the same table format and docs section writer)


def throughput(df: pd.DataFrame, rng: np.random.Generator, n_boot: int) -> dict:
    """One row: the counts, CPU and verified per core-hour of the solves in ``df`` (bootstrap 95 %)."""
    conv = df["converged"].to_numpy(dtype=bool)
    cpu = df["cpu_s"].to_numpy(dtype=float)
    ok = np.isfinite(cpu)  # a crashed or killed worker's row has no CPU time
    conv, cpu = conv[ok], cpu[ok]
    rate = lambda c, s: c.sum() / (s.sum() / 3600.0)
    idx = rng.integers(0, len(cpu), size=(n_boot, len(cpu)))
    boot = conv[idx].sum(axis=1) / (cpu[idx].sum(axis=1) / 3600.0)
    low, high = np.percentile(boot, [2.5, 97.5])
    return {
        "solves": int(len(df)),
        "verified": int(conv.sum()),
        "verified %": 100.0 * conv.mean(),
        "CPU-hours": cpu.sum() / 3600.0,
        "verified per core-hour": rate(conv, cpu),
        "95 % CI": f"{low:.0f}–{high:.0f}",
        "CPU share of unconverged %": 100.0 * cpu[~conv].sum() / cpu.sum(),
        "median CPU s per solve": float(np.median(cpu)),
        "median iters converged": float(np.median(df.loc[df["converged"].astype(bool), "iterations"])),
        "no CPU time (crashed)": int((~ok).sum()),
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--library-dir", type=Path, default=Path("data/library"))
    ap.add_argument("--seed", type=int, default=2026)
    ap.add_argument("--n-boot", type=int, default=2000)
    args = ap.parse_args()
    manifest = read_manifest(args.library_dir, "cr3bp")
    if manifest is None:
        sys.exit(f"{args.library_dir / 'cr3bp'}: no library manifest")
    rng = np.random.default_rng(args.seed)
    tables = {f"{e['alpha']:.3f}": read_library(args.library_dir, "cr3bp", f"{e['alpha']:.3f}")
              for e in manifest["per_alpha"]}
    rows = [{"alpha": label, **throughput(df, rng, args.n_boot)} for label, df in tables.items()]
    rows.append({"alpha": "all", **throughput(pd.concat(tables.values(), ignore_index=True), rng, args.n_boot)})
    cmd = "python benchmarks/library.py " + " ".join(sys.argv[1:])
    text = (f"Command: `{cmd}` — the committed library ({rows[-1]['solves']} solves, {rows[-1]['verified']} "
            f"verified converged, {len(manifest['exports'])} exports); bootstrap seed {args.seed}, "
            f"{args.n_boot} resamples.\n\n" + markdown(rows))
    print(text)
    write_section("library", text)


if __name__ == "__main__":
    main()
