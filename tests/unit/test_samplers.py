"""The ablation samplers on briefly trained small models: layout, bounds, seeds, α, checkpoints."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest
from cr3bp_synthetic import TRAIN_ALPHAS, synthetic_hq

from amorgs.ablation.arms import ARMS, SAMPLER_NAMES, ArmInputs, build_sampler, get_arm
from amorgs.models import cvae
from amorgs.models.cvae import torch_generator
from amorgs.models.names import CHECKPOINTS, resolve
from amorgs.models.samplers import (
    ContinuationSampler,
    GMMLSTMSampler,
    NearestAlphaPerturbedSampler,
    NearestAlphaSampler,
    UniformSampler,
    make_valid,
    nearest_training_alpha,
)
from amorgs.problems import get_problem

#: Every arm whose guesses depend on α through what it draws on (models, training-α solutions).
CONDITIONED = tuple(arm.name for arm in ARMS if arm.upfront)


@pytest.fixture(scope="module")
def hq(tiny_hq):
    return tiny_hq


@pytest.fixture(scope="module")
def problem():
    return get_problem("cr3bp")


@pytest.fixture(scope="module")
def models(tiny_models):
    return tiny_models


@pytest.fixture(scope="module")
def models_dir(tiny_models_dir):
    return tiny_models_dir


def in_memory(name: str, problem, models, hq=None):
    """The sampler of arm ``name`` built by its builder from models in memory (no checkpoints), the reuse
    arms' σ 0.02 and the GMM arm's 3 components."""
    hq = synthetic_hq(48) if hq is None else hq
    arm = get_arm(name)
    inputs = ArmInputs(models={m: models[m] for m in (*arm.models, *(["selector"] if arm.transfer else []))},
                       high_quality=hq, train_alphas=TRAIN_ALPHAS,
                       perturbation_scale=0.02, gmm_components=3)
    return resolve(arm.builder)(problem, inputs)


@pytest.mark.parametrize("name", SAMPLER_NAMES)
def test_valid_decision_vectors(name, problem, models):
    sampler = in_memory(name, problem, models)
    assert sampler.name == name
    x = sampler.sample(0.55, 40, np.random.default_rng(0))
    assert x.shape == (40, 64) and np.all(np.isfinite(x))
    assert np.all(x >= problem.lower) and np.all(x <= problem.upper)
    assert np.all(x[:, 4::3] < 2 * math.pi)  # azimuths wrapped, not clipped onto 2π
    for row in x:
        problem.check_guess(row)


@pytest.mark.parametrize("name", SAMPLER_NAMES)
def test_seeded_rng_gives_identical_samples(name, problem, models):
    sampler = in_memory(name, problem, models)
    a = sampler.sample(0.3, 16, np.random.default_rng(7))
    np.testing.assert_array_equal(a, sampler.sample(0.3, 16, np.random.default_rng(7)))
    # another rng, other samples — but for an arm whose order is its model's (the selector's), not the rng's
    assert np.array_equal(a, sampler.sample(0.3, 16, np.random.default_rng(8))) == get_arm(name).rng_free


@pytest.mark.parametrize("name", CONDITIONED)
def test_conditioning_on_alpha_changes_the_samples(name, problem, models):
    sampler = in_memory(name, problem, models)
    low = sampler.sample(0.15, 16, np.random.default_rng(3))
    high = sampler.sample(0.85, 16, np.random.default_rng(3))
    assert np.abs(low - high).max() > 1e-3


def test_which_parts_each_sampler_draws_from_the_model(problem, models):
    """Time & mass from the CVAE or uniform; controls from the LSTM or uniform — as the names say."""
    rng = lambda: np.random.default_rng(5)  # noqa: E731
    uniform = UniformSampler(problem).sample(0.5, 8, rng())
    cvae_uniform = in_memory("cvae_uniform_control", problem, models).sample(0.5, 8, rng())
    uniform_lstm = in_memory("uniform_lstm_control", problem, models).sample(0.5, 8, rng())
    amorgs = in_memory("amorgs", problem, models).sample(0.5, 8, rng())
    np.testing.assert_array_equal(uniform_lstm[:, :4], uniform[:, :4])  # the same uniform time & mass draws
    tm = models["cvae_gmm"].sample(0.5, 8, generator=torch_generator(rng())).numpy()
    np.testing.assert_allclose(amorgs[:, :4], np.clip(tm, problem.lower[:4], problem.upper[:4]), rtol=1e-6)
    np.testing.assert_allclose(cvae_uniform[:, :4], amorgs[:, :4])
    cond = np.column_stack([amorgs[:, :4], np.full(8, 0.5)])
    np.testing.assert_allclose(amorgs[:, 4:], models["lstm"].generate(cond), atol=1e-6)


@pytest.mark.parametrize("name", SAMPLER_NAMES)
def test_build_sampler_round_trip_through_checkpoints(name, problem, models, models_dir, hq):
    loaded = build_sampler(name, problem, models_dir, high_quality=hq, train_alphas=TRAIN_ALPHAS,
                           perturbation_scale=0.02, gmm_components=3)
    assert loaded.name == name
    expected = in_memory(name, problem, models).sample(0.85, 12, np.random.default_rng(11))
    np.testing.assert_array_equal(loaded.sample(0.85, 12, np.random.default_rng(11)), expected)


def test_build_sampler_errors(problem, models, models_dir, tmp_path):
    with pytest.raises(ValueError, match="unknown sampler"):
        build_sampler("diffusion", problem, models_dir)
    with pytest.raises(FileNotFoundError):
        build_sampler("amorgs", problem, tmp_path)
    cvae.save(models["vanilla_cvae"], tmp_path / CHECKPOINTS["cvae_gmm"])  # the wrong model under the name
    with pytest.raises(ValueError, match="GMMPriorCVAE"):
        build_sampler("cvae_uniform_control", problem, tmp_path)
    with pytest.raises(ValueError, match="alpha"):
        in_memory("amorgs", problem, models).sample(1.5, 4, np.random.default_rng(0))


# ------------------------------------------------------------------------------ the reuse baselines


def test_nearest_alpha_reuses_training_rows_unchanged_and_never_the_test_alpha(problem, hq):
    names = list(problem.variable_names)
    # add rows AT the query α = 0.15 (a "test" α): they must never be drawn
    leak = hq[np.isclose(hq["alpha"], 0.1)].assign(alpha=0.15, m_f=999.0)
    table = pd.concat([hq, leak], ignore_index=True)
    sampler = NearestAlphaSampler(problem, table, (*TRAIN_ALPHAS, 0.15))
    assert nearest_training_alpha(sampler.by_alpha, 0.15) == 0.1
    plain = NearestAlphaSampler(problem, hq, TRAIN_ALPHAS)
    assert nearest_training_alpha(plain.by_alpha, 0.25) == 0.1  # tie 0.1 / 0.4 → the smaller α
    assert nearest_training_alpha(plain.by_alpha, 0.9) == pytest.approx(1.0)
    x = sampler.sample(0.15, 200, np.random.default_rng(0))
    source = make_valid(hq.loc[np.isclose(hq["alpha"], 0.1), names].to_numpy(), problem)
    # every draw is one of α = 0.1's solutions, exactly; 200 draws from fewer rows: the pool, then repeats
    match = np.all(np.isclose(x[:, None, :], source[None, :, :], atol=1e-12), axis=2)
    assert match.any(axis=1).all() and len(source) < 200
    assert sampler.pool(0.15) == (0.1, len(source))
    assert set(match[: len(source)].argmax(axis=1)) == set(range(len(source)))  # the whole pool comes first
    assert not np.any(x[:, 3] == 999.0)
    # restricted to training α: rows at α not in the training list are ignored
    only = NearestAlphaSampler(problem, table, (0.7,))
    assert list(only.by_alpha) == [0.7]


@pytest.mark.parametrize("name", ["nearest_alpha", "nearest_alpha_perturbed"])
def test_reuse_draws_without_replacement_until_the_pool_is_exhausted(name, problem, hq):
    sampler = in_memory(name, problem, None, hq)
    source_alpha, pool = sampler.pool(0.85)
    assert source_alpha == 0.7 and pool == int(np.isclose(hq["alpha"], 0.7).sum())  # 0.85: 0.7 and 1.0 tie
    # the perturbed arm's noise is zero here so rows can be matched exactly
    draw = (NearestAlphaPerturbedSampler(problem, hq, TRAIN_ALPHAS, 0.0) if name.endswith("perturbed")
            else sampler)
    for n in (1, pool - 1, pool):
        x = draw.sample(0.85, n, np.random.default_rng(n))
        assert len(np.unique(x, axis=0)) == n  # n ≤ pool: no repeated row
    x = draw.sample(0.85, pool + 5, np.random.default_rng(1))
    assert len(np.unique(x[:pool], axis=0)) == pool  # the pool exhausted first, …
    assert len(np.unique(x, axis=0)) == pool  # … then the 5 extra draws repeat pool rows
    np.testing.assert_array_equal(x, draw.sample(0.85, pool + 5, np.random.default_rng(1)))  # seeded
    # the model seeds' cells take consecutive slices of one draw (run_cell's start_offset): pooled, no repeats
    n = pool // 3
    cells = [draw.sample(0.85, (k + 1) * n, np.random.default_rng(7))[k * n:] for k in range(3)]
    assert len(np.unique(np.concatenate(cells), axis=0)) == 3 * n


def test_nearest_alpha_perturbed_noise_scale(problem, hq):
    base = NearestAlphaSampler(problem, hq, TRAIN_ALPHAS).sample(0.85, 400, np.random.default_rng(4))
    zero = NearestAlphaPerturbedSampler(problem, hq, TRAIN_ALPHAS, 0.0).sample(0.85, 400, np.random.default_rng(4))
    np.testing.assert_allclose(zero, base, atol=1e-9)
    noisy = NearestAlphaPerturbedSampler(problem, hq, TRAIN_ALPHAS, 0.02).sample(0.85, 400, np.random.default_rng(4))
    z = (noisy[:, :4] - base[:, :4]) / (problem.upper[:4] - problem.lower[:4])  # τ, m_f: far from the bounds
    assert np.std(z) == pytest.approx(0.02, rel=0.1)
    with pytest.raises(ValueError, match="scale"):
        NearestAlphaPerturbedSampler(problem, hq, TRAIN_ALPHAS, -1.0)


def test_continuation_moves_the_reused_solutions_along_alpha(problem, hq):
    """On the synthetic table (τ_s = 6 + 20 α, m_f = 415 + 20 α plus noise) the secant carries the nearest
    training α's solutions to the trend at α: between two training α (interpolation) and beyond the range
    (extrapolation); the queried α's own rows are never used."""
    sampler = ContinuationSampler(problem, hq, TRAIN_ALPHAS)
    upper = ContinuationSampler(problem, hq, (0.4, 0.7, 1.0))
    assert (sampler.pool(0.5)[0], sampler.partner(0.5)) == (0.4, 0.7)  # across α: interpolation
    assert (upper.pool(0.25)[0], upper.partner(0.25)) == (0.4, 0.7)  # below the training α: extrapolation
    for s, alpha in ((sampler, 0.5), (upper, 0.25)):
        x = s.sample(alpha, 200, np.random.default_rng(2))
        assert x[:, 0].mean() == pytest.approx(6 + 20 * alpha, abs=0.3)
        assert x[:, 3].mean() == pytest.approx(415 + 20 * alpha, abs=1.0)
    reused = NearestAlphaSampler(problem, hq, TRAIN_ALPHAS).sample(0.5, 200, np.random.default_rng(2))
    assert reused[:, 0].mean() == pytest.approx(6 + 20 * 0.4, abs=0.3)  # reuse stays at a₀ = 0.4
    leak = hq[np.isclose(hq["alpha"], 0.7)].assign(alpha=0.5, m_f=999.0)
    with_leak = ContinuationSampler(problem, pd.concat([hq, leak], ignore_index=True), (*TRAIN_ALPHAS, 0.5))
    np.testing.assert_array_equal(with_leak.sample(0.5, 50, np.random.default_rng(3)),
                                  sampler.sample(0.5, 50, np.random.default_rng(3)))
    one = ContinuationSampler(problem, hq, (0.4,))  # one training α: plain reuse
    np.testing.assert_array_equal(one.sample(0.5, 20, np.random.default_rng(1)),
                                  NearestAlphaSampler(problem, hq, (0.4,)).sample(0.5, 20, np.random.default_rng(1)))


def test_gmm_lstm_blends_the_bracketing_alphas(problem, hq, models):
    sampler = GMMLSTMSampler(problem, hq, TRAIN_ALPHAS, models["lstm"], 2)
    (a, wa), (b, wb) = sampler.bracket(0.55)
    assert (a, b) == (0.4, 0.7) and wa == pytest.approx(0.5) and wb == pytest.approx(0.5)
    assert sampler.bracket(0.05)[0] == (0.1, 1.0)  # outside the training range: the nearest α
    # synthetic τ_s = 6 + 20 α: at α = 0.4 + 0.3 w_b the blend has mean 6 + 20 (0.4 wa + 0.7 wb)
    tm = sampler.time_mass(0.625, 4000, np.random.default_rng(1))
    assert tm[:, 0].mean() == pytest.approx(6 + 20 * (0.4 * 0.25 + 0.7 * 0.75), abs=0.3)
    assert tm[:, 3].mean() == pytest.approx(415 + 20 * (0.4 * 0.25 + 0.7 * 0.75), abs=1.0)


def test_baselines_need_their_inputs(problem, models_dir, hq):
    with pytest.raises(ValueError, match="high-quality"):
        build_sampler("nearest_alpha", problem, models_dir)
    with pytest.raises(ValueError, match="models directory"):
        build_sampler("gmm_lstm", problem, None, high_quality=hq, train_alphas=TRAIN_ALPHAS)
    with pytest.raises(ValueError, match="no high-quality rows"):
        NearestAlphaSampler(problem, hq, (0.33,))
