"""Thrust controls in Cartesian synodic components and their per-segment statistics (paper Fig. 13, Fig. 20).

Segment k of a solution has azimuth θ_k, elevation φ_k (rad) and throttle ρ_k ∈ [0, 1]; its thrust direction
in the rotating frame is û = (cos φ cos θ, cos φ sin θ, sin φ), so the throttle-weighted control is
u_k = ρ_k û_k (dimensionless, ‖u_k‖ ≤ 1; multiply by α N for the thrust).  Segments are in time order.

Per-segment statistics of a group of solutions (a funnel, a sampler's output, …) are the mean of each
component and a 95 % interval, either

- ``"mean_ci"`` (default): the Student-t confidence interval of the mean, mean ± t_{0.975, n−1} s/√n — what
  the paper's Fig. 13 shows ("few samples … large variance"); NaN bounds for a group of one; or
- ``"percentile"``: the 2.5–97.5 % percentile band of the group itself (the spread of the solutions).
"""

from __future__ import annotations

import re

import numpy as np
import pandas as pd
from scipy import stats

from amorgs.analysis.structure_params import INTERVALS
from amorgs.problems.cr3bp.controls import thrust_vectors

COMPONENTS = ("u_x", "u_y", "u_z")


def n_segments(df: pd.DataFrame) -> int:
    """Number of control segments N in a solution table (from its ``theta_kk`` columns)."""
    return sum(1 for c in df.columns if re.fullmatch(r"theta_\d+", c))


def thrust_components(df: pd.DataFrame) -> np.ndarray:
    """u = ρ (cos φ cos θ, cos φ sin θ, sin φ) for every row and segment, shape (n, N, 3)."""
    segs = [f"{k:02d}" for k in range(1, n_segments(df) + 1)]
    th, ph, rho = (df[[f"{v}_{s}" for s in segs]].to_numpy(dtype=float) for v in ("theta", "phi", "rho"))
    return thrust_vectors(th, ph, rho)


def segment_statistics(u: np.ndarray, interval: str = "mean_ci", level: float = 0.95) -> pd.DataFrame:
    """Per segment and component of ``u`` (n, N, 3): ``mean``, ``lower``, ``upper`` and ``n``.

    Long format with columns ``segment`` (1 … N), ``component`` (u_x, u_y, u_z), ``mean``, ``lower``,
    ``upper``, ``n``; ``interval`` as in the module docstring, at confidence ``level``.
    """
    if interval not in INTERVALS:
        raise ValueError(f"interval must be one of {INTERVALS}, got {interval!r}")
    u = np.asarray(u, float)
    n, n_seg, _ = u.shape
    mean = u.mean(axis=0) if n else np.full((n_seg, 3), np.nan)
    if interval == "mean_ci":
        if n >= 2:
            half = stats.t.ppf(0.5 + level / 2, n - 1) * u.std(axis=0, ddof=1) / np.sqrt(n)
        else:
            half = np.full((n_seg, 3), np.nan)
        lower, upper = mean - half, mean + half
    elif n:
        lower, upper = np.quantile(u, [(1 - level) / 2, (1 + level) / 2], axis=0)
    else:
        lower = upper = np.full((n_seg, 3), np.nan)
    seg, comp = np.meshgrid(np.arange(1, n_seg + 1), np.arange(3), indexing="ij")
    return pd.DataFrame(
        {
            "segment": seg.ravel(),
            "component": np.array(COMPONENTS)[comp.ravel()],
            "mean": mean.ravel(),
            "lower": lower.ravel(),
            "upper": upper.ravel(),
            "n": n,
        }
    )


def group_statistics(df: pd.DataFrame, groups: pd.Series | np.ndarray, interval: str = "mean_ci",
                     level: float = 0.95) -> pd.DataFrame:
    """:func:`segment_statistics` of each group of rows of ``df``; a ``group`` column leads the result."""
    groups = np.asarray(groups)
    u = thrust_components(df)
    frames = [segment_statistics(u[groups == g], interval, level).assign(group=g) for g in pd.unique(groups)]
    if not frames:
        return pd.DataFrame(columns=["group", "segment", "component", "mean", "lower", "upper", "n"])
    out = pd.concat(frames, ignore_index=True)
    return out[["group", *[c for c in out.columns if c != "group"]]]
