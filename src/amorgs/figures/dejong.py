"""Figures of De Jong's 5th function (paper Fig. 2 and Fig. 16): data in, matplotlib Figure out, no file IO.

Coordinates ``x1``, ``x2`` and the objective J are dimensionless; α is in radians.
"""

from __future__ import annotations

import math

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd
from matplotlib.colors import LogNorm
from matplotlib.figure import Figure

from amorgs.alphas import rows_at_any
from amorgs.problems.dejong import DeJong5, dejong5, foxholes_25, true_minima


def _grid(n: int) -> tuple[np.ndarray, np.ndarray]:
    p = DeJong5()
    return np.meshgrid(np.linspace(p.lower[0], p.upper[0], n), np.linspace(p.lower[1], p.upper[1], n))


def fig02_foxholes(resolution: int = 201) -> Figure:
    """Fig. 2: J over [−50, 50]² with the classic 25 foxholes (5×5 grid at −32 … 32).

    Left a surface of J, right a filled contour of J on a log scale with the hole centres marked;
    ``resolution`` grid points per axis (201 → 0.5-unit spacing, enough to resolve the ≈ 5-unit-wide holes).
    """
    A = foxholes_25()
    x1, x2 = _grid(resolution)
    J = dejong5(np.stack([x1, x2], axis=-1), A)
    fig = plt.figure(figsize=(12, 5))
    ax3 = fig.add_subplot(1, 2, 1, projection="3d")
    ax3.plot_surface(x1, x2, J, cmap="viridis", rcount=resolution, ccount=resolution, linewidth=0)
    ax3.set_xlabel("$x_1$")
    ax3.set_ylabel("$x_2$")
    ax3.set_zlabel("$J$")
    ax3.view_init(elev=35, azim=-60)
    ax = fig.add_subplot(1, 2, 2)
    levels = np.geomspace(J.min(), J.max(), 30)
    cs = ax.contourf(x1, x2, J, levels=levels, norm=LogNorm(), cmap="viridis")
    ax.plot(A[0], A[1], "+", color="w", ms=6)
    ax.set_aspect("equal")
    ax.set_xlabel("$x_1$")
    ax.set_ylabel("$x_2$")
    fig.colorbar(cs, ax=ax, label="$J$ (log scale)", format="%.3g")
    fig.suptitle("Fig. 2 — De Jong's 5th function with 25 local minima")
    fig.tight_layout()
    return fig


def fig16_dejong_predictions(
    train_df: pd.DataFrame, samples_by_alpha: dict[float, np.ndarray], train_alphas: list[float]
) -> Figure:
    """Fig. 16: (a) training minima for several α, (b) CVAE samples at unseen α with the true minima.

    ``train_df`` has columns ``alpha``, ``x1``, ``x2`` (the high-quality solution table); rows whose α label
    matches one of ``train_alphas`` are drawn in (a), coloured by α.  ``samples_by_alpha`` maps each test α
    to its samples (n, 2), drawn in (b) one panel per α (paper: 1000 samples at π/9, 2π/9, π/3, 4π/9) with
    the eight analytic minima R(α)A overlaid.
    """
    fig = plt.figure(figsize=(15, 7), layout="constrained")
    left, right = fig.subfigures(1, 2, width_ratios=[1.0, 1.15])
    ax = left.subplots()
    shown = rows_at_any(train_df, train_alphas)
    sc = ax.scatter(shown["x1"], shown["x2"], c=shown["alpha"], cmap="viridis", s=10, vmin=0.0, vmax=math.pi / 2)
    left.colorbar(sc, ax=ax, label="α (rad)", shrink=0.8)
    _square(ax)
    ax.set_title(f"(a) training minima: {len(shown)} solutions at {np.unique(shown['alpha']).size} α")

    test = sorted(samples_by_alpha)
    ncol = 2 if len(test) > 1 else 1
    axes = right.subplots(max(1, math.ceil(len(test) / ncol)), ncol, squeeze=False).ravel()
    for axk, alpha in zip(axes, test):
        s = np.asarray(samples_by_alpha[alpha], dtype=float).reshape(-1, 2)
        tm = true_minima(alpha)
        axk.scatter(s[:, 0], s[:, 1], s=2, color="C0", alpha=0.4, label=f"{len(s)} samples")
        axk.scatter(tm[:, 0], tm[:, 1], s=14, facecolor="none", edgecolor="C1", lw=1.0, label="true minima")
        axk.set_title(f"α = {alpha / math.pi:.3g}π", fontsize=10)
        _square(axk)
    for axk in axes[len(test):]:
        axk.set_visible(False)
    if test:
        axes[0].legend(loc="lower left", fontsize=7, markerscale=2)
    right.suptitle("(b) CVAE samples at α not in the training set")
    fig.suptitle("Fig. 16 — De Jong's 5th function: training data and AmorGS predictions", fontsize=13)
    return fig


def _square(ax) -> None:
    p = DeJong5()
    ax.set_xlim(p.lower[0], p.upper[0])
    ax.set_ylim(p.lower[1], p.upper[1])
    ax.set_aspect("equal")
    ax.set_xlabel("$x_1$")
    ax.set_ylabel("$x_2$")
