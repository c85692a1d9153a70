"""Scoring generated De Jong samples against the analytic minima (paper Sec. V.A, Fig. 16b).

Distances are in the (dimensionless) units of the decision vector ``(x1, x2)``; the true minima are the
columns of R(α)A (:func:`amorgs.problems.dejong.true_minima`).
"""

from __future__ import annotations

import numpy as np

from amorgs.problems.dejong import true_minima


def distances_to_minima(samples: np.ndarray, alpha: float) -> np.ndarray:
    """Euclidean distance from each sample (n, 2) to each of the 8 true minima at α, shape (n, 8)."""
    samples = np.asarray(samples, dtype=float).reshape(-1, 2)
    return np.linalg.norm(samples[:, None, :] - true_minima(alpha)[None, :, :], axis=-1)


def prediction_metrics(samples: np.ndarray, alpha: float, radius: float = 3.0) -> dict:
    """How well samples (n, 2) at α cover the 8 true minima.

    ``fraction_within_radius``: fraction of samples within ``radius`` of any true minimum;
    ``minima_covered``: how many of the 8 minima have at least one sample within ``radius``;
    ``n_samples`` and ``radius`` echo the inputs.  Non-finite samples count as misses.
    """
    d = distances_to_minima(samples, alpha)
    d = np.where(np.isfinite(d), d, np.inf)
    near = d <= radius
    return {
        "fraction_within_radius": float(near.any(axis=1).mean()) if len(d) else float("nan"),
        "minima_covered": int(near.any(axis=0).sum()),
        "n_samples": int(len(d)),
        "radius": float(radius),
    }
