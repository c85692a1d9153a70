"""The five ablation samplers on briefly trained small models: layout, bounds, seeds, α, checkpoints."""

from __future__ import annotations

import math

import numpy as np
import pytest
from cr3bp_synthetic import synthetic_hq

from amorgs.models import cvae, lstm
from amorgs.models.cr3bp_models import train_control_lstm, train_time_mass_cvae, train_vanilla_cvae
from amorgs.models.samplers import (
    CHECKPOINTS,
    SAMPLER_NAMES,
    AmorGSSampler,
    CVAETimeMassUniformControl,
    UniformSampler,
    UniformTimeMassLSTMControl,
    VanillaCVAESampler,
    build_sampler,
    torch_generator,
)
from amorgs.models.training import TrainConfig
from amorgs.problems import get_problem

BRIEF = TrainConfig(epochs=5, batch_size=1024, lr=5e-3, seed=0, device="cpu")
LEARNED = tuple(n for n in SAMPLER_NAMES if n != "uniform")



@pytest.fixture(scope="module")
def problem():
    return get_problem("cr3bp")


@pytest.fixture(scope="module")
def models(one_torch_thread):
    hq = synthetic_hq(48)
    return {
        "cvae_gmm": train_time_mass_cvae(hq, "small", BRIEF),
        "vanilla_cvae": train_vanilla_cvae(hq, "small", BRIEF),
        "lstm": train_control_lstm(hq, "small", BRIEF),
    }


@pytest.fixture(scope="module")
def models_dir(models, tmp_path_factory):
    d = tmp_path_factory.mktemp("models")
    cvae.save(models["cvae_gmm"], d / CHECKPOINTS["cvae_gmm"])
    cvae.save(models["vanilla_cvae"], d / CHECKPOINTS["vanilla_cvae"])
    lstm.save(models["lstm"], d / CHECKPOINTS["lstm"])
    return d


def in_memory(name: str, problem, models):
    return {
        "uniform": lambda: UniformSampler(problem),
        "cvae_uniform_control": lambda: CVAETimeMassUniformControl(problem, models["cvae_gmm"]),
        "uniform_lstm_control": lambda: UniformTimeMassLSTMControl(problem, models["lstm"]),
        "vanilla_cvae": lambda: VanillaCVAESampler(problem, models["vanilla_cvae"]),
        "amorgs": lambda: AmorGSSampler(problem, models["cvae_gmm"], models["lstm"]),
    }[name]()


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
    assert not np.array_equal(a, sampler.sample(0.3, 16, np.random.default_rng(8)))


@pytest.mark.parametrize("name", LEARNED)
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
def test_build_sampler_round_trip_through_checkpoints(name, problem, models, models_dir):
    loaded = build_sampler(name, problem, models_dir)
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
