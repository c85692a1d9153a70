"""Funnel clusters inside one time-of-flight hyperplane (paper Sec. III.B.6, Figs. 11–12, Tables 1–2).

Within a hyperplane H_T the solutions spread over the in-plane coordinates (τ1', τ2') of
:mod:`amorgs.analysis.hyperplanes` (TU).  The paper outlines its funnels by eye; here a Gaussian mixture is
fitted for k = 1 … ``max_funnels`` components and, among the fits whose every funnel has at least
``min_per_funnel`` members, the one with the lowest BIC wins — so the number of funnels is chosen by the data,
and a mixture cannot explain two or three stray solutions by a funnel of their own (a plane with fewer than
``2·min_per_funnel`` solutions is a single funnel).  With ``use_mass`` the final mass m_f (kg) is a
third feature; a full-covariance mixture is affine-equivariant, so the relative scaling of the features does
not matter and there is no weight to tune.  Fits are seeded (``seed``) and see the rows in a canonical order,
so the result is reproducible and independent of how the table is sorted.

Funnels are named A, B, C, … in order of decreasing size (ties: higher best m_f first).
"""

from __future__ import annotations

import string
from dataclasses import dataclass, field

import numpy as np
import pandas as pd
from sklearn.mixture import GaussianMixture

from amorgs.analysis.structure_params import FunnelParams  # noqa: F401  (re-exported)


@dataclass
class FunnelResult:
    """``labels`` (n,) funnel index per solution (0 = A), ``n_funnels``, and the BIC of every k tried
    (admissible or not)."""

    labels: np.ndarray
    n_funnels: int
    bic: dict[int, float] = field(default_factory=dict)


#: Columns of :func:`funnel_table`.
TABLE_COLUMNS = ("plane_tof", "funnel", "count", "tau_s_mean", "tau_i_mean", "tau_f_mean", "coast_mean", "tof_mean",
                 "m_f_mean", "m_f_best", "tau1p_mean", "tau2p_mean")


def funnel_name(index: int) -> str:
    """0 → 'A', 1 → 'B', …"""
    return string.ascii_uppercase[index]


def cluster_funnels(inplane: np.ndarray, m_f: np.ndarray, params: FunnelParams = FunnelParams()) -> FunnelResult:
    """Cluster solutions of one hyperplane by (τ1', τ2') [TU] (and m_f [kg] with ``use_mass``)."""
    inplane = np.asarray(inplane, float).reshape(-1, 2)
    n = len(inplane)
    features = np.column_stack([inplane, np.asarray(m_f, float)]) if params.use_mass else inplane
    k_max = min(params.max_funnels, n // params.min_per_funnel)
    if k_max < 2:
        return FunnelResult(labels=np.zeros(n, dtype=int), n_funnels=1 if n else 0)
    # Fit on the rows in a canonical (lexicographic) order so the result does not depend on the row order.
    canonical = features[np.lexsort(features.T[::-1])]
    bic, labels = {}, {}
    for k in range(1, k_max + 1):
        gm = GaussianMixture(k, covariance_type="full", n_init=params.n_init, random_state=params.seed)
        gm.fit(canonical)
        bic[k], labels[k] = float(gm.bic(features)), gm.predict(features)
    admissible = [k for k in bic if k == 1 or np.bincount(labels[k], minlength=k).min() >= params.min_per_funnel]
    raw = labels[min(admissible, key=bic.get)]
    # Rename by decreasing size, then by decreasing best m_f.
    m = np.asarray(m_f, float)
    order = sorted(np.unique(raw), key=lambda c: (-np.sum(raw == c), -np.max(m[raw == c])))
    remap = {c: i for i, c in enumerate(order)}
    return FunnelResult(labels=np.array([remap[c] for c in raw], dtype=int), n_funnels=len(order), bic=bic)


def funnel_table(plane: pd.DataFrame, labels: np.ndarray, plane_tof: float) -> pd.DataFrame:
    """Tables 1–2 for one hyperplane: one row per funnel.

    ``plane`` holds the hyperplane's solutions with ``tau_s, tau_i, tau_f, m_f, tau1p, tau2p``.  Columns:
    ``plane_tof`` (T, TU), ``funnel`` (A, B, …), ``count``, the means of τ_s, τ_i, τ_f, total coast τ_i + τ_f
    and TOF (TU), ``m_f_mean`` and ``m_f_best`` (kg), and the funnel centre ``tau1p_mean``, ``tau2p_mean`` (TU).
    """
    d = plane.assign(funnel=[funnel_name(i) for i in labels], coast=plane["tau_i"] + plane["tau_f"],
                     tof=plane["tau_s"] + plane["tau_i"] + plane["tau_f"])
    g = d.groupby("funnel", sort=True)
    table = pd.DataFrame(
        {
            "count": g.size(),
            "tau_s_mean": g["tau_s"].mean(),
            "tau_i_mean": g["tau_i"].mean(),
            "tau_f_mean": g["tau_f"].mean(),
            "coast_mean": g["coast"].mean(),
            "tof_mean": g["tof"].mean(),
            "m_f_mean": g["m_f"].mean(),
            "m_f_best": g["m_f"].max(),
            "tau1p_mean": g["tau1p"].mean(),
            "tau2p_mean": g["tau2p"].mean(),
        }
    ).reset_index()
    table.insert(0, "plane_tof", float(plane_tof))
    return table[list(TABLE_COLUMNS)]
