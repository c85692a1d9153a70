"""Figures of the LT-CR3BP solution-set structure (paper Sec. III.B, Figs. 3–13).

One function per paper figure: data in, :class:`matplotlib.figure.Figure` out — built on the object API
(no pyplot state, no backend, no file IO), so the caller decides where it is saved or logged.  The data are
computed by :func:`amorgs.analysis.structure_report.analyze`; :func:`structure_figures` draws all of them
from its :class:`~amorgs.analysis.structure_result.StructureResult`, and these functions only draw.  Where
there is too little data for a panel (an empty hyperplane, three points that cannot be triangulated) the
panel says so in words instead of failing; nothing is ever filled in.  Units: times TU, final mass m_f kg
(fuel at the terminal state), positions DU in the Earth–Moon rotating frame.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import mpl_toolkits.mplot3d  # noqa: F401  (registers the "3d" projection)
import numpy as np
import pandas as pd
from matplotlib import colormaps
from matplotlib import colors as mcolors
from matplotlib.figure import Figure
from matplotlib.ticker import MaxNLocator
from matplotlib.tri import Triangulation

from amorgs.alphas import alpha_mask, rows_at, rows_at_any
from amorgs.analysis.controls import COMPONENTS
from amorgs.analysis.structure_result import StructureResult, TransferPath

MASS_CMAP = "viridis"
MASS_LABEL = "$m_f$ [kg]"


def _note(ax, text: str) -> None:
    """Write ``text`` in the middle of an axes that has no (or too little) data."""
    kw = dict(ha="center", va="center", fontsize=9, color="0.3", wrap=True)
    if getattr(ax, "name", "") == "3d":
        ax.text2D(0.5, 0.5, text, transform=ax.transAxes, **kw)
    else:
        ax.text(0.5, 0.5, text, transform=ax.transAxes, **kw)


def _alpha_colors(alphas: Sequence[float]) -> dict[float, tuple]:
    cmap = colormaps["plasma"]
    return {a: cmap(0.1 + 0.75 * i / max(len(alphas) - 1, 1)) for i, a in enumerate(sorted(alphas))}


def _mass_norm(*series: pd.Series) -> mcolors.Normalize:
    values = np.concatenate([np.asarray(s, float) for s in series if len(s)] or [np.array([0.0, 1.0])])
    values = values[np.isfinite(values)]
    lo, hi = (values.min(), values.max()) if values.size else (0.0, 1.0)
    return mcolors.Normalize(vmin=lo, vmax=hi if hi > lo else lo + 1.0)


def _triangulation(x: np.ndarray, y: np.ndarray) -> Triangulation | None:
    """Delaunay triangulation of the points, or None where they are too few or collinear."""
    if len(x) < 3:
        return None
    try:
        tri = Triangulation(x, y)
    except (ValueError, RuntimeError):
        return None
    return tri if len(tri.triangles) else None


def fig03_time_hyperplanes(converged: pd.DataFrame, alphas: Sequence[float]) -> Figure:
    """3-D scatter of (τ_s, τ_i, τ_f) of converged solutions at each α in ``alphas`` (Fig. 3)."""
    fig = Figure(figsize=(7, 6), layout="constrained")
    ax = fig.add_subplot(projection="3d")
    colors = _alpha_colors(alphas)
    for a in sorted(alphas):
        d = rows_at(converged, a)
        ax.scatter(d["tau_s"], d["tau_i"], d["tau_f"], s=6, color=colors[a], label=f"α = {a:g} ({len(d)})",
                   depthshade=False)
    # Viewed along (−1, −1, 2), which is perpendicular to the common normal (1, 1, 1): planes appear edge-on.
    ax.view_init(elev=math.degrees(math.atan(math.sqrt(2.0))), azim=-135)
    ax.set_proj_type("ortho")
    ax.set_aspect("equal")
    ax.set_xlabel(r"$\tau_s$ [TU]")
    ax.set_ylabel(r"$\tau_i$ [TU]")
    ax.set_zlabel(r"$\tau_f$ [TU]")
    ax.set_title("Time coordinates of converged solutions")
    if len(alphas):
        ax.legend(loc="upper left", fontsize=8)
    else:
        _note(ax, "no converged solutions")
    return fig


def fig04_tof_histograms(converged: pd.DataFrame, modes: dict[float, np.ndarray], bin_width: float) -> Figure:
    """Left: TOF histograms per α with the detected modes (dashed); right: (τ1', τ3') of Eq. 33 (Fig. 4).

    ``converged`` has alpha, tau_s, tau_i, tau_f and the transformed tau1p, tau3p; ``modes`` maps α → T [TU].
    """
    fig = Figure(figsize=(12, 4.8), layout="constrained")
    ax_h, ax_t = fig.subplots(1, 2)
    alphas = sorted(modes)
    colors = _alpha_colors(alphas)
    tof = converged[["tau_s", "tau_i", "tau_f"]].sum(axis=1).to_numpy()
    if len(tof):
        edges = np.arange(np.floor(tof.min()), np.ceil(tof.max()) + bin_width, bin_width)
    for a in alphas:
        sel = alpha_mask(converged["alpha"], a)
        ax_h.hist(tof[sel], bins=edges, histtype="step", color=colors[a],
                  label=f"α = {a:g}: {len(modes[a])} modes")
        for T in modes[a]:
            ax_h.axvline(T, color=colors[a], ls="--", lw=0.8)
        ax_t.scatter(converged["tau1p"].to_numpy()[sel], converged["tau3p"].to_numpy()[sel], s=5,
                     color=colors[a], label=f"α = {a:g}")
    ax_h.set_xlabel("time of flight [TU]")
    ax_h.set_ylabel(f"solutions per {bin_width:g} TU")
    ax_h.set_title("TOF histograms and detected modes")
    ax_t.set_xlabel(r"$\tau_1'$ [TU]")
    ax_t.set_ylabel(r"$\tau_3'$ = TOF/$\sqrt{3}$ [TU]")
    ax_t.set_title("Transformed coordinates (Eq. 33), planes edge-on")
    if alphas:
        ax_h.legend(fontsize=8)
        ax_t.legend(fontsize=8)
    else:
        _note(ax_h, "no converged solutions")
        _note(ax_t, "no converged solutions")
    return fig


def fig05_hyperplane_filtering(panels: Sequence[tuple[str, pd.DataFrame]]) -> Figure:
    """Three 3-D views (τ1', τ2', τ3') coloured by m_f: all converged, β-filtered, near-hyperplane (Fig. 5).

    ``panels``: (title, table with tau1p, tau2p, tau3p, m_f) per panel, in order.
    """
    fig = Figure(figsize=(15, 5), layout="constrained")
    norm = _mass_norm(*[d["m_f"] for _, d in panels])
    axes = [fig.add_subplot(1, len(panels), i + 1, projection="3d") for i in range(len(panels))]
    sc = None
    for ax, (title, d) in zip(axes, panels):
        ax.view_init(elev=8, azim=-60)  # low elevation: the planes τ3' = T/√3 show as layers
        for axis in (ax.xaxis, ax.yaxis):
            axis.set_major_locator(MaxNLocator(4))
        ax.set_title(f"{title} ({len(d)})", fontsize=10)
        ax.set_xlabel(r"$\tau_1'$ [TU]")
        ax.set_ylabel(r"$\tau_2'$ [TU]")
        ax.set_zlabel(r"$\tau_3'$ [TU]")
        if d.empty:
            _note(ax, "no solutions")
            continue
        sc = ax.scatter(d["tau1p"], d["tau2p"], d["tau3p"], c=d["m_f"], cmap=MASS_CMAP, norm=norm, s=5,
                        depthshade=False)
    if sc is not None:
        fig.colorbar(sc, ax=axes, shrink=0.6, label=MASS_LABEL)
    return fig


def fig06_inplane_mass_contours(planes: pd.DataFrame, plane_order: Sequence[float], levels: int,
                                ncols: int = 4) -> Figure:
    """m_f over (τ1', τ2') on each hyperplane in ``plane_order`` (Fig. 6): linear-interpolation tricontourf
    with ``levels`` levels, the solutions as dots; one shared colour scale.

    ``planes`` has plane_tof, tau1p, tau2p, m_f for the (β-filtered, near-plane) solutions.
    """
    n = max(len(plane_order), 1)
    ncols = min(ncols, n)
    nrows = math.ceil(n / ncols)
    fig = Figure(figsize=(3.6 * ncols, 3.2 * nrows), layout="constrained")
    axes = np.atleast_1d(fig.subplots(nrows, ncols, squeeze=False)).ravel()
    norm = _mass_norm(planes["m_f"])
    level_values = np.linspace(norm.vmin, norm.vmax, levels + 1)
    mappable = None
    for ax, T in zip(axes, plane_order):
        d = planes[planes["plane_tof"] == T]
        x, y, m = (d[c].to_numpy(dtype=float) for c in ("tau1p", "tau2p", "m_f"))
        tri = _triangulation(x, y)
        if tri is not None:
            mappable = ax.tricontourf(tri, m, levels=level_values, cmap=MASS_CMAP, norm=norm)
            ax.plot(x, y, "k.", ms=2)
        else:
            ax.scatter(x, y, c=m, cmap=MASS_CMAP, norm=norm, s=12)
            _note(ax, f"{len(d)} solution(s): too few\nfor a contour")
        ax.set_title(f"TOF = {T:.3f} TU ({len(d)})", fontsize=9)
        ax.set_xlabel(r"$\tau_1'$ [TU]")
        ax.set_ylabel(r"$\tau_2'$ [TU]")
    for ax in axes[len(plane_order):]:
        ax.set_axis_off()
    if not len(plane_order):
        axes[0].set_axis_on()
        _note(axes[0], "no β-filtered solutions on any hyperplane")
    if mappable is not None:
        fig.colorbar(mappable, ax=list(axes), shrink=0.8, label=MASS_LABEL)
    return fig


def _moving_average_figure(tof: np.ndarray, m_f: np.ndarray, ma: pd.DataFrame, title: str,
                           xlim: tuple[float, float] | None) -> Figure:
    fig = Figure(figsize=(10, 4.5), layout="constrained")
    ax = fig.add_subplot()
    ax.plot(tof, m_f, "k.", ms=2.5, label=f"solutions ({len(tof)})")
    windows = sorted(ma["window"].unique(), reverse=True)
    cmap = colormaps["tab10"]
    for i, w in enumerate(windows):
        d = ma[ma["window"] == w]
        x, y = d["tof"].to_numpy(dtype=float), d["m_f_ma"].to_numpy(dtype=float)
        # Break the curve across gaps wider than the window: there is no average there.
        gap = np.flatnonzero(np.diff(x) > w) + 1
        ax.plot(np.insert(x, gap, np.nan), np.insert(y, gap, np.nan), color=cmap(i), lw=1.4, label=f"MA {w:g} TU")
    if xlim is not None:
        ax.set_xlim(*xlim)
        inside = (tof >= xlim[0]) & (tof <= xlim[1])
        if inside.any():
            lo, hi = np.min(m_f[inside]), np.max(m_f[inside])
            pad = max(0.05 * (hi - lo), 0.5)
            ax.set_ylim(lo - pad, hi + pad)
        else:
            _note(ax, "no solutions in this TOF window")
    if not len(tof):
        _note(ax, "no converged solutions")
    ax.set_xlabel("time of flight [TU]")
    ax.set_ylabel(MASS_LABEL)
    ax.set_title(title)
    ax.legend(fontsize=8, loc="lower right")
    return fig


def fig07_moving_average_macro(tof: np.ndarray, m_f: np.ndarray, ma: pd.DataFrame, alpha: float) -> Figure:
    """m_f against TOF (black) with moving averages of the wide windows in ``ma`` (Fig. 7)."""
    return _moving_average_figure(tof, m_f, ma, f"Moving averages of $m_f$ over TOF, α = {alpha:g} (macro)", None)


def fig08_moving_average_micro(tof: np.ndarray, m_f: np.ndarray, ma: pd.DataFrame, alpha: float, center: float,
                               half_width: float) -> Figure:
    """As Fig. 7 with the narrow windows, zoomed on ``center ± half_width`` TU (Fig. 8)."""
    return _moving_average_figure(tof, m_f, ma, f"Moving averages near {center:.2f} TU, α = {alpha:g} (micro)",
                                  (center - half_width, center + half_width))


def _trajectory_figure(paths: Sequence[TransferPath], refs: dict[str, np.ndarray], boundary: dict,
                       title: str) -> Figure:
    n = max(len(paths), 1)
    fig = Figure(figsize=(5.5 * n, 4.8), layout="constrained")
    fig.suptitle(title)
    mu = float(boundary["mu"])
    xi0 = np.asarray(boundary["initial_state"], float)[:3]
    xif = np.asarray(boundary["terminal_state"], float)[:3]
    for i in range(n):
        ax = fig.add_subplot(1, n, i + 1, projection="3d")
        ax.scatter([-mu], [0], [0], color="tab:blue", s=40, label="Earth")
        ax.scatter([1 - mu], [0], [0], color="0.5", s=15, label="Moon")
        ax.scatter([boundary["l1_x"]], [0], [0], color="k", marker="x", s=20, label="L1")
        ax.plot(*refs["halo"], color="k", lw=0.8, label="halo orbit")
        ax.plot(*refs["manifold"], color="tab:orange", lw=1.0, label=r"manifold arc $\xi_f$ → halo")
        ax.scatter(*xi0, color="tab:cyan", s=20, label=r"spiral end $\xi_0$")
        ax.scatter(*xif, color="tab:orange", s=20, marker="s", label=r"$\xi_f$")
        if i < len(paths):
            p = paths[i]
            ax.plot(*p.positions, color="tab:green", lw=0.9, label="transfer")
            ax.set_title(f"{p.label}: TOF = {p.tof:.3f} TU, $m_f$ = {p.m_f:.1f} kg", fontsize=9)
            pts = np.hstack([p.positions, refs["halo"], refs["manifold"]])
        else:
            _note(ax, "no high-quality solution on a hyperplane")
            pts = np.hstack([refs["halo"], refs["manifold"], xi0[:, None]])
        lo, hi = pts.min(axis=1), pts.max(axis=1)
        # True proportions, except that a nearly planar picture keeps a readable z extent.
        ax.set_box_aspect(np.maximum(hi - lo, 0.25 * (hi - lo).max()))
        ax.zaxis.set_major_locator(MaxNLocator(4))
        ax.set_xlabel("x [DU]")
        ax.set_ylabel("y [DU]")
        ax.set_zlabel("z [DU]")
        if i == 0:
            ax.legend(fontsize=7, loc="upper left")
    return fig


def fig09_trajectories_across_hyperplanes(paths: Sequence[TransferPath], refs: dict[str, np.ndarray],
                                          boundary: dict) -> Figure:
    """Transfers from different hyperplanes with Earth, Moon, L1, halo, manifold arc and ξ₀ (Fig. 9)."""
    return _trajectory_figure(paths, refs, boundary, "Solutions from different hyperplanes")


def fig10_trajectories_within_hyperplane(paths: Sequence[TransferPath], refs: dict[str, np.ndarray],
                                         boundary: dict, plane_tof: float | None) -> Figure:
    """Transfers from the hyperplane TOF ≈ ``plane_tof``, far apart in (τ1', τ2') (Fig. 10)."""
    title = (f"Solutions within the {plane_tof:.3f} TU hyperplane" if plane_tof is not None
             else "Solutions within one hyperplane")
    return _trajectory_figure(paths, refs, boundary, title)


def _funnel_figure(plane: pd.DataFrame | None, plane_tof: float | None, levels: int) -> Figure:
    fig = Figure(figsize=(15, 4.6), layout="constrained")
    axes = fig.subplots(1, 3)
    if plane is None or plane.empty:
        fig.suptitle("Funnel structure")
        for ax in axes:
            _note(ax, "no populated hyperplane for this figure")
        return fig
    fig.suptitle(f"Funnel structure of the {plane_tof:.3f} TU hyperplane ({len(plane)} solutions)")
    x, y, m = (plane[c].to_numpy(dtype=float) for c in ("tau1p", "tau2p", "m_f"))
    norm = _mass_norm(plane["m_f"])
    sc = axes[0].scatter(x, y, c=m, cmap=MASS_CMAP, norm=norm, s=10)
    axes[0].set_title("solutions by final mass")
    cmap = colormaps["tab10"]
    for i, (name, d) in enumerate(plane.groupby("funnel", sort=True)):
        axes[1].scatter(d["tau1p"], d["tau2p"], s=10, color=cmap(i), label=f"Funnel {name} ({len(d)})")
        axes[1].annotate(name, (d["tau1p"].mean(), d["tau2p"].mean()), fontsize=12, weight="bold",
                         ha="center", va="center")
    axes[1].legend(fontsize=8)
    axes[1].set_title("funnels (Gaussian mixture, BIC)")
    tri = _triangulation(x, y)
    if tri is not None:
        axes[2].tricontourf(tri, m, levels=np.linspace(norm.vmin, norm.vmax, levels + 1), cmap=MASS_CMAP,
                            norm=norm)
        axes[2].scatter(x, y, c=m, cmap=MASS_CMAP, norm=norm, s=10, edgecolors="k", linewidths=0.3)
    else:
        axes[2].scatter(x, y, c=m, cmap=MASS_CMAP, norm=norm, s=10)
        _note(axes[2], "too few solutions for a contour")
    axes[2].set_title("final-mass contours")
    for ax in axes:
        ax.set_xlabel(r"$\tau_1'$ [TU]")
        ax.set_ylabel(r"$\tau_2'$ [TU]")
    fig.colorbar(sc, ax=[axes[0], axes[2]], label=MASS_LABEL, shrink=0.8)
    return fig


def fig11_funnels(plane: pd.DataFrame | None, plane_tof: float | None, levels: int) -> Figure:
    """Funnels of the first chosen hyperplane: m_f colours, funnel labels, m_f contours (Fig. 11).

    ``plane`` has tau1p, tau2p, m_f and ``funnel`` (A, B, …); None or empty draws an annotated figure.
    """
    return _funnel_figure(plane, plane_tof, levels)


def fig12_funnels(plane: pd.DataFrame | None, plane_tof: float | None, levels: int) -> Figure:
    """As :func:`fig11_funnels` for the second chosen hyperplane (Fig. 12)."""
    return _funnel_figure(plane, plane_tof, levels)


def fig13_control_statistics(stats: pd.DataFrame, interval_label: str) -> Figure:
    """Per funnel: mean and 95 % interval of u_x, u_y, u_z over the segments (Fig. 13).

    ``stats``: long table with plane_tof, group (funnel), segment, component, mean, lower, upper, n — one
    column of panels per hyperplane, one row per component.
    """
    planes = sorted(stats["plane_tof"].unique()) if not stats.empty else []
    ncols = max(len(planes), 1)
    fig = Figure(figsize=(5.5 * ncols, 7.5), layout="constrained")
    axes = fig.subplots(3, ncols, squeeze=False, sharex=True)
    cmap = colormaps["tab10"]
    for j, T in enumerate(planes):
        s = stats[stats["plane_tof"] == T]
        for i, comp in enumerate(COMPONENTS):
            ax = axes[i, j]
            for k, (name, g) in enumerate(s[s["component"] == comp].groupby("group", sort=True)):
                g = g.sort_values("segment")
                ax.plot(g["segment"], g["mean"], color=cmap(k), marker=".", label=f"Funnel {name} (n={g['n'].iloc[0]})")
                ax.fill_between(g["segment"], g["lower"], g["upper"], color=cmap(k), alpha=0.2)
            ax.axhline(0.0, color="0.6", lw=0.5)
            ax.set_ylim(-1.05, 1.05)  # |u| ≤ 1: wider confidence bounds of tiny funnels are clipped
            ax.set_ylabel(f"${comp[0]}_{comp[-1]}$ / $T_{{max}}$")
            if i == 0:
                ax.set_title(f"TOF = {T:.3f} TU")
                ax.legend(fontsize=7)
        axes[-1, j].set_xlabel("control segment")
    if not planes:
        _note(axes[0, 0], "no funnels to summarise")
    fig.suptitle(f"Thrust components per segment: mean and {interval_label}")
    return fig


def structure_figures(result: StructureResult) -> dict[str, Figure]:
    """Figs. 3–13 of one structure analysis, by name (``fig03_time_hyperplanes`` … ``fig13_control_statistics``,
    the names of :data:`amorgs.layout.ANALYSIS_FIGURES`)."""
    params = result.params
    shown = result.shown_alphas
    on_shown = rows_at_any(result.converged, shown)
    focus = result.focus_alpha
    focus_value = focus if focus is not None else math.nan
    fconv = result.focus_converged
    tof, m_f = fconv["tof"].to_numpy(dtype=float), fconv["m_f"].to_numpy(dtype=float)
    ma = result.tables["moving_average"]
    ma_macro, ma_micro = (ma[ma["scale"] == scale] for scale in ("macro", "micro"))
    funnel_planes = [*result.funnel_planes, (None, None), (None, None)][:2]
    interval_label = ("95 % confidence interval of the mean" if params.control_interval == "mean_ci"
                      else "2.5–97.5 % percentile band")
    return {
        "fig03_time_hyperplanes": fig03_time_hyperplanes(on_shown, shown),
        "fig04_tof_histograms": fig04_tof_histograms(on_shown, {a: result.modes[a] for a in shown},
                                                     params.histogram_bin),
        "fig05_hyperplane_filtering": fig05_hyperplane_filtering([
            (f"(a) converged, α = {focus_value:g}" if focus is not None else "(a) converged, α = –", fconv),
            (f"(b) β-filtered, m_f ≥ {result.beta_kg:g} kg", result.focus_high_quality),
            (f"(c) within δ = {params.modes.delta:g} TU of a mode, projected", result.near_plane),
        ]),
        "fig06_inplane_mass_contours": fig06_inplane_mass_contours(result.near_plane, result.fig06_planes,
                                                                   params.contour_levels),
        "fig07_moving_average_macro": fig07_moving_average_macro(tof, m_f, ma_macro, focus_value),
        "fig08_moving_average_micro": fig08_moving_average_micro(tof, m_f, ma_micro, focus_value,
                                                                 result.micro_center, params.micro_half_width),
        "fig09_trajectories_across_hyperplanes": fig09_trajectories_across_hyperplanes(
            result.paths_across, result.reference_arcs, result.boundary),
        "fig10_trajectories_within_hyperplane": fig10_trajectories_within_hyperplane(
            result.paths_within, result.reference_arcs, result.boundary, funnel_planes[0][1]),
        "fig11_funnels": fig11_funnels(*funnel_planes[0], params.contour_levels),
        "fig12_funnels": fig12_funnels(*funnel_planes[1], params.contour_levels),
        "fig13_control_statistics": fig13_control_statistics(result.tables["control_statistics"], interval_label),
    }
