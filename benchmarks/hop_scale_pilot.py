"""Cheaper hops (issue 41): MBH × reuse at α = 0.3 with hop scale 0.005 against the study's scale 0.02.

Reads the pilot (``reference/global-search-pilots/hop-scale-0.005``) and the study's reuse cells
(``reference/global-search/alpha=0.300``: MBH with scale 0.02 and multi-start, run 1) and prints, per hop scale,
the hops' mean and median IPOPT iterations, the fraction kept and converged, and the ERT ratio of the pilot to
each study cell within 2 and 5 kg of the study's best known m_f (95 % bootstrap over searches, as the study's).
Reproduce with::

    python benchmarks/hop_scale_pilot.py
"""

from __future__ import annotations

import pandas as pd

from amorgs.ablation.global_search import ert_ratios

STUDY = "reference/global-search/alpha=0.300"
PILOT = "reference/global-search-pilots/hop-scale-0.005"


def main() -> None:
    study, pilot = pd.read_parquet(f"{STUDY}/events.parquet"), pd.read_parquet(f"{PILOT}/events.parquet")
    best = float(pd.read_csv(f"{STUDY}/best_known.csv")["objective"].iloc[0])
    reuse = study[(study["sampler"] == "nearest_alpha") & study["strategy"].isin(["mbh", "multistart"])]
    events = pd.concat([reuse, pilot.assign(strategy="mbh_scale_0.005")], ignore_index=True)
    for name, cell in (("scale 0.02 (study)", reuse[reuse["strategy"] == "mbh"]), ("scale 0.005 (pilot)", pilot)):
        hops = cell[cell["kind"] == "hop"]
        print(f"{name}: {len(hops)} hops, iterations mean {hops['iterations'].mean():.0f} median "
              f"{hops['iterations'].median():.0f}, kept {hops['accepted'].mean():.2f}, converged "
              f"{hops['converged'].mean():.2f}; best m_f {-cell.loc[cell['converged'], 'objective'].min():.3f} kg")
    for baseline in (("mbh", "nearest_alpha"), ("multistart", "nearest_alpha")):
        ratios = ert_ratios(events, best, (2.0, 5.0), baseline=baseline, budget=10000)
        for r in ratios[ratios["strategy"] == "mbh_scale_0.005"].itertuples(index=False):
            print(f"δ = {r.delta:g} kg: scale 0.005 ÷ {r.baseline}: {r.ratio:.2f} ({r.ratio_lo:.2f}–{r.ratio_hi:.2f})")


if __name__ == "__main__":
    main()
