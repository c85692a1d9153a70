"""Benchmark of the CR3BP local solver: verified converged solutions per core-hour.

Runs ``--starts`` uniform starts (spec §6) at each α on ONE core (one worker process, solves in series),
with the default and the library config's solver options unless other variants are chosen, and prints and
writes the table to ``docs/performance.md`` (section between the BENCHMARK markers).  Reproduce with::

    python benchmarks/solve.py                      # the default and the library solver, same 50 starts × α ∈ {0.1, 0.5, 1.0}
    python benchmarks/solve.py --variants --starts 12   # the comparison of transcription/solver variants
    python benchmarks/solve.py --scaling            # 1 → 2 worker processes
    python benchmarks/solve.py --compare --jobs 2   # previous default vs new default, same seed and starts
    python benchmarks/solve.py --steps --alphas 0.5 1.0 --jobs 2 --max-wall-s 600   # default vs scale_down
    python benchmarks/solve.py --ipopt-screen --starts 10 --alphas 1.0   # IPOPT options, one at a time
    python benchmarks/solve.py --quasi-newton --alphas 0.1 1.0 --max-wall-s 600   # L-BFGS 30 vs SR1, history 6
    python benchmarks/solve.py --coast --starts 200 --alphas 0.1 1.0 --jobs 2 --max-wall-s 600   # issue 22
    python benchmarks/solve.py --controls --starts 200 --alphas 0.1 1.0 --jobs 2 --max-wall-s 600   # Cartesian controls
    python benchmarks/solve.py --controls --starts 100 --alphas 0.2 0.3 0.5 --jobs 2 --max-wall-s 600 --section controls_switch
    python benchmarks/solve.py --aug --starts 200 --alphas 1.0 0.1 --jobs 2 --max-wall-s 600   # extended L-BFGS system
    python benchmarks/solve.py --mumps --starts 200 --alphas 1.0 0.1 --jobs 2 --max-wall-s 600  # MUMPS scaling off
    python benchmarks/solve.py --library-only --starts 200 --alphas 1.0 0.1 --jobs 2 --max-wall-s 600 \
        --before /tmp/before.parquet --section rk8_kernel   # a code change: the same command's raw rows before it

``--before RAW`` pairs this run with the raw rows (``--raw``) of the same command run on the code before a change
(another checkout; the seed fixes the starts): each variant is compared with itself "before", with the paired
bootstrap and the per-band table below.  ``--library-only`` runs the library config's solver alone.

``--variants`` and ``--compare`` also write a start-by-start table of which starts converge with and without
the stall abort, per TOF band (6.3 TU wide, centred on multiples of 6.3 TU — the hyperplane spacing): the
abort must not shrink any band.  ``--jobs`` runs the cells (variant × α) side by side, each in its own
single-worker process; ``--max-wall-s`` raises the wall-time safety net so that a loaded machine does not
cut solves short (it is not part of the deterministic budget).

``--steps`` compares the default with fewer RK8 steps at high α (``TranscriptionOptions.scale_down``: the
law ceil(24·sqrt(0.3/α)) above α = 0.3 too, 14 steps per segment at α = 1.0, 19 at 0.5; it changes nothing
below 0.3) and with scale_down plus fewer coast steps, on the same starts; it writes the same per-band table
(default vs variant) and a paired bootstrap over starts (seeded) of the ratio of verified per core-hour.

Throughput counts solve CPU time (``time.process_time`` inside the worker), not the one-off JIT build,
which is reported separately.  The iteration-cap table is computed from the same solves: a start that
converged in k ≤ cap iterations converges identically under that cap (IPOPT is deterministic), every other
start is charged cap × its own measured cost per iteration.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import platform
import re
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np
import pandas as pd

from amorgs.config import load_config
from amorgs.problems import get_problem
from amorgs.solvers.multistart import run_multistart
from amorgs.solvers.options import IpoptOptions, TranscriptionOptions

ROOT = Path(__file__).resolve().parents[1]
DOC = ROOT / "docs" / "performance.md"
#: The solver defaults before issue 9 §1 (explicit, so the comparison survives later default changes).
PREVIOUS = IpoptOptions(
    compile_flags="-O2",
    lbfgs_aug_solver="sherman-morrison",
    lbfgs_memory=30,
    stall_window=0,
    transcription=TranscriptionOptions(coast="rk8", steps_per_segment=24, steps_per_coast=320,
                                       step_scaling_alpha=0.3, scale_down=False),
)


def _with(base: IpoptOptions, **changes) -> IpoptOptions:
    """``base`` with ``changes``; ``transcription=`` takes a dict of changes to the nested options."""
    if "transcription" in changes:
        changes["transcription"] = dataclasses.replace(base.transcription, **changes["transcription"])
    return dataclasses.replace(base, **changes)


#: ``--variants``: the previous default, each issue-9 change alone on top of it, and the new default ({}).
VARIANTS = {
    "previous default (-O2, RK8 24/seg ×√(0.3/α) below 0.3 + 320/coast, no abort)": PREVIOUS,
    "+ compile flags -O3 -march=native -ffp-contract=off": _with(PREVIOUS, compile_flags="-O3 -march=native -ffp-contract=off"),
    "+ stall abort": _with(PREVIOUS, stall_window=300, stall_factor=0.5),
    "+ steps scaled down above α = 0.3": _with(PREVIOUS, transcription={"scale_down": True}),
    "new default (compile flags only; abort off, steps unchanged)": _with(IpoptOptions(), lbfgs_aug_solver="sherman-morrison", lbfgs_memory=30, transcription={"coast": "rk8"}),
}
#: ``--compare``: the final old-vs-new table.
COMPARE = {k: v for k, v in VARIANTS.items() if k.startswith(("previous", "new"))}
#: Pairs (with abort, without abort) whose converged sets are compared start by start per TOF band.
ABORT_PAIRS = {
    "+ stall abort": "previous default (-O2, RK8 24/seg ×√(0.3/α) below 0.3 + 320/coast, no abort)",
}
#: ``--steps``: the default vs fewer steps at high α (same starts).
STEPS_DEFAULT = "default (24/seg ×√(0.3/α) below 0.3, 320/coast)"
#: The solver before issue 22: RK8 coasts, IPOPT's Sherman–Morrison L-BFGS solve, history 30 (options_hash
#: 42bf7b6dd566, the library's generation 1).
_RK8_COASTS = _with(IpoptOptions(), lbfgs_aug_solver="sherman-morrison", lbfgs_memory=30,
                    transcription={"coast": "rk8"})
STEPS = {
    STEPS_DEFAULT: _RK8_COASTS,
    "scale_down (⌈24·√(0.3/α)⌉/seg above 0.3 too)": _with(_RK8_COASTS, transcription={"scale_down": True}),
    "scale_down + 240/coast": _with(_RK8_COASTS, transcription={"scale_down": True, "steps_per_coast": 240,
                                                                "coast_pieces": 8}),
}
#: ``--ipopt-screen``: IPOPT options that leave the NLP alone, one at a time on top of the generation-1 solver (a cheap
#: screen on few starts; what survives it goes to a paired comparison such as ``--quasi-newton``).
IPOPT_SCREEN = {
    "default": _RK8_COASTS,
    "SR1 update": _with(_RK8_COASTS, ipopt_options={"limited_memory_update_type": "sr1"}),
    "L-BFGS history 6": _with(_RK8_COASTS, lbfgs_memory=6),
    "L-BFGS history 60": _with(_RK8_COASTS, lbfgs_memory=60),
    "limited_memory_initialization scalar2": _with(_RK8_COASTS, ipopt_options={"limited_memory_initialization": "scalar2"}),
    "mu_strategy monotone": _with(_RK8_COASTS, ipopt_options={"mu_strategy": "monotone"}),
    "nlp_scaling_method none": _with(_RK8_COASTS, ipopt_options={"nlp_scaling_method": "none"}),
    "mu_oracle quality-function": _with(_RK8_COASTS, ipopt_options={"mu_oracle": "quality-function"}),
    "no watchdog (watchdog_shortened_iter_trigger 0)": _with(_RK8_COASTS, ipopt_options={"watchdog_shortened_iter_trigger": 0}),
    "bound_push = bound_frac = 1e-6": _with(_RK8_COASTS, ipopt_options={"bound_push": 1e-6, "bound_frac": 1e-6}),
}
#: ``--quasi-newton``: the default L-BFGS (history 30) vs the two survivors of the screen, on the same starts.
QN_DEFAULT = "default (L-BFGS, history 30)"
QUASI_NEWTON = {
    QN_DEFAULT: IPOPT_SCREEN["default"],
    "SR1 update (limited_memory_update_type sr1)": IPOPT_SCREEN["SR1 update"],
    "L-BFGS history 6": IPOPT_SCREEN["L-BFGS history 6"],
}
#: ``--coast``: the default before issue 22 (coasts integrated with RK8 at every evaluation) vs coasts read off
#: the B-spline of the ballistic flow, with IPOPT's Sherman–Morrison L-BFGS solve at history 30 and 6, and with
#: the extended L-BFGS system (measured in the previous round, not adopted: warm starts), on the same starts.
COAST_DEFAULT = "RK8 coasts 320 steps, L-BFGS history 30 (before issue 22)"
COAST = {
    COAST_DEFAULT: _RK8_COASTS,
    "interpolated coasts, L-BFGS history 30": _with(_RK8_COASTS, transcription={"coast": "interpolant"}),
    "interpolated coasts, L-BFGS history 6": _with(_RK8_COASTS, lbfgs_memory=6, transcription={"coast": "interpolant"}),
}
#: The default block: the two solvers in use today, on the same starts — the default (IPOPT L-BFGS history 30:
#: `design`, the ablation's warm starts, every config but the library's) and the library config's (history 6:
#: the cold starts that grow the library, issue 22), read from ``config/library.yaml`` so that it stays its own.
DEFAULT_REFERENCE = "default solver (L-BFGS history 30)"
DEFAULTS = {
    DEFAULT_REFERENCE: IpoptOptions(),
    "library config (L-BFGS history 6, Cartesian controls below α = 0.25)":
        load_config(ROOT / "config" / "library.yaml").problems.cr3bp.solver,
}
#: ``--controls``: the library's solver on the stored (θ, φ, ρ) against Cartesian controls (a direction v with
#: ‖v‖ ≤ 1 and the throttle ρ, issue 22), on the same uniform starts.
_LIBRARY_SOLVER = _with(DEFAULTS["library config (L-BFGS history 6, Cartesian controls below α = 0.25)"],
                        transcription={"controls": "spherical", "controls_switch_alpha": 0.0})
CONTROLS_DEFAULT = "library solver, spherical controls (θ, φ, ρ) (generation 2)"
CONTROLS = {
    CONTROLS_DEFAULT: _LIBRARY_SOLVER,
    "library solver, Cartesian controls (v, ρ), ‖v‖ ≤ 1": _with(_LIBRARY_SOLVER, transcription={"controls": "cartesian"}),
}
#: ``--aug``: the library config's solver (generation 3) against the same with IPOPT's extended L-BFGS system
#: (``lbfgs_aug_solver = 'extended'``: cheaper iterations; it fails re-solves from converged solutions, so it is
#: a candidate for cold starts only), on the same uniform starts.
AUG_DEFAULT = "library config (generation 3: Sherman–Morrison L-BFGS, history 6)"
AUG = {
    AUG_DEFAULT: DEFAULTS["library config (L-BFGS history 6, Cartesian controls below α = 0.25)"],
    "library config + extended L-BFGS system": _with(
        DEFAULTS["library config (L-BFGS history 6, Cartesian controls below α = 0.25)"], lbfgs_aug_solver="extended"),
}
#: ``--mumps``: the library config's solver (generation 3) against the same without MUMPS's scaling of the KKT
#: system (``mumps_scaling = mumps_permuting_scaling = 0``: a 71-row system with an identity-like L-BFGS block
#: needs none, and computing it was ≈ 40 % of IPOPT's own time per iteration), and with the extended L-BFGS
#: system on top, on the same uniform starts.
MUMPS_DEFAULT = AUG_DEFAULT
_NO_MUMPS_SCALING = {"mumps_scaling": 0, "mumps_permuting_scaling": 0}
MUMPS = {
    MUMPS_DEFAULT: AUG[AUG_DEFAULT],
    "library config, MUMPS scaling off": _with(AUG[AUG_DEFAULT], ipopt_options=_NO_MUMPS_SCALING),
    "library config, MUMPS scaling off + extended L-BFGS system": _with(
        AUG[AUG_DEFAULT], ipopt_options=_NO_MUMPS_SCALING, lbfgs_aug_solver="extended"),
}
#: The paired comparisons (variants, reference): the same starts for each, a paired bootstrap of the
#: throughput ratio and start-by-start TOF bands against the reference.
PAIRED = {"steps": (STEPS, STEPS_DEFAULT), "quasi_newton": (QUASI_NEWTON, QN_DEFAULT), "coast": (COAST, COAST_DEFAULT),
          "default": (DEFAULTS, DEFAULT_REFERENCE), "controls": (CONTROLS, CONTROLS_DEFAULT),
          "aug": (AUG, AUG_DEFAULT), "mumps": (MUMPS, MUMPS_DEFAULT)}
TOF_BAND_TU = 6.3
BOOTSTRAP = 10_000


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
        "aborted": int((df.status == "aborted_stalled").sum()),
        "CPU share of unconverged %": 100 * df.cpu_s[~df.converged].sum() / df.cpu_s.sum() if cpu_h else float("nan"),
        "wall q25/50/75 converged (s)": q(conv.wall_s),
        "wall q25/50/75 all (s)": q(df.wall_s),
        "median iters converged": float(conv.iterations.median()) if len(conv) else float("nan"),
        "total iters": int(iters),
        "ms/iter": 1000 * df.cpu_s.sum() / max(iters, 1),
        "median ms/iter": 1000 * float((df.cpu_s / df.iterations)[df.iterations > 0].median()),
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


def tof_band(tof: pd.Series) -> pd.Series:
    """Label of the TOF band (width ``TOF_BAND_TU``, centred on its multiples) of each TOF."""
    k = np.round(tof / TOF_BAND_TU)
    return k.map(lambda v: f"{(v - 0.5) * TOF_BAND_TU:.1f}–{(v + 0.5) * TOF_BAND_TU:.1f}" if np.isfinite(v) else "–")


def band_table(raw: pd.DataFrame, pairs: dict[str, str], ref_col: str, new_col: str,
               with_variant: bool = False, with_moves: bool = False) -> list[dict]:
    """Start by start: which starts converge in the reference and in the variant run, per TOF band.

    ``pairs`` maps variant → reference label.  Per band: converged in the reference (band of its solution),
    converged in the variant (band of its solution); ``lost`` = converged only in the reference (band of the
    lost solution); ``gained`` = converged only in the variant (band of the new solution); with
    ``with_moves``, ``moved out`` / ``moved in`` = converged in both runs but to solutions in different bands
    (counted in the reference's / the variant's band), so that variant = reference − lost + gained − moved
    out + moved in in every band.
    """
    rows = []
    for variant, reference in pairs.items():
        for alpha in sorted(raw.alpha.unique()):
            a = raw[(raw.variant == variant) & (raw.alpha == alpha)].set_index("start")
            b = raw[(raw.variant == reference) & (raw.alpha == alpha)].set_index("start")
            if a.empty or b.empty:
                continue
            head = {"variant": variant} if with_variant else {}
            b_band = tof_band(b.tau_s + b.tau_i + b.tau_f)
            a_band = tof_band(a.tau_s + a.tau_i + a.tau_f)
            bands = sorted(set(b_band[b.converged]) | set(a_band[a.converged]), key=lambda t: float(t.split("–")[0]))
            both = a.converged & b.converged
            for band in bands:
                ref = b.converged & (b_band == band)
                new = a.converged & (a_band == band)
                row = {**head, "alpha": alpha, "TOF band (TU)": band, ref_col: int(ref.sum()),
                       new_col: int(new.sum()), "lost": int((ref & ~a.converged).sum()),
                       "gained": int((new & ~b.converged).sum())}
                if with_moves:
                    row["moved out"] = int((ref & both & (a_band != band)).sum())
                    row["moved in"] = int((new & both & (b_band != band)).sum())
                rows.append(row)
            row = {**head, "alpha": alpha, "TOF band (TU)": "all", ref_col: int(b.converged.sum()),
                   new_col: int(a.converged.sum()), "lost": int((b.converged & ~a.converged).sum()),
                   "gained": int((a.converged & ~b.converged).sum())}
            if with_moves:
                row["moved out"] = row["moved in"] = int((both & (a_band != b_band)).sum())
            rows.append(row)
    return rows


def abort_table(raw: pd.DataFrame) -> list[dict]:
    """:func:`band_table` of the stall abort (variant) against no abort (reference)."""
    return band_table(raw, ABORT_PAIRS, "converged without abort", "converged with abort")


def ratio_bootstrap(raw: pd.DataFrame, pairs: dict[str, str], seed: int, n_boot: int = BOOTSTRAP) -> list[dict]:
    """Ratio (variant / reference) of verified per core-hour on the same starts, with a 95 % percentile
    interval from a paired bootstrap over starts (the same resampled starts in both runs; ``seed``).

    It covers the start-to-start variation only, not the run-to-run noise of CPU time on a shared machine
    (see the ms/iter ratio, whose iterations are deterministic)."""
    rows = []
    for variant, reference in pairs.items():
        for alpha in sorted(raw.alpha.unique()):
            a = raw[(raw.variant == variant) & (raw.alpha == alpha)].set_index("start").sort_index()
            b = raw[(raw.variant == reference) & (raw.alpha == alpha)].set_index("start").sort_index()
            if a.empty or b.empty:
                continue
            common = a.index.intersection(b.index)
            a, b = a.loc[common], b.loc[common]
            ca, cb = a.converged.to_numpy(float), b.converged.to_numpy(float)
            ta, tb = a.cpu_s.to_numpy(), b.cpu_s.to_numpy()
            rate = lambda c, t: c.sum(axis=-1) / t.sum(axis=-1)
            idx = np.random.default_rng(seed).integers(0, len(common), size=(n_boot, len(common)))
            with np.errstate(divide="ignore", invalid="ignore"):
                boot = rate(ca[idx], ta[idx]) / rate(cb[idx], tb[idx])
            lo, hi = np.nanquantile(boot, [0.025, 0.975])
            ms = lambda d: d.cpu_s.sum() / max(d.iterations.sum(), 1)
            rows.append({"variant": variant, "alpha": alpha, "n (paired starts)": len(common),
                         "verified per core-hour, reference": 3600 * rate(cb, tb),
                         "verified per core-hour, variant": 3600 * rate(ca, ta),
                         "ratio": f"{rate(ca, ta) / rate(cb, tb):.2f}", "95 % interval": f"{lo:.2f}–{hi:.2f}",
                         "P(ratio ≤ 1.2)": f"{np.mean(boot <= 1.2):.3f}",
                         "ms/iter ratio": f"{ms(a) / ms(b):.2f}",
                         "total iterations ratio": f"{a.iterations.sum() / max(b.iterations.sum(), 1):.2f}",
                         "total CPU ratio": f"{ta.sum() / tb.sum():.2f}"})
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
    ap.add_argument("--compare", action="store_true", help="previous default vs new default only")
    ap.add_argument("--steps", action="store_true",
                    help="default vs fewer RK8 steps at high α (scale_down, ± fewer coast steps), same starts")
    ap.add_argument("--ipopt-screen", action="store_true",
                    help="screen IPOPT options that leave the NLP alone, one at a time (few starts)")
    ap.add_argument("--quasi-newton", action="store_true",
                    help="default L-BFGS vs the SR1 update and a short L-BFGS history, same starts")
    ap.add_argument("--coast", action="store_true",
                    help="the default vs interpolated coasts + extended L-BFGS system (issue 22), same starts")
    ap.add_argument("--controls", action="store_true",
                    help="library solver: spherical (θ, φ, ρ) vs Cartesian controls on the same starts (issue 22)")
    ap.add_argument("--aug", action="store_true",
                    help="library solver: Sherman–Morrison vs the extended L-BFGS system on the same starts (issue 22)")
    ap.add_argument("--mumps", action="store_true",
                    help="library config vs the same without MUMPS scaling (and with the extended L-BFGS system)")
    ap.add_argument("--section", default=None,
                    help="name of the docs/performance.md block to write (default: the mode's own, e.g. controls)")
    ap.add_argument("--max-wall-s", type=float, default=None,
                    help="raise the wall-time safety net (on a loaded machine it would cut solves short)")
    ap.add_argument("--jobs", type=int, default=1, help="cells (variant × α) run side by side, one worker each")
    ap.add_argument("--scaling", action="store_true", help="measure 1 → 2 worker scaling")
    ap.add_argument("--raw", type=Path, default=None, help="also save the raw rows as Parquet")
    ap.add_argument("--before", type=Path, default=None,
                    help="raw rows (--raw) of this command on the code before a change: compare start by start")
    ap.add_argument("--library-only", action="store_true", help="the default block's library config alone")
    args = ap.parse_args()
    cmd = "python benchmarks/solve.py " + " ".join(sys.argv[1:])

    if args.scaling:
        rows = []
        for workers in (1, 2):
            t0 = time.perf_counter()
            df = run_multistart(get_problem("cr3bp"), 1.0, args.seed, args.starts, workers=workers, progress=False)
            rows.append({"workers": workers, "starts": args.starts, "wall (s)": time.perf_counter() - t0,
                         "solve CPU (s)": df.cpu_s.sum()})
        rows[1]["speed-up"] = rows[0]["wall (s)"] / rows[1]["wall (s)"]
        text = f"Command: `{cmd}` — {machine()}; wall time includes each worker's JIT build.\n\n" + markdown(rows)
        print(text)
        write_section("scaling", text)
        return

    paired = ("steps" if args.steps else "quasi_newton" if args.quasi_newton else "coast" if args.coast
              else "controls" if args.controls else "aug" if args.aug else "mumps" if args.mumps else None if args.variants or args.compare or args.ipopt_screen else "default")
    variants = (VARIANTS if args.variants else COMPARE if args.compare else PAIRED[paired][0] if paired
                else IPOPT_SCREEN)
    if args.library_only:
        variants = {k: v for k, v in variants.items() if k.startswith("library config")}
    if paired:  # α-major, so that the runs compared on the same starts run at about the same time
        cells = [(label, opts, alpha) for alpha in args.alphas for label, opts in variants.items()]
    else:
        cells = [(label, opts, alpha) for label, opts in variants.items() for alpha in args.alphas]

    def run_cell(cell):
        label, opts, alpha = cell
        if args.max_wall_s is not None:
            opts = dataclasses.replace(opts, max_wall_s=args.max_wall_s)
        df = run_multistart(get_problem("cr3bp"), alpha, args.seed, args.starts, workers=1, options=opts, progress=False)
        df["variant"] = label
        print(json.dumps({"variant": label, **summarize(df)}, default=str), flush=True)
        return df

    # Each cell is one worker process solving in series; --jobs runs cells side by side (CPU time per solve
    # is measured inside the worker, so it stays a one-core figure).
    with ThreadPoolExecutor(max_workers=max(1, args.jobs)) as pool:
        raw = list(pool.map(run_cell, cells))
    rows, caps = [], []
    for df in raw:
        rows.append({"variant": df.variant.iloc[0], **summarize(df)})
        caps += [{"variant": df.variant.iloc[0], **row} for row in cap_table(df)]
    mode = "variants" if args.variants else "compare" if args.compare else "ipopt_screen" if args.ipopt_screen else paired
    name = args.section or mode
    text = f"Command: `{cmd}` — {machine()}; seed {args.seed}; one worker process per cell.\n\n" + markdown(rows)
    if mode == "default":
        text += "\nIteration cap (computed from the same solves, see the script's docstring):\n\n" + markdown(caps)
    all_raw = pd.concat(raw)
    if args.raw:  # first, so that a failure in the tables below does not lose the solves
        all_raw.to_parquet(args.raw)
    abort_rows = abort_table(all_raw)
    if abort_rows:
        text += ("\nStall abort, start by start on the same starts, per TOF band of the converged solution "
                 "(see `abort_table`):\n\n" + markdown(abort_rows))
    if args.before:
        before = pd.read_parquet(args.before)
        before["variant"] = before.variant + ", before"
        all_raw = pd.concat([all_raw, before])
        pairs = {k: f"{k}, before" for k in variants}
        text += (f"\nThe same command on the code before the change (`{args.before.name}`), start by start: ratio "
                 f"of verified per core-hour (after / before), 95 % interval from a paired bootstrap over starts "
                 f"({BOOTSTRAP} resamples, seed {args.seed}):\n\n"
                 + markdown(ratio_bootstrap(all_raw, pairs, args.seed))
                 + "\nPer TOF band of the converged solution (6.3 TU; `band_table`):\n\n"
                 + markdown(band_table(all_raw, pairs, "converged, before", "converged, after", with_variant=True,
                                       with_moves=True)))
    elif paired and len(variants) > 1:
        reference = PAIRED[paired][1]
        pairs = {k: reference for k in variants if k != reference}
        text += ("\nRatio of verified per core-hour (variant / default) on the same starts; 95 % interval from "
                 f"a paired bootstrap over starts ({BOOTSTRAP} resamples, seed {args.seed}; see "
                 "`ratio_bootstrap`):\n\n" + markdown(ratio_bootstrap(all_raw, pairs, args.seed)))
        text += ("\nStart by start on the same starts, per TOF band of the converged solution (6.3 TU, the "
                 "hyperplane spacing; see `band_table`):\n\n"
                 + markdown(band_table(all_raw, pairs, "converged, default", "converged, variant",
                                       with_variant=True, with_moves=True)))
    print(text)
    write_section(name, text)


if __name__ == "__main__":
    main()
