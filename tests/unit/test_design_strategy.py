"""``amorgs design --strategy auto``: the strategy follows the committed global-search study nearest in α."""

from __future__ import annotations

import json
from pathlib import Path

import pandas as pd
import pytest

from amorgs.config import ConfigError
from amorgs.design.search import DEFAULT_GLOBAL_SEARCH, DesignRequest, resolve_strategy

ROOT = Path(__file__).resolve().parents[2]


def study(folder: Path, alpha: float, hit: dict[str, int], searches: int = 12, budget: int = 10_000) -> Path:
    """A global-search study folder whose searches of each strategy (from ``uniform``) first come within 1 kg of
    the best known m_f (440 kg) after ``hit[strategy]`` iterations, then spend the rest of the budget."""
    rows = []
    for strategy, at in hit.items():
        for r in range(searches):
            at_r = at + 10 * r
            rows += [{"sampler": "uniform", "strategy": strategy, "alpha": alpha, "search": r,
                      "cumulative_iterations": at_r, "best_objective": -439.5},
                     {"sampler": "uniform", "strategy": strategy, "alpha": alpha, "search": r,
                      "cumulative_iterations": budget, "best_objective": -439.5}]
    folder.mkdir(parents=True)
    pd.DataFrame(rows).to_parquet(folder / "events.parquet")
    (folder / "study.json").write_text(json.dumps({"alpha": alpha, "searches": searches, "budget": budget, "seed": 0}))
    pd.DataFrame({"alpha": [alpha], "m_f": [440.0], "source": ["test"]}).to_csv(folder / "best_known.csv", index=False)
    return folder


def request(**kw) -> DesignRequest:
    return DesignRequest(**{"alpha": 0.42, "n": 5, "sampler": "uniform", "strategy": "auto", **kw})


def test_auto_takes_basin_hopping_only_where_the_nearest_study_found_it_significantly_faster(tmp_path):
    study(tmp_path / "alpha=0.300", 0.3, {"multistart": 4000, "mbh": 200})  # hopping 20× faster
    study(tmp_path / "alpha=0.900", 0.9, {"multistart": 300, "mbh": 300})  # no difference
    chosen, why = resolve_strategy(request(alpha=0.35), tmp_path)
    assert chosen.strategy == "mbh" and "alpha=0.300" in why and "95 %" in why
    chosen, why = resolve_strategy(request(alpha=0.8), tmp_path)
    assert chosen.strategy == "multistart" and "alpha=0.900" in why and "not significantly faster" in why
    # a sampler the study has no cells of is judged on uniform, and says so
    chosen, why = resolve_strategy(request(alpha=0.35, sampler="amorgs"), tmp_path)
    assert chosen.strategy == "mbh" and "MBH × uniform" in why
    # no study: multi-start; a strategy given is kept
    assert resolve_strategy(request(), tmp_path / "none")[0].strategy == "multistart"
    assert resolve_strategy(request(strategy="mbh"), tmp_path / "none") == (request(strategy="mbh"),
                                                                            "strategy mbh (--strategy)")


def test_auto_on_the_committed_studies_follows_their_evidence(monkeypatch):
    """What docs/global-search.md says: at α = 0.3 and 1.0 hopping from uniform or reuse starts is not
    significantly faster to within 2 kg; from the selector's one ranking it is the only way there (multi-start
    from it never got within 2 kg: 4 of 30 MBH searches at α = 0.3, 24 of 30 at α = 1.0)."""
    monkeypatch.chdir(ROOT)
    for alpha, folder in ((0.42, "alpha=0.300"), (0.95, "alpha=1.000")):
        for sampler in ("uniform", "nearest_alpha"):
            chosen, why = resolve_strategy(request(alpha=alpha, sampler=sampler), DEFAULT_GLOBAL_SEARCH)
            assert chosen.strategy == "multistart" and f"MBH × {sampler}" in why and folder in why
        chosen, why = resolve_strategy(request(alpha=alpha, sampler="selector"), DEFAULT_GLOBAL_SEARCH)
        assert chosen.strategy == "mbh" and folder in why and "multi-start from the same sampler in none" in why


@pytest.mark.parametrize(("alpha", "folder", "selector"), [(0.11, "alpha=0.100", "mbh"),
                                                           (0.17, "alpha=0.160", "mbh")])
def test_auto_at_the_low_alpha_studies_follows_their_evidence(monkeypatch, alpha, folder, selector):
    """What docs/global-search.md says of α = 0.1 and 0.16: multi-start from reuse and from the continuation (the
    frontier's best learned arm there); from the selector's ranking MBH (multi-start from it never within 2 kg of
    the best known — at α = 0.1 the lifted record's 438.871 kg, α = 0.16's trajectory, above the study's own
    438.421 kg, within 2 kg of which that ranking alone was the fastest cell)."""
    monkeypatch.chdir(ROOT)
    for sampler in ("nearest_alpha", "continuation"):
        chosen, why = resolve_strategy(request(alpha=alpha, sampler=sampler), DEFAULT_GLOBAL_SEARCH)
        assert chosen.strategy == "multistart" and f"MBH × {sampler}" in why and folder in why
    chosen, why = resolve_strategy(request(alpha=alpha, sampler="selector"), DEFAULT_GLOBAL_SEARCH)
    assert chosen.strategy == selector and folder in why


def test_an_unknown_strategy_is_refused_naming_the_choices():
    with pytest.raises(ConfigError, match="--strategy 'hop'.*auto, multistart, mbh"):
        request(strategy="hop").check()


def test_auto_judges_a_study_against_the_best_known_record_where_that_is_higher(tmp_path):
    """A study timed to 440 kg, in which MBH gets within 2 kg of 441 kg and multi-start does not: judged against a
    record of 441 kg at its α, MBH is the only way there; against the study's own target, not faster."""
    folder = study(tmp_path / "studies" / "alpha=0.300", 0.3, {"multistart": 300, "mbh": 300})
    events = pd.read_parquet(folder / "events.parquet")
    events.loc[events["strategy"] == "mbh", "best_objective"] = -439.5
    events.loc[events["strategy"] == "multistart", "best_objective"] = -438.5
    events.to_parquet(folder / "events.parquet")
    own, why = resolve_strategy(request(alpha=0.3), tmp_path / "studies", tmp_path / "no-record.json")
    assert own.strategy == "multistart" and "not significantly faster" in why
    from amorgs.data import best_known as bk

    record = bk.read_record(tmp_path / "no-record.json")
    record["alphas"]["0.300"] = {"alpha": 0.3, "m_f_kg": 441.0, "x": [], "source": {"kind": "test", "where": "t"}}
    bk.save_record(record, tmp_path / "record.json")
    lifted, why = resolve_strategy(request(alpha=0.3), tmp_path / "studies", tmp_path / "record.json")
    assert lifted.strategy == "mbh" and "multi-start from the same sampler in none" in why
