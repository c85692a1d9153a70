"""The transfer selector (issue 38 §2): features, the two ensembles, the selection order and the arm."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from amorgs.models.baselines import UniformSampler
from amorgs.models.selector import (
    FEATURES,
    SampledSelectorSampler,
    SelectedProposalSampler,
    SelectorSampler,
    TransferSelector,
    selection_order,
    transfer_features,
)
from amorgs.problems import get_problem

PROBLEM = get_problem("cr3bp")
NAMES = PROBLEM.variable_names


def synthetic_transfers(n: int = 600, seed: int = 0) -> pd.DataFrame:
    """Transfers whose outcome depends on the source's time of flight as the frontier's did: short transfers
    land high-quality in few iterations, long ones fail at the cap."""
    rng = np.random.default_rng(seed)
    x = PROBLEM.sample_uniform(0.5, n, rng)
    x[:, 3] = rng.uniform(415, 440, n)
    tof = x[:, :3].sum(axis=1)
    source = rng.choice([0.4, 0.5, 0.6], n)
    target = np.where(source == 0.5, 0.6, 0.5)
    ok = tof + 10 * np.abs(target - source) / target < 40
    table = pd.DataFrame(x, columns=[f"guess_{v}" for v in NAMES])
    return table.assign(alpha=target, source_alpha=source, seed=1, start=np.arange(n), converged=ok,
                        m_f=np.where(ok, 425.0, np.nan), iterations=np.where(ok, 50 + 2 * tof, 1000).astype(int))


def test_features_name_what_is_known_before_solving():
    x = PROBLEM.sample_uniform(0.3, 5, np.random.default_rng(1))
    f = transfer_features(x, 0.2, 0.3, NAMES)
    assert f.shape == (5, len(FEATURES))
    col = dict(zip(FEATURES, f.T))
    assert np.allclose(col["gap_relative"], 0.1 / 0.3) and np.allclose(col["gap_signed"], 0.1 / 0.3)
    assert np.allclose(col["tof"], x[:, :3].sum(axis=1)) and np.allclose(col["m_f"], x[:, 3])
    assert ((0 <= col["rho_full"]) & (col["rho_full"] <= 1)).all()


def test_the_selector_learns_that_long_transfers_fail_and_ranks_short_ones_first(tmp_path):
    table = synthetic_transfers()
    selector = TransferSelector(beta_kg=415.0, seed=0).fit(table, NAMES)
    x = PROBLEM.sample_uniform(0.5, 200, np.random.default_rng(7))
    f = transfer_features(x, 0.5, 0.6, NAMES)
    p, k = selector.predict(f)
    tof = x[:, :3].sum(axis=1)
    assert p[tof < 30].mean() > 0.8 > 0.2 > p[tof > 50].mean()
    assert k[tof > 50].mean() > 5 * k[tof < 30].mean()
    score = selector.score(f)
    assert np.corrcoef(score, tof)[0, 1] > 0.5  # longer transfers are ranked later
    selector.save(tmp_path / "selector.joblib")
    again = TransferSelector.load(tmp_path / "selector.joblib")
    np.testing.assert_array_equal(again.score(f), score)
    refit = TransferSelector(beta_kg=415.0, seed=0).fit(table.sample(frac=1.0, random_state=3), NAMES)
    np.testing.assert_array_equal(refit.score(f), score)  # the shards' order does not matter
    pd.to_pickle("not a selector", tmp_path / "other.joblib")
    with pytest.raises(ValueError, match="not a transfer selector"):
        TransferSelector.load(tmp_path / "other.joblib")


def test_one_class_of_labels_gives_a_constant_probability():
    table = synthetic_transfers(50).assign(converged=True, m_f=430.0)
    selector = TransferSelector().fit(table, NAMES)
    p, _ = selector.predict(transfer_features(PROBLEM.sample_uniform(0.5, 4, np.random.default_rng(0)), 0.4, 0.5,
                                              NAMES))
    assert selector.classifier is None and np.all(p == 1.0)
    with pytest.raises(ValueError, match="empty"):
        TransferSelector().fit(table.iloc[:0], NAMES)


def test_the_order_is_by_score_and_defers_a_candidate_in_a_chosen_basin():
    times = np.array([[10.0, 5, 5], [10.1, 5, 5], [20, 5, 5], [30, 5, 5]])
    order = selection_order(np.array([1.0, 2.0, 3.0, 0.5]), times, eta=0.02)
    assert order.tolist() == [3, 0, 2, 1]  # 1 lies within η of 0: after every distinct one
    assert selection_order(np.array([1.0, 2.0, 3.0, 0.5]), times, eta=0.0).tolist() == [3, 0, 1, 2]


def test_the_arm_draws_every_training_alpha_in_the_selectors_order():
    rng = np.random.default_rng(0)
    hq = pd.DataFrame(PROBLEM.sample_uniform(0.5, 40, rng), columns=NAMES)
    hq["m_f"] = 420.0
    hq["alpha"] = np.repeat([0.4, 0.5, 0.6, 0.8], 10)  # 0.8: not a training α here
    sampler = SelectorSampler(PROBLEM, hq, (0.4, 0.5, 0.6), TransferSelector().fit(synthetic_transfers(), NAMES))
    rows, scores = sampler.ranked(0.55)
    assert len(rows) == 30 and scores[0] == scores.min()  # the best first (deferral reorders only the rest)
    first = sampler.sample(0.55, 45, rng)
    assert first.shape == (45, len(NAMES))
    np.testing.assert_array_equal(first[30:], first[:15])  # beyond the candidates: the order again
    np.testing.assert_array_equal(first, sampler.sample(0.55, 45, np.random.default_rng(99)))  # no randomness
    assert not set(map(tuple, first[:, :4])) & set(map(tuple, hq[hq["alpha"] == 0.8][list(NAMES[:4])].to_numpy()))


def test_the_sampled_arm_draws_an_order_per_rng_that_favours_the_selectors_choice():
    """Issue 41: selector_sampled draws the same candidates in a Plackett–Luce order (weights 1 / score) seeded by
    the rng — the same rng gives the same order, another rng another one — and puts low-score candidates first
    far more often than a uniform order would."""
    rng = np.random.default_rng(0)
    hq = pd.DataFrame(PROBLEM.sample_uniform(0.5, 60, rng), columns=NAMES)
    hq["m_f"] = 420.0
    hq["alpha"] = np.repeat([0.4, 0.5, 0.6], 20)
    selector = TransferSelector().fit(synthetic_transfers(), NAMES)
    ranked = SelectorSampler(PROBLEM, hq, (0.4, 0.5, 0.6), selector)
    sampled = SampledSelectorSampler(PROBLEM, hq, (0.4, 0.5, 0.6), selector)
    assert sampled.name == "selector_sampled"
    rows, scores = ranked.ranked(0.55)
    a = sampled.sample(0.55, 60, np.random.default_rng(1))
    np.testing.assert_array_equal(a, sampled.sample(0.55, 60, np.random.default_rng(1)))
    assert not np.array_equal(a, sampled.sample(0.55, 60, np.random.default_rng(2)))
    assert sorted(map(tuple, a)) == sorted(map(tuple, rows))  # every candidate once, none invented
    np.testing.assert_array_equal(sampled.sample(0.55, 75, np.random.default_rng(1))[60:], a[:15])
    # the first draw's score, over many rngs, lies well below a uniform pick's mean score
    score_of = {tuple(r): s for r, s in zip(rows, scores)}
    first = np.mean([score_of[tuple(sampled.sample(0.55, 1, np.random.default_rng(k))[0])] for k in range(200)])
    assert first < 0.8 * scores.mean() and first > scores.min()


def test_selection_on_top_of_generation_solves_the_best_ranked_proposals():
    """Issue 38 §3: of oversample × n proposals the n the selector ranks best, best first, seeded by the rng;
    the selector (long transfers fail) keeps short ones, and oversample 1 only reorders the generator's draw."""
    selector = TransferSelector().fit(synthetic_transfers(), NAMES)
    generator = UniformSampler(PROBLEM)
    picked = SelectedProposalSampler(PROBLEM, generator, selector, oversample=6)
    x = picked.sample(0.5, 10, np.random.default_rng(3))
    proposals = generator.sample(0.5, 60, np.random.default_rng(3))
    ranked, scores = picked.ranked(0.5, 10, np.random.default_rng(3))
    np.testing.assert_array_equal(x, ranked[:10])
    assert sorted(map(tuple, ranked)) == sorted(map(tuple, proposals))  # a reordering of the draw
    assert scores[0] == scores.min()
    all_scores = selector.score(transfer_features(proposals, 0.5, 0.5, NAMES))
    assert scores[:10].mean() < np.median(all_scores)  # the chosen are the better ranked
    assert x[:, :3].sum(axis=1).mean() < proposals[:, :3].sum(axis=1).mean()  # shorter than the draw's mean
    np.testing.assert_array_equal(x, picked.sample(0.5, 10, np.random.default_rng(3)))
    once = SelectedProposalSampler(PROBLEM, generator, selector, oversample=1).sample(0.5, 10, np.random.default_rng(3))
    assert sorted(map(tuple, once)) == sorted(map(tuple, generator.sample(0.5, 10, np.random.default_rng(3))))
    assert picked.sample(0.5, 0, np.random.default_rng(3)).shape == (0, len(NAMES))
    with pytest.raises(ValueError, match="oversample"):
        SelectedProposalSampler(PROBLEM, generator, selector, oversample=0)
