"""η-diverse subsets of the high-quality set (paper Sec. II.D.2, Eq. 12–13).

Eq. 12 asks for the largest subset whose solutions are pairwise more than η apart under a diversity metric d̂.
That is a maximum independent set of the *conflict graph* (an edge wherever d̂ ≤ η), NP-hard in general; we
solve it with the classic minimum-degree greedy: repeatedly keep the remaining solution with the fewest
remaining conflicts (ties: higher m_f, then lower row index), drop it and its neighbours.  The result is
η-diverse and *maximal* — no left-out solution can be added — and on sparse conflict graphs it is usually
close to the maximum.  A search that finds solutions one after another holds a different η-diverse set:
:func:`first_come_diverse` keeps each solution farther than η from every one kept before it (the *new*
η-distinct optima), so the set only grows as solutions arrive; it is maximal too, but may be smaller.
η⁻ (Eq. 13) is the smallest nearest-neighbour distance in the set; η must exceed it for Eq. 12 to remove
anything.

Surrogate metric (the paper suggests a Euclidean one on the decision space), chosen by ``features``:

- ``"times"`` (default): Euclidean on (τ_s/40, τ_i/15, τ_f/15) — the time coordinates divided by the upper
  bounds of their decision box (spec §5), so each axis is the fraction of its admissible range and η is
  dimensionless.  Times are what separate qualitatively different transfers (hyperplanes ↔ revolutions).
- ``"full"``: those three plus the 20 Cartesian thrust vectors u_k = ρ_k û_k (dimensionless, ‖u_k‖ ≤ 1),
  63 coordinates.  Cartesian rather than (θ, φ, ρ) because the azimuth wraps at 2π and the angles are
  arbitrary when ρ = 0.  m_f is left out: it measures quality, not qualitative difference.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pandas as pd
from sklearn.neighbors import NearestNeighbors, radius_neighbors_graph

from amorgs.analysis.controls import thrust_components
from amorgs.analysis.hyperplanes import TIME_COLUMNS
from amorgs.analysis.structure_params import FEATURE_SETS, DiversityParams  # noqa: F401  (re-exported)


@dataclass
class DiversityResult:
    """Row positions of the chosen η-diverse subset, its size, η and η⁻ (Eq. 13; NaN with < 2 solutions)."""

    indices: np.ndarray
    size: int
    eta: float
    eta_minus: float


def diversity_features(df: pd.DataFrame, params: DiversityParams = DiversityParams()) -> np.ndarray:
    """The scaled coordinates the surrogate metric is Euclidean on, shape (n, 3) or (n, 63)."""
    times = df[list(TIME_COLUMNS)].to_numpy(dtype=float) / np.asarray(params.time_scale, float)
    if params.features == "times":
        return times
    return np.column_stack([times, thrust_components(df).reshape(len(df), -1)])


def eta_minus(features: np.ndarray) -> float:
    """Eq. 13: min over solutions of the distance to the nearest other one; NaN with fewer than 2."""
    features = np.asarray(features, float)
    if len(features) < 2:
        return math.nan
    dist, _ = NearestNeighbors(n_neighbors=2).fit(features).kneighbors(features)
    return float(dist[:, 1].min())


def greedy_diverse_subset(features: np.ndarray, eta: float, quality: np.ndarray | None = None) -> np.ndarray:
    """Minimum-degree greedy maximal η-diverse subset (pairwise distance > η); sorted row positions.

    ``quality`` (higher is better, e.g. m_f) breaks ties between equally constrained solutions.
    """
    features = np.asarray(features, float)
    n = len(features)
    if n == 0:
        return np.empty(0, dtype=int)
    graph = radius_neighbors_graph(features, radius=eta, mode="connectivity", include_self=False).tocsr()
    neighbours = np.split(graph.indices, graph.indptr[1:-1])
    degree = np.diff(graph.indptr).astype(np.int64)
    q = np.zeros(n) if quality is None else np.asarray(quality, float)
    # Static tie-break rank: higher quality first, then lower index.
    rank = np.empty(n, dtype=np.int64)
    rank[np.lexsort((np.arange(n), -q))] = np.arange(n)
    alive = np.ones(n, dtype=bool)
    chosen = []
    while alive.any():
        cand = np.flatnonzero(alive)
        v = cand[np.lexsort((rank[cand], degree[cand]))[0]]
        chosen.append(v)
        removed = [v, *[u for u in neighbours[v] if alive[u]]]
        alive[removed] = False
        for u in removed:
            degree[neighbours[u]] -= 1
    return np.sort(np.array(chosen, dtype=int))


def conflicts(features: np.ndarray, eta: float) -> np.ndarray:
    """The conflict graph of Eq. 12 as a dense boolean matrix (n, n): True where d̂ ≤ η (the diagonal too)."""
    features = np.asarray(features, float)
    return np.linalg.norm(features[:, None, :] - features[None, :, :], axis=-1) <= eta


def first_come_diverse(close: np.ndarray, order: np.ndarray) -> np.ndarray:
    """Which solutions are *new* η-distinct optima when they arrive in ``order``.

    ``close``: :func:`conflicts` of the solutions (k, k); ``order``: row positions into it, 1-D (one sequence)
    or 2-D (one sequence per row, e.g. bootstrap resamples); a position may repeat (a repeat is never new) and
    a negative one stands for a start without a solution (never new).  Returns a boolean array shaped like
    ``order``: True where the solution is farther than η from every solution kept before it in its sequence.
    The kept solutions of a sequence are an η-diverse set (Eq. 12's constraint), maximal among its solutions.
    """
    close = np.asarray(close, bool)
    order = np.asarray(order, dtype=np.int64)
    seqs = np.atleast_2d(order)
    new = np.zeros(seqs.shape, dtype=bool)
    if not close.shape[0]:
        return new.reshape(order.shape)
    blocked = np.zeros((seqs.shape[0], close.shape[0]), dtype=bool)
    rows = np.arange(seqs.shape[0])
    for t in range(seqs.shape[1]):
        i = seqs[:, t]
        fresh = (i >= 0) & ~blocked[rows, np.maximum(i, 0)]
        new[:, t] = fresh
        blocked[fresh] |= close[i[fresh]]
    return new.reshape(order.shape)


def is_eta_diverse(features: np.ndarray, indices: np.ndarray, eta: float) -> bool:
    """True when every pair of the selected rows is more than η apart."""
    sub = np.asarray(features, float)[np.asarray(indices, int)]
    if len(sub) < 2:
        return True
    return eta_minus(sub) > eta


def diverse_subset(df: pd.DataFrame, params: DiversityParams = DiversityParams()) -> DiversityResult:
    """Eq. 12 on the solutions ``df`` (one α; columns tau_*, m_f and for ``"full"`` the controls)."""
    feats = diversity_features(df, params)
    idx = greedy_diverse_subset(feats, params.eta, df["m_f"].to_numpy(dtype=float))
    return DiversityResult(indices=idx, size=int(idx.size), eta=float(params.eta), eta_minus=eta_minus(feats))
