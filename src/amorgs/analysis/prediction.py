"""How well generated samples match the ground truth at held-out α (paper Sec. V.B.3–5, Figs. 17–19).

Inputs are tables with named columns: ``samples`` (from a sampler in the stored layout, or from the time &
mass CVAE alone) and ``truth`` (the high-quality solutions of an extensive search at the same α), both with
``alpha``, ``tau_s``, ``tau_i``, ``tau_f`` (TU) and ``m_f`` (kg).  TOF = τ_s + τ_i + τ_f (TU).

Metrics of one sample set against its ground truth (:func:`prediction_metrics`):

- ``tof_w1`` (TU), ``m_f_w1`` (kg): the Wasserstein-1 distance between the sampled and the true marginal
  distributions of TOF and of m_f (``scipy.stats.wasserstein_distance``; the mean |shift| of mass that turns
  one empirical distribution into the other, so 0 for identical distributions and Δ for a pure shift by Δ).
- ``n_modes``: ground-truth hyperplanes, i.e. the modes T of the true TOF density
  (:func:`amorgs.analysis.hyperplanes.detect_modes` with the given :class:`ModeParams`).
- ``fraction_on_hyperplanes``: the fraction of samples with |TOF − T| ≤ δ for some true mode T (Eq. 32,
  δ = ``params.delta``, the paper's 0.25 TU); ``truth_fraction_on_hyperplanes`` the same for the truth itself
  (its ceiling: true solutions between planes or on planes too sparse to count).
- ``modes_covered``: true modes with at least one sample within δ.

With no ground truth at an α every comparison is NaN (``n_truth`` = 0): nothing is made up.  Samples and
truth are matched by α label (:func:`amorgs.alphas.rows_at`).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pandas as pd
from scipy.stats import wasserstein_distance

from amorgs.alphas import alpha_value, rows_at
from amorgs.analysis.hyperplanes import ModeParams, assign_hyperplane, detect_modes, time_of_flight

METRICS = (
    "n_samples",
    "n_truth",
    "tof_w1",
    "m_f_w1",
    "n_modes",
    "fraction_on_hyperplanes",
    "truth_fraction_on_hyperplanes",
    "modes_covered",
)


def _finite(values: np.ndarray) -> np.ndarray:
    values = np.asarray(values, dtype=float)
    return values[np.isfinite(values)]


def prediction_metrics(samples: pd.DataFrame, truth: pd.DataFrame, params: ModeParams = ModeParams()) -> dict:
    """The metrics of the module docstring for ``samples`` against ``truth`` (both at one α)."""
    s_tof, t_tof = _finite(time_of_flight(samples)), _finite(time_of_flight(truth))
    s_mf, t_mf = _finite(samples["m_f"]), _finite(truth["m_f"])
    out: dict = {"n_samples": len(samples), "n_truth": len(truth)}
    if s_tof.size == 0 or t_tof.size == 0:
        return out | {k: np.nan for k in METRICS if k not in out}
    modes = detect_modes(t_tof, params)
    on_plane = assign_hyperplane(s_tof, modes, params.delta)
    return out | {
        "tof_w1": float(wasserstein_distance(s_tof, t_tof)),
        "m_f_w1": float(wasserstein_distance(s_mf, t_mf)) if s_mf.size and t_mf.size else np.nan,
        "n_modes": int(modes.size),
        "fraction_on_hyperplanes": float(np.mean(on_plane >= 0)),
        "truth_fraction_on_hyperplanes": float(np.mean(assign_hyperplane(t_tof, modes, params.delta) >= 0)),
        "modes_covered": int(np.unique(on_plane[on_plane >= 0]).size),
    }


def prediction_table(
    samples: pd.DataFrame,
    truth: pd.DataFrame,
    params: ModeParams = ModeParams(),
    by: Sequence[str] = ("alpha",),
) -> pd.DataFrame:
    """:func:`prediction_metrics` for every group of ``samples`` by the columns ``by`` (which include
    ``alpha``; e.g. ``("alpha", "data_fraction")``), each against the truth rows at the group's α.  α are
    grouped by label; the ``alpha`` column holds :func:`amorgs.alphas.alpha_value`.

    One row per group: the ``by`` columns, then :data:`METRICS`; sorted by the group keys.
    """
    by = list(by)
    if "alpha" not in by:
        raise ValueError(f"prediction_table: 'by' must include 'alpha', got {by}")
    rows = []
    for keys, group in samples.assign(alpha=samples["alpha"].map(alpha_value)).groupby(by, sort=True):
        key = dict(zip(by, keys if isinstance(keys, tuple) else (keys,)))
        rows.append(key | prediction_metrics(group, rows_at(truth, key["alpha"]), params))
    return pd.DataFrame(rows, columns=[*by, *METRICS])
