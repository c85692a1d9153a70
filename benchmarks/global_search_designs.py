"""Does a sparser training design slow the search for the best trajectory? (issue 41)

For every sparse design's study ``reference/global-search/<design>/alpha=X/`` whose α also has a leave-one-α-out
study ``reference/global-search/alpha=X/`` (the same α, seed, budget, hops and solver; only the library α the
samplers draw on and the models differ): for each (strategy, sampler) cell the two studies share and each δ, the
ERT (IPOPT iterations to come within δ kg of the best known m_f — the higher of the two studies' best known, so both
are timed to the same target) of the sparse design's cell ÷ the leave-one-α-out one's, with the studies' percentile
bootstrap over searches (the two cells resampled on their own, 2000 resamples, the study's seed).  Below 1: the
sparse design's cell got there sooner.  A cell that draws on no library α (uniform) is the same searches in both,
ratio 1, and is left out.  Reproduce with::

    python benchmarks/global_search_designs.py
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import pandas as pd

from amorgs.ablation.global_search import ert_ratios, runtime_to_target

STUDIES = Path("reference/global-search")


def compare(sparse: Path, loo: Path) -> list[dict]:
    """Rows of sparse ÷ leave-one-α-out ERT per shared cell and δ (see the module docstring)."""
    study = json.loads((sparse / "study.json").read_text())
    other = json.loads((loo / "study.json").read_text())
    same = ("alpha", "budget", "seed", "hops", "solver", "searches")
    differ = [k for k in same if study[k] != other[k]]
    if differ:
        raise SystemExit(f"{sparse} and {loo} differ in {', '.join(differ)}: not comparable")
    best = min(float(pd.read_csv(d / "best_known.csv")["objective"].iloc[0]) for d in (sparse, loo))
    events = {name: pd.read_parquet(d / "events.parquet") for name, d in (("sparse", sparse), ("loo", loo))}
    cells = sorted(set(zip(events["sparse"]["strategy"], events["sparse"]["sampler"]))
                   & set(zip(events["loo"]["strategy"], events["loo"]["sampler"])))
    deltas = sorted(set(study["deltas"]) & set(other["deltas"]))
    rows = []
    for strategy, sampler in cells:
        if sampler == "uniform":
            continue
        pair = pd.concat([e[(e["strategy"] == strategy) & (e["sampler"] == sampler)].assign(sampler=f"{sampler}@{name}")
                          for name, e in events.items()], ignore_index=True)
        ratios = ert_ratios(pair, best, deltas=deltas, baseline=(strategy, f"{sampler}@loo"), seed=study["seed"],
                            budget=study["budget"])
        hits = runtime_to_target(pair, best, deltas, n_boot=1, budget=study["budget"]).set_index(["sampler", "delta"])
        for r in ratios[ratios["sampler"] == f"{sampler}@sparse"].itertuples():
            won = {name: int(hits.loc[(f"{sampler}@{name}", r.delta), "successes"]) for name in events}
            if math.isnan(r.ratio):  # the leave-one-α-out cell never got there
                said = "only the sparse design's got there" if won["sparse"] else "neither got there"
            else:
                said = f"{r.ratio:.2f} ({r.ratio_lo:.2f}–{r.ratio_hi:.2f})"
            rows.append({"design": sparse.parent.name, "alpha": f"{study['alpha']:g}", "delta_kg": f"{r.delta:g}",
                         "cell": f"{strategy} × {sampler}", "successes sparse / loo":
                         f"{won['sparse']}/{study['searches']} / {won['loo']}/{other['searches']}",
                         "sparse ÷ loo (95 %)": said})
    return rows


def main() -> None:
    rows = [row for sparse in sorted(STUDIES.glob("*/alpha=*")) if (STUDIES / sparse.name).is_dir()
            for row in compare(sparse, STUDIES / sparse.name)]
    print(pd.DataFrame(rows).to_markdown(index=False))


if __name__ == "__main__":
    main()
