"""Hop pilots (issue 41): MBH × reuse with other hops than the studies' (Pareto, scale 0.02 of the box, every
variable), each against the study at its α.

- ``hop-scale-0.005`` (α = 0.3): a quarter of the step, every variable;
- ``hop-times`` (α = 0.16): the study's step, the times only (τ_s, τ_i, τ_f; controls and m_f kept).

For each pilot and the study's MBH × reuse cell it prints the hops' mean and median IPOPT iterations, the fraction
kept and converged, how often a converged hop landed η-distinct from its incumbent (its solution's times differ
from the incumbent's by more than 0.02 of their box — 0.8 TU of τ_s, 0.3 TU of τ_i or τ_f, the η of the
near-best count — in at least one time) and the best m_f; then the ERT ratio of the pilot to each of the study's
reuse cells (MBH with the study's hops, and multi-start) within each δ of the *study's* best known m_f (95 %
bootstrap over searches, as the study's; seed 0).  Reproduce with::

    python benchmarks/hop_pilots.py            # every pilot
    python benchmarks/hop_pilots.py hop-times  # one
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pandas as pd

from amorgs.ablation.global_search import ert_ratios

ROOT = Path(__file__).resolve().parents[1]
#: pilot folder (under reference/global-search-pilots) → (its study, the pilot's strategy label, δ in kg)
PILOTS = {
    "hop-scale-0.005": ("alpha=0.300", "mbh_scale_0.005", (2.0, 5.0)),
    "hop-times": ("alpha=0.160", "mbh_times", (0.5, 2.0, 5.0)),
}


TIMES, TIME_BOX, ETA = ["tau_s", "tau_i", "tau_f"], np.array([40.0, 15.0, 15.0]), 0.02


def left_funnel(cell: pd.DataFrame, solutions: pd.DataFrame) -> tuple[int, float]:
    """The converged hops that had an incumbent, and the fraction of them whose solution's times lie more than η of
    the box from the incumbent's in at least one time."""
    times = solutions.set_index(["search", "event"])[TIMES]
    moves = []
    for (search, _), run in cell.groupby(["search", "run"]):
        incumbent = None
        for e in run.itertuples(index=False):
            here = times.loc[(search, e.solve)].to_numpy(float) if e.converged else None
            if e.kind == "hop" and here is not None and incumbent is not None:
                moves.append(np.max(np.abs(here - incumbent) / TIME_BOX))
            if e.accepted:
                incumbent = here
    return len(moves), float(np.mean(np.array(moves) > ETA)) if moves else float("nan")


def describe(name: str, cell: pd.DataFrame, solutions: pd.DataFrame) -> str:
    hops = cell[cell["kind"] == "hop"]
    n, left = left_funnel(cell, solutions)
    return (f"{name}: {len(hops)} hops, iterations mean {hops['iterations'].mean():.0f} median "
            f"{hops['iterations'].median():.0f}, kept {hops['accepted'].mean():.2f}, converged "
            f"{hops['converged'].mean():.2f}, {left:.2f} of {n} converged hops landed η-distinct from the incumbent; "
            f"best m_f {-cell.loc[cell['converged'], 'objective'].min():.3f} kg")


def report(pilot_name: str) -> None:
    study_name, label, deltas = PILOTS[pilot_name]
    study_dir = ROOT / "reference/global-search" / study_name
    pilot_dir = ROOT / "reference/global-search-pilots" / pilot_name
    study, pilot = pd.read_parquet(study_dir / "events.parquet"), pd.read_parquet(pilot_dir / "events.parquet")
    found = pd.read_parquet(study_dir / "solutions.parquet")
    mbh = (study["sampler"] == "nearest_alpha") & (study["strategy"] == "mbh")
    best = float(pd.read_csv(study_dir / "best_known.csv")["objective"].iloc[0])
    print(f"== {pilot_name} against reference/global-search/{study_name} (best known m_f {-best:.3f} kg)")
    reuse = study[(study["sampler"] == "nearest_alpha") & study["strategy"].isin(["mbh", "multistart"])]
    print(describe("study MBH × reuse", study[mbh], found[(found["sampler"] == "nearest_alpha") &
                                                          (found["strategy"] == "mbh")]))
    print(describe(f"pilot {label}", pilot, pd.read_parquet(pilot_dir / "solutions.parquet")))
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
