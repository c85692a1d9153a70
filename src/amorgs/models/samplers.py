"""Initial-guess samplers for warm-starting the solver (DESIGN.md contract, paper Sec. V.B.7).

Every sampler has ``sample(alpha, n, rng) -> ndarray (n, 3N+4)`` in the stored decision-vector layout
(see :mod:`amorgs.problems.cr3bp.transcription`) and returns *valid* guesses: inside the problem's bounds,
azimuths wrapped to [0, 2π), throttles clipped to [0, 1].  ``rng`` is a ``numpy.random.Generator``; learned
samplers derive their torch seed from it, so a seeded rng gives identical samples.
"""

from __future__ import annotations

import math
from typing import Protocol

import numpy as np

from amorgs.problems import Problem

SAMPLER_NAMES = ("uniform", "cvae_uniform_control", "uniform_lstm_control", "vanilla_cvae", "amorgs")
SAMPLER_LABELS = {
    "uniform": "Uniform",
    "uniform_lstm_control": "Uniform time & mass, LSTM control",
    "cvae_uniform_control": "CVAE time & mass, uniform control",
    "vanilla_cvae": "Vanilla CVAE",
    "amorgs": "AmorGS",
}


class Sampler(Protocol):
    name: str

    def sample(self, alpha: float, n: int, rng: np.random.Generator) -> np.ndarray: ...


def make_valid(x: np.ndarray, problem: Problem) -> np.ndarray:
    """Wrap azimuths (every ``theta_*`` column) to [0, 2π) and clip everything else into the bounds."""
    x = np.array(x, dtype=float, copy=True)
    theta = [i for i, name in enumerate(problem.variable_names) if name.startswith("theta_")]
    x[:, theta] = np.mod(x[:, theta], 2 * math.pi)
    return np.clip(x, problem.lower, problem.upper)


class UniformSampler:
    """The naive baseline: the problem's own uniform initial-guess distribution (spec §6)."""

    name = "uniform"

    def __init__(self, problem: Problem):
        self.problem = problem

    def sample(self, alpha: float, n: int, rng: np.random.Generator) -> np.ndarray:
        return make_valid(self.problem.sample_uniform(alpha, n, rng), self.problem)
