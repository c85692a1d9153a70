"""Which strategy × sampler reaches the funnel bottom fastest, at each committed global-search study (issue 41).

For every ``reference/global-search/alpha=*/`` (the leave-one-α-out studies, design ``loo``) and
``reference/global-search/<design>/alpha=*/`` (a sparse design's, e.g. ``sparse-3``), and each δ of its study: the
cell with the lowest ERT (IPOPT iterations to come within δ kg of the study's best known m_f) and every cell's ERT ÷
that fastest cell's, with the study's percentile bootstrap over searches (each pair of cells resampled on its own,
the study's seed and budget). A cell whose interval's lower end is at most 1 is *not significantly slower* than the
fastest: the fastest cell is significantly the fastest only where it is alone in that list. A cell whose searches
are one search repeated (:func:`~amorgs.ablation.global_search.repeats_search_0`: a multi-start from a sampler that
ignores the seed, the selector's one ranking) has no interval: its ERT is exact for that trained selector, and
ratios against it resample the other cell alone. Reproduce with::

    python benchmarks/global_search_fastest.py

``--record data/best_known/cr3bp.json`` times every study to the best known m_f of that record at its α where it
is higher than the study's own (:func:`amorgs.data.best_known.lift` carries a trajectory to every higher α, so a
study's target can lie below what is known today): the tables are recomputed from the events, nothing re-solved.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import argparse

import pandas as pd

from amorgs.ablation.global_search import Cell, ert_ratios, repeats_search_0, runtime_to_target

STUDIES = Path("reference/global-search")


def pairwise(events: pd.DataFrame, top: tuple[str, str], other: tuple[str, str], best: float, delta: float,
             study: dict) -> pd.DataFrame:
    """``other``'s ERT ÷ ``top``'s, bootstrapped on those two cells' events alone: the interval does not depend on
    which other cells the study holds (resampling every cell from one stream would shift it as cells are added)."""
    pair = events[[(t, s) in (top, other) for t, s in zip(events["strategy"], events["sampler"])]]
    ratios = ert_ratios(pair, best, deltas=(delta,), baseline=top, seed=study["seed"], budget=study["budget"])
    return ratios[(ratios["strategy"] == other[0]) & (ratios["sampler"] == other[1])]


def fastest(folder: Path, record: dict | None = None) -> list[dict]:
    """Per δ: the fastest cell, its ERT with interval and successes, and the cells not significantly slower; timed
    to the study's best known m_f, or to ``record``'s at its α where that is higher."""
    study = json.loads((folder / "study.json").read_text())
    events = pd.read_parquet(folder / "events.parquet")
    best = float(pd.read_csv(folder / "best_known.csv")["objective"].iloc[0])
    table = pd.read_csv(folder / "runtime_to_target.csv")
    if record is not None:
        from amorgs.data.best_known import best_m_f

        known = -best_m_f(record, study["alpha"])
        if known < best:
            best = known
            table = runtime_to_target(events, best, study["deltas"], seed=study["seed"], budget=study["budget"])
    rows = []
    for delta in study["deltas"]:
        here = table[(table["delta"] == delta) & table["ert"].map(math.isfinite)]
        if here.empty:
            continue
        top = here.sort_values("ert").iloc[0]
        ratios = pd.concat([pairwise(events, (top["strategy"], top["sampler"]), other, best, delta, study)
                            for other in sorted(set(zip(events["strategy"], events["sampler"])))
                            if other != (top["strategy"], top["sampler"])], ignore_index=True)
        level = ratios[ratios["ratio_lo"] <= 1]
        cell = Cell(sampler=top["sampler"], strategy=top["strategy"], alpha=study["alpha"],
                    searches=study["searches"], budget=study["budget"], seed=study["seed"])
        interval = "one search repeated" if repeats_search_0(cell) else f"{top['ert_lo']:.0f}–{top['ert_hi']:.0f}"
        rows.append({"design": folder.parent.name if folder.parent != STUDIES else "loo",
                     "alpha": f"{study['alpha']:g}", "target_m_f": f"{-best:.3f}", "delta_kg": f"{delta:g}",
                     "fastest": f"{top['strategy']} × {top['sampler']}",
                     "ERT (95 %)": f"{top['ert']:.0f} ({interval})",
                     "successes": f"{int(top['successes'])}/{int(top['searches'])}",
                     "not_significantly_slower": "; ".join(
                         f"{r.strategy} × {r.sampler} {r.ratio:.2f} ({r.ratio_lo:.2f}–{r.ratio_hi:.2f})"
                         for r in level.itertuples()) or "none"})
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--record", default=None, help="time each study to this best-known record where it is higher")
    args = parser.parse_args()
    record = None
    if args.record:
        from amorgs.data.best_known import read_record

        record = read_record(args.record)
    folders = [*sorted(STUDIES.glob("alpha=*")), *sorted(STUDIES.glob("*/alpha=*"))]
    rows = [row for folder in folders for row in fastest(folder, record)]
    print(pd.DataFrame(rows).to_markdown(index=False))


if __name__ == "__main__":
    main()
