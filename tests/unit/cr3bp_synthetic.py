"""A synthetic LT-CR3BP high-quality table whose every column moves with α in a known way (test helper).

Per row, at α drawn from ``alphas``::

    τ_s = 6 + 20 α + N(0, 0.3²) TU            (the dependence the interpolation test checks)
    τ_i + τ_f = one of two coast totals 4 or 10 TU (two TOF hyperplanes per α), split at a uniform fraction
    m_f = 415 + 20 α + N(0, 1²) kg
    θ_k = 2π (k − 1)/N + α,  φ_k = α − 0.5,  ρ_k = 0.4 + 0.5 α          (controls, k = 1 … N, in bounds)
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from amorgs.problems.cr3bp.transcription import N_SEGMENTS, variable_names


#: The α of :func:`synthetic_hq` by default (the "training α" of the tests that use it).
TRAIN_ALPHAS = (0.1, 0.4, 0.7, 1.0)


def synthetic_hq(n: int, alphas: tuple[float, ...] = TRAIN_ALPHAS, seed: int = 0) -> pd.DataFrame:
    rng = np.random.default_rng(seed)
    alpha = rng.choice(np.asarray(alphas, float), size=n)
    tau_s = 6.0 + 20.0 * alpha + rng.normal(0.0, 0.3, n)
    coast = rng.choice([4.0, 10.0], size=n)
    split = rng.uniform(0.1, 0.9, n)
    m_f = 415.0 + 20.0 * alpha + rng.normal(0.0, 1.0, n)
    k = np.arange(N_SEGMENTS)
    theta = np.mod(2 * math.pi * k[None, :] / N_SEGMENTS + alpha[:, None], 2 * math.pi)
    phi = np.broadcast_to(alpha[:, None] - 0.5, (n, N_SEGMENTS))
    rho = np.broadcast_to(0.4 + 0.5 * alpha[:, None], (n, N_SEGMENTS))
    controls = np.stack([theta, phi, rho], axis=-1).reshape(n, -1)
    x = np.column_stack([tau_s, split * coast, (1 - split) * coast, m_f, controls])
    return pd.DataFrame(x, columns=variable_names(N_SEGMENTS)).assign(alpha=alpha, converged=True)
