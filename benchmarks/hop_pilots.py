"""Hop pilots (issue 41): MBH × reuse with other hops than the studies' (Pareto, scale 0.02 of the box, every
variable), each against the study at its α.

- ``hop-scale-0.005`` (α = 0.3): a quarter of the step, every variable;
- ``hop-times`` (α = 0.16): the study's step, the times only (τ_s, τ_i, τ_f; controls and m_f kept).

For each pilot and each of its study's reuse cells (MBH with the study's hops, and multi-start) it prints the hops'
mean and median IPOPT iterations, the fraction kept and converged, the best m_f, and the ERT ratio of the pilot to
each study cell within each δ of the *study's* best known m_f (95 % bootstrap over searches, as the study's; seed
0).  Reproduce with::

    python benchmarks/hop_pilots.py            # every pilot
    python benchmarks/hop_pilots.py hop-times  # one
"""

from __future__ import annotations

import sys
from pathlib import Path

import pandas as pd

from amorgs.ablation.global_search import ert_ratios

ROOT = Path(__file__).resolve().parents[1]
#: pilot folder (under reference/global-search-pilots) → (its study, the pilot's strategy label, δ in kg)
PILOTS = {
    "hop-scale-0.005": ("alpha=0.300", "mbh_scale_0.005", (2.0, 5.0)),
    "hop-times": ("alpha=0.160", "mbh_times", (0.5, 2.0, 5.0)),
}


def describe(name: str, cell: pd.DataFrame) -> str:
    hops = cell[cell["kind"] == "hop"]
    return (f"{name}: {len(hops)} hops, iterations mean {hops['iterations'].mean():.0f} median "
            f"{hops['iterations'].median():.0f}, kept {hops['accepted'].mean():.2f}, converged "
            f"{hops['converged'].mean():.2f}; best m_f {-cell.loc[cell['converged'], 'objective'].min():.3f} kg")


def report(pilot_name: str) -> None:
    study_name, label, deltas = PILOTS[pilot_name]
    study_dir = ROOT / "reference/global-search" / study_name
    pilot_dir = ROOT / "reference/global-search-pilots" / pilot_name
    study, pilot = pd.read_parquet(study_dir / "events.parquet"), pd.read_parquet(pilot_dir / "events.parquet")
    best = float(pd.read_csv(study_dir / "best_known.csv")["objective"].iloc[0])
    print(f"== {pilot_name} against reference/global-search/{study_name} (best known m_f {-best:.3f} kg)")
    reuse = study[(study["sampler"] == "nearest_alpha") & study["strategy"].isin(["mbh", "multistart"])]
    print(describe("study MBH × reuse", reuse[reuse["strategy"] == "mbh"]))
    print(describe(f"pilot {label}", pilot))
    events = pd.concat([reuse, pilot.assign(strategy=label)], ignore_index=True)
    for baseline in (("mbh", "nearest_alpha"), ("multistart", "nearest_alpha")):
        ratios = ert_ratios(events, best, deltas, baseline=baseline, budget=10000)
        for r in ratios[ratios["strategy"] == label].itertuples(index=False):
            print(f"δ = {r.delta:g} kg: {label} ÷ {r.baseline}: {r.ratio:.2f} ({r.ratio_lo:.2f}–{r.ratio_hi:.2f})")


def main(names: list[str]) -> None:
    unknown = [n for n in names if n not in PILOTS]
    if unknown:
        raise SystemExit(f"hop_pilots: unknown pilot {', '.join(unknown)}; one of {', '.join(PILOTS)}")
    for name in names or list(PILOTS):
        report(name)


if __name__ == "__main__":
    main(sys.argv[1:])
