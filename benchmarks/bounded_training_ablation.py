"""Does bounded training lose what the ablation shows? (issue 40 §3) — paired on the same cells.

Two workflow runs of the same config but for the CR3BP models' training budget — ``--bounded`` (the default
config: ≤ 600 rows per training α, early stopping) and ``--full`` (every row, every epoch: the same run
re-trained with ``--config "cr3bp_models={max_rows_per_alpha: 1000000, validation_fraction: 0.0, patience: 0}"``) —
have the same ablation cells: the same test α, arms, seeds and starts per arm; only the learned arms' samples
differ.  For every learned arm and test α this prints the high-quality counts and aRT (IPOPT iterations per
high-quality solution) of both runs and aRT(bounded) ÷ aRT(full) with a percentile bootstrap 95 % interval over
each run's starts (``amorgs.ablation.running_time``: below 1, bounded is faster), then the ratio pooled over the
test α.  Writes the table to ``docs/performance.md`` (section ``bounded-training-ablation``)::

    python benchmarks/bounded_training_ablation.py --bounded RUN_A/results --full RUN_B/results
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
import pandas as pd

from amorgs.ablation.arms import LEARNED_SAMPLER_NAMES
from amorgs.ablation.statistics import high_quality
from amorgs.ablation.running_time import _art, _found_counter, _ratio_boot, solve_costs
from amorgs.problems.cr3bp import BETA_KG

sys.path.insert(0, str(Path(__file__).parent))
from solve import markdown, write_section  # noqa: E402


def cells(results: Path) -> dict[tuple[str, str], pd.DataFrame]:
    """(α label, arm) → the per-start table of that ablation cell of a run (the main ablation, not the
    learning-curve fractions)."""
    return {(p.parent.name.removeprefix("alpha="), p.stem): pd.read_parquet(p)
            for p in sorted((results / "cr3bp" / "ablation").glob("alpha=*/*.parquet"))}


def compare(bounded: pd.DataFrame, full: pd.DataFrame, rng: np.random.Generator, n_boot: int) -> dict:
    cb, cf = solve_costs(bounded, "iterations"), solve_costs(full, "iterations")
    hb, hf = high_quality(bounded, BETA_KG).to_numpy(), high_quality(full, BETA_KG).to_numpy()
    kb, kf = _found_counter(hb), _found_counter(hf)
    art_b, art_f = _art(cb, kb), _art(cf, kf)
    lo, hi = _ratio_boot(cb, kb, cf, kf, n_boot, rng)
    return {"n": f"{len(bounded)} / {len(full)}", "high-quality": f"{int(hb.sum())} / {int(hf.sum())}",
            "aRT bounded": round(art_b), "aRT full": round(art_f), "ratio": art_b / art_f,
            "ci95": f"{lo:.2f}–{hi:.2f}"}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--bounded", type=Path, required=True, help="results/ of the run with bounded training")
    ap.add_argument("--full", type=Path, required=True, help="results/ of the run trained on everything")
    ap.add_argument("--n-boot", type=int, default=2000)
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()
    rng = np.random.default_rng(args.seed)
    a, b = cells(args.bounded), cells(args.full)
    learned = sorted({arm for _, arm in a} & set(LEARNED_SAMPLER_NAMES))
    rows = []
    for arm in learned:
        keys = sorted(k for k in a if k[1] == arm and k in b)
        for key in keys:
            rows.append({"arm": arm, "α": key[0], **compare(a[key], b[key], rng, args.n_boot)})
        pooled = compare(pd.concat([a[k] for k in keys]), pd.concat([b[k] for k in keys]), rng, args.n_boot)
        rows.append({"arm": arm, "α": "pooled", **pooled})
        print(rows[-1], flush=True)
    for r in rows:
        r["ratio"] = f"{r['ratio']:.2f}"
    cmd = " ".join(["python benchmarks/bounded_training_ablation.py", *sys.argv[1:]])
    text = (f"Command: `{cmd}` — aRT in IPOPT iterations per high-quality solution (m_f ≥ {BETA_KG} kg); ratio = "
            "aRT(bounded) ÷ aRT(full), percentile bootstrap 95 % over each run's starts (below 1: bounded "
            "faster); the uniform and reuse arms are the same starts in both runs.\n\n" + markdown(rows))
    print(text)
    write_section("bounded-training-ablation", text)


if __name__ == "__main__":
    main()
