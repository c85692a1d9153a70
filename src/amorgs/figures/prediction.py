"""Prediction figures at held-out α (paper Figs. 17–20): data in, matplotlib Figure out, no file IO.

Tables have an ``alpha`` column and named decision variables: ``tau_s``, ``tau_i``, ``tau_f`` (TU), ``m_f``
(kg) and, for Fig. 20, ``theta_kk``, ``phi_kk`` (rad), ``rho_kk``.  ``samples`` come from a generative model,
``truth`` are the high-quality solutions of an extensive search at the same α.  A panel without data says so
("no ground truth at α = …") instead of drawing anything.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import mpl_toolkits.mplot3d  # noqa: F401  (registers the "3d" projection)
import numpy as np
import pandas as pd
from matplotlib.figure import Figure
from scipy.stats import gaussian_kde

from amorgs.alphas import rows_at
from amorgs.analysis.controls import COMPONENTS, segment_statistics, thrust_components
from amorgs.analysis.hyperplanes import TIME_COLUMNS, time_of_flight

SAMPLE_COLOR = "C0"  # blue, as in the paper
TRUTH_COLOR = "C1"  # orange


def _note(ax, text: str, y: float = 0.5) -> None:
    """Write ``text`` across an axes (at height ``y`` in axes units) that lacks data, over a white box."""
    kw = dict(ha="center", va="center", fontsize=9, color="0.3", wrap=True,
              bbox=dict(facecolor="white", edgecolor="none", alpha=0.85))
    if getattr(ax, "name", "") == "3d":
        ax.text2D(0.5, y, text, transform=ax.transAxes, **kw)
    else:
        ax.text(0.5, y, text, transform=ax.transAxes, **kw)


def _time_limits(*frames: pd.DataFrame) -> list[tuple[float, float]] | None:
    """Common (low, high) per time axis over the non-empty frames, None if all are empty."""
    tau = [f[list(TIME_COLUMNS)].to_numpy(dtype=float) for f in frames if len(f)]
    if not tau:
        return None
    allv = np.vstack(tau)
    lo, hi = np.nanmin(allv, axis=0), np.nanmax(allv, axis=0)
    pad = np.maximum(0.05 * (hi - lo), 0.1)
    return list(zip(lo - pad, hi + pad))


def _time_scatter(ax, df: pd.DataFrame, color: str, title: str, empty: str,
                  limits: list[tuple[float, float]] | None) -> None:
    """3-D scatter of (τ_s, τ_i, τ_f) of ``df`` or the note ``empty``."""
    if len(df):
        size = 2 if len(df) > 500 else 8
        ax.scatter(df["tau_s"], df["tau_i"], df["tau_f"], s=size, color=color, alpha=0.5, depthshade=False)
    else:
        _note(ax, empty)
    if limits is not None:
        ax.set_xlim(*limits[0])
        ax.set_ylim(*limits[1])
        ax.set_zlim(*limits[2])
    ax.set_xlabel(r"$\tau_s$ [TU]", fontsize=8)
    ax.set_ylabel(r"$\tau_i$ [TU]", fontsize=8)
    ax.set_zlabel(r"$\tau_f$ [TU]", fontsize=8)
    ax.set_title(title, fontsize=9)


def _finite(values: np.ndarray) -> np.ndarray:
    values = np.asarray(values, dtype=float)
    return values[np.isfinite(values)]


def _bins(values: Sequence[np.ndarray], width: float) -> np.ndarray | None:
    """Common bin edges of the given width covering every finite value, None if there is none."""
    v = _finite(np.concatenate([np.asarray(x, float) for x in values] or [np.empty(0)]))
    if v.size == 0:
        return None
    lo = np.floor(v.min() / width) * width
    return np.arange(lo, v.max() + width, width) if v.max() > lo else np.array([lo, lo + width])


def fig17_time_predictions(samples: pd.DataFrame, truth: pd.DataFrame, alphas: Sequence[float],
                           bin_width: float = 0.5) -> Figure:
    """Fig. 17: per test α (columns) the sampled (τ_s, τ_i, τ_f) (top), the ground truth (middle, same axes)
    and density histograms of TOF (bottom, ``bin_width`` TU bins), samples in blue, ground truth in orange."""
    alphas = list(alphas)
    ncols = max(len(alphas), 1)
    fig = Figure(figsize=(5.0 * ncols, 12.0), layout="constrained")
    for j, alpha in enumerate(alphas):
        s, t = rows_at(samples, alpha), rows_at(truth, alpha)
        limits = _time_limits(s, t)
        _time_scatter(fig.add_subplot(3, ncols, j + 1, projection="3d"), s, SAMPLE_COLOR,
                      f"α = {alpha:g}: samples (n = {len(s)})", f"no samples at α = {alpha:g}", limits)
        _time_scatter(fig.add_subplot(3, ncols, ncols + j + 1, projection="3d"), t, TRUTH_COLOR,
                      f"α = {alpha:g}: ground truth (n = {len(t)})", f"no ground truth at α = {alpha:g}", limits)
        ax = fig.add_subplot(3, ncols, 2 * ncols + j + 1)
        s_tof, t_tof = _finite(time_of_flight(s)), _finite(time_of_flight(t))
        edges = _bins([s_tof, t_tof], bin_width)
        if s_tof.size:
            ax.hist(s_tof, bins=edges, density=True, color=SAMPLE_COLOR, alpha=0.5, label="samples")
        else:
            _note(ax, f"no samples at α = {alpha:g}", y=0.35)
        if t_tof.size:
            ax.hist(t_tof, bins=edges, density=True, color=TRUTH_COLOR, alpha=0.5, label="ground truth")
        else:
            _note(ax, f"no ground truth at α = {alpha:g}", y=0.8)
        if s_tof.size or t_tof.size:
            ax.legend(fontsize=8)
        ax.set_xlabel("TOF [TU]")
        ax.set_ylabel("density [1/TU]")
    if not alphas:
        _note(fig.add_subplot(1, 1, 1), "no test α")
    fig.suptitle("Fig. 17 — time variables: samples vs ground truth")
    return fig


def fig18_data_fraction(samples_by_fraction: Mapping[float, pd.DataFrame], truth: pd.DataFrame,
                        alphas: Sequence[float], bin_width: float = 0.5) -> Figure:
    """Fig. 18: per test α (rows) the sampled (τ_s, τ_i, τ_f) of the CVAE trained on each fraction of the
    training data (columns, e.g. 0.1, 0.5, 1.0) and, last column, TOF histograms of every fraction (step
    lines) over the ground truth (filled, orange).  ``samples_by_fraction`` maps fraction → samples table."""
    alphas = list(alphas)
    fractions = sorted(samples_by_fraction)
    ncols, nrows = len(fractions) + 1, max(len(alphas), 1)
    fig = Figure(figsize=(4.2 * ncols, 4.0 * nrows), layout="constrained")
    for i, alpha in enumerate(alphas):
        t = rows_at(truth, alpha)
        per = {f: rows_at(samples_by_fraction[f], alpha) for f in fractions}
        limits = _time_limits(t, *per.values())
        for j, f in enumerate(fractions):
            ax = fig.add_subplot(nrows, ncols, i * ncols + j + 1, projection="3d")
            _time_scatter(ax, per[f], f"C{j + 2}", f"α = {alpha:g}: {100 * f:g}% of data (n = {len(per[f])})",
                          f"no samples at α = {alpha:g}", limits)
        ax = fig.add_subplot(nrows, ncols, (i + 1) * ncols)
        t_tof = _finite(time_of_flight(t))
        tofs = {f: _finite(time_of_flight(p)) for f, p in per.items()}
        edges = _bins([t_tof, *tofs.values()], bin_width)
        if t_tof.size:
            ax.hist(t_tof, bins=edges, density=True, color=TRUTH_COLOR, alpha=0.4, label="ground truth")
        else:
            _note(ax, f"no ground truth at α = {alpha:g}")
        for j, f in enumerate(fractions):
            if tofs[f].size:
                ax.hist(tofs[f], bins=edges, density=True, histtype="step", lw=1.2,
                        color=f"C{j + 2}", label=f"{100 * f:g}% of data")
        if t_tof.size or any(v.size for v in tofs.values()):
            ax.legend(fontsize=7)
        ax.set_xlabel("TOF [TU]")
        ax.set_ylabel("density [1/TU]")
        ax.set_title(f"α = {alpha:g}: TOF", fontsize=9)
    if not alphas:
        _note(fig.add_subplot(1, 1, 1), "no test α")
    fig.suptitle("Fig. 18 — time-variable predictions with 10 / 50 / 100 % of the training data")
    return fig


def _hist_kde(ax, values: np.ndarray, color: str, label: str, edges: np.ndarray) -> None:
    """Density histogram of finite ``values`` on ``edges`` with a Gaussian KDE line (when they spread)."""
    ax.hist(values, bins=edges, density=True, color=color, alpha=0.4, label=f"{label} (n = {values.size})")
    if values.size >= 3 and np.ptp(values) > 0:
        grid = np.linspace(edges[0], edges[-1], 300)
        ax.plot(grid, gaussian_kde(values)(grid), color=color)


def fig19_final_mass(samples: pd.DataFrame, truth: pd.DataFrame, alphas: Sequence[float],
                     bin_width: float = 1.0) -> Figure:
    """Fig. 19: per test α, density histograms of m_f (``bin_width`` kg bins) with a KDE overlaid, samples
    (blue) against the ground truth (orange)."""
    alphas = list(alphas)
    ncols = max(len(alphas), 1)
    fig = Figure(figsize=(5.0 * ncols, 3.8), layout="constrained")
    axes = fig.subplots(1, ncols, squeeze=False)[0]
    for ax, alpha in zip(axes, alphas):
        s = rows_at(samples, alpha)["m_f"].to_numpy(dtype=float)
        t = rows_at(truth, alpha)["m_f"].to_numpy(dtype=float)
        s, t = _finite(s), _finite(t)
        edges = _bins([s, t], bin_width)
        if s.size:
            _hist_kde(ax, s, SAMPLE_COLOR, "samples", edges)
        else:
            _note(ax, f"no samples at α = {alpha:g}", y=0.35)
        if t.size:
            _hist_kde(ax, t, TRUTH_COLOR, "ground truth", edges)
        else:
            _note(ax, f"no ground truth at α = {alpha:g}", y=0.8)
        if s.size or t.size:
            ax.legend(fontsize=8)
        ax.set_xlabel("$m_f$ [kg]")
        ax.set_ylabel("density [1/kg]")
        ax.set_title(f"α = {alpha:g}")
    if not alphas:
        _note(axes[0], "no test α")
    fig.suptitle("Fig. 19 — final mass: samples vs ground truth")
    return fig


def fig20_control_statistics(sources: Mapping[str, pd.DataFrame], alphas: Sequence[float],
                             interval: str = "mean_ci", level: float = 0.95) -> Figure:
    """Fig. 20: per test α (columns) and thrust component u_x, u_y, u_z (rows, throttle-weighted, in units
    of T_max) the per-segment mean and ``level`` interval of each source, e.g. ``{"LSTM": …, "Ground truth":
    …, "Uniform": …}``.  ``interval``: ``"mean_ci"`` (confidence interval of the mean, the paper's wording)
    or ``"percentile"`` (the spread of the samples), see :mod:`amorgs.analysis.controls`."""
    alphas = list(alphas)
    ncols = max(len(alphas), 1)
    fig = Figure(figsize=(5.5 * ncols, 7.5), layout="constrained")
    axes = fig.subplots(3, ncols, squeeze=False, sharex=True)
    for j, alpha in enumerate(alphas):
        missing = []
        for k, (label, df) in enumerate(sources.items()):
            rows = rows_at(df, alpha)
            if not len(rows):
                missing.append(label)
                continue
            stats = segment_statistics(thrust_components(rows), interval, level)
            for i, comp in enumerate(COMPONENTS):
                g = stats[stats["component"] == comp]
                axes[i, j].plot(g["segment"], g["mean"], color=f"C{k}", marker=".", label=f"{label} (n = {len(rows)})")
                axes[i, j].fill_between(g["segment"], g["lower"], g["upper"], color=f"C{k}", alpha=0.2)
        for i, comp in enumerate(COMPONENTS):
            ax = axes[i, j]
            ax.axhline(0.0, color="0.6", lw=0.5)
            ax.set_ylim(-1.05, 1.05)
            ax.set_ylabel(f"${comp[0]}_{comp[-1]}$ / $T_{{max}}$")
        if missing:
            _note(axes[0, j], "no data at α = {:g}: {}".format(alpha, ", ".join(missing)), y=0.85)
        axes[0, j].set_title(f"α = {alpha:g}")
        if len(missing) < len(sources):
            axes[0, j].legend(fontsize=7)
        axes[-1, j].set_xlabel("control segment")
    if not alphas:
        _note(axes[0, 0], "no test α")
    name = "95 % confidence interval of the mean" if interval == "mean_ci" else "95 % percentile band"
    if level != 0.95:
        name = name.replace("95", f"{100 * level:g}")
    fig.suptitle(f"Fig. 20 — thrust components per segment: mean and {name}")
    return fig
