"""Production throughput of the CR3BP solver, measured on the committed library: verified per core-hour.

`benchmarks/solve.py` times a few dozen starts per α on one core; the library holds thousands of solves made
by ``amorgs library-grow`` with the default solver (uniform starts, spec §6), each with its own solve CPU
time (``cpu_s``, ``time.process_time`` inside the worker, so machine load and ``nice`` barely change it).
This script reads every library row through the manifest check (``amorgs.data.library.read_library``) and
prints, per α and in total: solves, verified converged, CPU-hours, **verified per core-hour** with a seeded
bootstrap 95 % interval (rows resampled within α), the CPU share of unconverged solves and the median
iterations; then writes the table to ``docs/performance.md`` (section ``library``).  Reproduce with::

    python benchmarks/library.py                 # data/library, 2000 bootstrap resamples, seed 2026
    python benchmarks/library.py --generation 2  # only the rows of library generation 2 (section library-gen2)

Issue 9's targets are ≥ 2000 verified per core-hour at α = 1.0 and ≥ 800 at α = 0.1.

A second table (section ``library-caps``) asks what a lower iteration cap would buy, on the same solves:
IPOPT is deterministic, so under a cap c a start that converged in k ≤ c iterations converges identically
and every other start is charged min(k, c) × its own CPU per iteration.  Per α it gives the verified
solutions kept, verified per core-hour with a paired bootstrap 95 % interval of its ratio to the 1000-iteration
default, and the kept share of the longest- and shortest-TOF thirds of the converged solutions — the bias
a cap brings (fast basins kept, long transfers lost).
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


CAPS = (200, 400, 600, 800, 1000)
CAP_ALPHAS = ("0.100", "0.500", "1.000")


def cap_what_if(df: pd.DataFrame, caps, rng: np.random.Generator, n_boot: int) -> list[dict]:
    """Rows per cap: verified kept, verified per core-hour (and its ratio to the uncapped solves, paired
    bootstrap 95 % over rows), kept % of the longest- and shortest-TOF thirds of the converged solutions."""
    df = df[np.isfinite(df["cpu_s"]) & (df["iterations"] > 0)]
    iters = df["iterations"].to_numpy(dtype=float)
    cpu_full = df["cpu_s"].to_numpy(dtype=float)
    per_iter = cpu_full / iters
    conv = df["converged"].to_numpy(dtype=bool)
    tof = (df["tau_s"] + df["tau_i"] + df["tau_f"]).to_numpy(dtype=float)
    low_t, high_t = np.quantile(tof[conv], [1 / 3, 2 / 3])
    long, short = conv & (tof > high_t), conv & (tof < low_t)
    idx = rng.integers(0, len(df), size=(n_boot, len(df)))

    def rate(keep, cpu):
        return keep.sum(axis=-1) / (cpu.sum(axis=-1) / 3600.0)

    full = rate(conv[idx], cpu_full[idx])
    rows = []
    for cap in caps:
        keep = conv & (iters <= cap)
        cpu = np.minimum(iters, cap) * per_iter
        low, high = np.percentile(rate(keep[idx], cpu[idx]) / full, [2.5, 97.5])
        rows.append({
            "iteration cap": cap,
            "verified kept": f"{keep.sum()} of {conv.sum()}",
            "verified per core-hour": rate(keep, cpu),
            "ratio to cap 1000 (95 %)": f"{rate(keep, cpu) / rate(conv, cpu_full):.2f} ({low:.2f}–{high:.2f})",
            "kept % of longest-TOF third": 100.0 * (keep & long).sum() / long.sum(),
            "kept % of shortest-TOF third": 100.0 * (keep & short).sum() / short.sum(),
            "TOF thirds (TU)": f"< {low_t:.1f} / > {high_t:.1f}",
        })
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--library-dir", type=Path, default=Path("data/library"))
    ap.add_argument("--seed", type=int, default=2026)
    ap.add_argument("--n-boot", type=int, default=2000)
    ap.add_argument("--generation", type=int, default=None,
                    help="only the rows of this library generation (by the solver-option hashes the manifest lists "
                         "for it); the tables go to sections library-gen<N> and library-caps-gen<N>")
    args = ap.parse_args()
    manifest = read_manifest(args.library_dir, "cr3bp")
    if manifest is None:
        sys.exit(f"{args.library_dir / 'cr3bp'}: no library manifest")
    rng = np.random.default_rng(args.seed)
    tables = {f"{e['alpha']:.3f}": read_library(args.library_dir, "cr3bp", f"{e['alpha']:.3f}")
              for e in manifest["per_alpha"]}
    suffix, what = "", "the committed library"
    if args.generation is not None:
        (gen,) = [g for g in manifest["generations"] if g["generation"] == args.generation] or [None]
        if gen is None:
            sys.exit(f"the library has no generation {args.generation}")
        hashes = set(gen["options_hashes"])
        tables = {k: df[df["options_hash"].isin(hashes)].reset_index(drop=True) for k, df in tables.items()}
        tables = {k: df for k, df in tables.items() if len(df)}
        suffix, what = f"-gen{args.generation}", f"generation {args.generation} of the committed library ({gen['what']})"
    rows = [{"alpha": label, **throughput(df, rng, args.n_boot)} for label, df in tables.items()]
    rows.append({"alpha": "all", **throughput(pd.concat(tables.values(), ignore_index=True), rng, args.n_boot)})
    cmd = "python benchmarks/library.py " + " ".join(sys.argv[1:])
    text = (f"Command: `{cmd}` — {what} ({rows[-1]['solves']} solves, {rows[-1]['verified']} "
            f"verified converged, {len(manifest['exports'])} exports); bootstrap seed {args.seed}, "
            f"{args.n_boot} resamples.\n\n" + markdown(rows))
    print(text)
    write_section("library" + suffix, text)
    caps = [{"alpha": label, **row} for label in CAP_ALPHAS if label in tables
            for row in cap_what_if(tables[label], CAPS, rng, args.n_boot)]
    text = (f"Command: `{cmd}` — the same solves; iteration caps {', '.join(map(str, CAPS))} computed from each "
            f"solve's iterations and CPU per iteration (IPOPT is deterministic); paired bootstrap over solves.\n\n"
            + markdown(caps))
    print(text)
    write_section("library-caps" + suffix, text)


if __name__ == "__main__":
    main()
