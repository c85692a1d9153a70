"""Structure analysis of the LT-CR3BP solution set in one call (paper Sec. III.B, Figs. 3–13, Tables 1–2).

``analyze(solutions, high_quality, beta_kg, params)`` runs every step and returns

- ``metrics``: flat ``{name: float}`` (MLflow-ready), e.g. ``n_modes_alpha_1``, ``hyperplane_spacing_alpha_1``
  (TU), ``funnels_plane_1`` (count in the first funnel plane), ``diverse_size_alpha_1``;
- ``tables``: ``modes`` (hyperplanes per α), ``funnels`` (Tables 1–2), ``control_statistics`` (Fig. 13),
  ``moving_average`` (Figs. 7–8), ``diversity`` (Eq. 12–13 per α), ``diverse_subset`` (the chosen rows),
  ``trajectories`` (rows shown in Figs. 9–10);
- ``figures``: ``fig03_time_hyperplanes`` … ``fig13_control_statistics``.

Data sets, as in the paper: hyperplanes (modes) are detected per α on every *converged* solution (A_α);
Figs. 5b–13 and the funnels use the β-filtered set A_{α,β} at the focus α (paper: α = 1.0), restricted to
solutions within δ of a mode; the moving averages use all converged solutions at the focus α (Fig. 7: A_1.0);
diversity is per α over A_{α,β}.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields

import numpy as np
import pandas as pd
from matplotlib.figure import Figure

from amorgs.analysis.controls import INTERVALS, group_statistics
from amorgs.analysis.diversity import DiversityParams, diverse_subset
from amorgs.analysis.funnels import TABLE_COLUMNS as FUNNEL_COLUMNS
from amorgs.analysis.funnels import FunnelParams, cluster_funnels, funnel_name, funnel_table
from amorgs.analysis.hyperplanes import (
    ModeParams,
    assign_hyperplane,
    detect_modes,
    hyperplane_period,
    hyperplane_spacing,
    project_to_plane,
    time_coordinates,
    time_of_flight,
    transform,
)
from amorgs.analysis.moving_average import moving_averages
from amorgs.analysis.trajectories import (
    reference_arcs,
    select_across_hyperplanes,
    select_within_hyperplane,
    transfer_paths,
)
from amorgs.figures import structure as figs
from amorgs.problems.cr3bp.boundary import load_boundary_conditions

KEY_COLUMNS = ("problem", "alpha", "seed", "start")
ROMAN = ("I", "II", "III", "IV", "V", "VI")


@dataclass(frozen=True)
class StructureParams:
    """Parameters of the structure analysis (times in TU, masses in kg).

    modes, funnels, diversity: parameters of those steps (see their modules).
    focus_alpha: α of the in-depth analysis (Figs. 5–13); the largest α present if it has no solutions.
    fig03_alphas: α shown in Figs. 3–4; each is replaced by the nearest α with converged solutions that is not
        already shown (so the paper's (0.1, 0.3, 1.0) becomes (0.1, 0.5, 1.0) on data at 0.1, 0.5, 1.0).
    histogram_bin: TOF bin width of Fig. 4.
    ma_windows_macro, ma_windows_micro: moving-average widths of Figs. 7 and 8.
    micro_center: centre of the Fig. 8 zoom; None → the mode with the most converged solutions at focus α.
    micro_half_width: half-width of the Fig. 8 zoom.
    funnel_planes: T of the hyperplanes of Figs. 11–12 (snapped to the nearest detected mode); None → the two
        hyperplanes with the most β-filtered solutions at focus α.
    fig06_max_planes: most hyperplanes shown in Fig. 6 (the most populated ones, in TOF order).
    contour_levels: filled contour levels of Figs. 6, 11, 12.
    control_interval: ``"mean_ci"`` or ``"percentile"`` (see :mod:`amorgs.analysis.controls`).
    n_trajectories: solutions drawn in each of Figs. 9 and 10.
    """

    modes: ModeParams = ModeParams()
    funnels: FunnelParams = FunnelParams()
    diversity: DiversityParams = DiversityParams()
    focus_alpha: float = 1.0
    fig03_alphas: tuple[float, ...] = (0.1, 0.3, 1.0)
    histogram_bin: float = 0.1
    ma_windows_macro: tuple[float, ...] = (0.25, 0.5, 1.0)
    ma_windows_micro: tuple[float, ...] = (0.01, 0.05, 0.1)
    micro_center: float | None = None
    micro_half_width: float = 1.0
    funnel_planes: tuple[float, ...] | None = None
    fig06_max_planes: int = 8
    contour_levels: int = 10
    control_interval: str = "mean_ci"
    n_trajectories: int = 3

    def __post_init__(self) -> None:
        if self.control_interval not in INTERVALS:
            raise ValueError(f"StructureParams.control_interval must be one of {INTERVALS}, "
                             f"got {self.control_interval!r}")
        if not 0 <= self.n_trajectories <= len(ROMAN):
            raise ValueError(f"StructureParams.n_trajectories must be in [0, {len(ROMAN)}], got {self.n_trajectories}")
        for key in ("histogram_bin", "micro_half_width"):
            if not getattr(self, key) > 0:
                raise ValueError(f"StructureParams.{key} must be > 0 TU, got {getattr(self, key)}")
        if min((*self.ma_windows_macro, *self.ma_windows_micro), default=1.0) <= 0:
            raise ValueError("StructureParams moving-average windows must be > 0 TU")
        if self.fig06_max_planes < 1 or self.contour_levels < 1:
            raise ValueError("StructureParams.fig06_max_planes and contour_levels must be ≥ 1")

    @classmethod
    def from_dict(cls, values: dict | None) -> "StructureParams":
        """Build from a plain (e.g. YAML) dict; nested ``modes``/``funnels``/``diversity`` dicts allowed."""
        values = dict(values or {})
        known = {f.name for f in fields(cls)}
        unknown = sorted(set(values) - known)
        if unknown:
            raise ValueError(f"unknown structure-analysis parameter(s) {unknown}")
        nested = {"modes": ModeParams, "funnels": FunnelParams, "diversity": DiversityParams}
        for key, kind in nested.items():
            if isinstance(values.get(key), dict):
                sub = {k: tuple(v) if isinstance(v, list) else v for k, v in values[key].items()}
                values[key] = kind(**sub)
        for key in ("fig03_alphas", "ma_windows_macro", "ma_windows_micro", "funnel_planes"):
            if isinstance(values.get(key), list):
                values[key] = tuple(values[key])
        return cls(**values)


def _key(alpha: float) -> str:
    return f"{alpha:g}"


def _pick_alpha(available: np.ndarray, wanted: float) -> float | None:
    if available.size == 0:
        return None
    hit = available[np.isclose(available, wanted)]
    return float(hit[0]) if hit.size else float(available.max())


def _nearest_alphas(available: np.ndarray, wanted: tuple[float, ...]) -> list[float]:
    """For each wanted α the nearest available one not already taken (Figs. 3–4), ascending."""
    left, shown = list(available), []
    for a in wanted:
        if left:
            shown.append(left.pop(int(np.argmin(np.abs(np.asarray(left) - a)))))
    return sorted(shown)


def _with_planes(df: pd.DataFrame, modes: np.ndarray, delta: float) -> pd.DataFrame:
    """``df`` plus transformed coordinates, the nearest plane and Eq. 32 membership (``on_plane``)."""
    t = transform(time_coordinates(df), modes).set_index(df.index)
    out = pd.concat([df, t], axis=1)
    out["tof"] = time_of_flight(df)
    out["on_plane"] = assign_hyperplane(out["tof"].to_numpy(), modes, delta) >= 0
    return out


def _identity(df: pd.DataFrame) -> pd.DataFrame:
    return df[[c for c in KEY_COLUMNS if c in df.columns]].copy()


def _funnel_section(near: pd.DataFrame, chosen: list[float], params: StructureParams, metrics: dict,
                    tables: dict) -> list[tuple[pd.DataFrame, float]]:
    """Cluster each chosen plane; fill Tables 1–2 (``funnels``) and Fig. 13 data (``control_statistics``)."""
    funnel_tables, stats_tables, planes = [], [], []
    for j, T in enumerate(chosen):
        plane = near[near["plane_tof"] == T]
        res = cluster_funnels(plane[["tau1p", "tau2p"]].to_numpy(), plane["m_f"].to_numpy(), params.funnels)
        plane = plane.assign(funnel=[funnel_name(i) for i in res.labels])
        planes.append((plane, T))
        metrics[f"funnels_plane_{j + 1}"] = float(res.n_funnels)
        metrics[f"funnel_plane_{j + 1}_tof"] = T
        funnel_tables.append(funnel_table(plane, res.labels, T))
        stats_tables.append(group_statistics(plane, plane["funnel"].to_numpy(), params.control_interval)
                            .assign(plane_tof=T))
    tables["funnels"] = (pd.concat(funnel_tables, ignore_index=True) if funnel_tables
                         else pd.DataFrame(columns=list(FUNNEL_COLUMNS)))
    tables["control_statistics"] = (pd.concat(stats_tables, ignore_index=True) if stats_tables else pd.DataFrame(
        columns=["group", "segment", "component", "mean", "lower", "upper", "n", "plane_tof"]))
    return planes


def _diversity_section(hq: pd.DataFrame, params: DiversityParams, metrics: dict, tables: dict) -> None:
    """Eq. 12–13 per α over A_{α,β}: the ``diversity`` summary and the ``diverse_subset`` rows."""
    rows, chosen = [], []
    for a in np.sort(hq["alpha"].unique()):
        ha = hq[hq["alpha"] == a].reset_index(drop=True)
        res = diverse_subset(ha, params)
        rows.append({"alpha": float(a), "n_high_quality": len(ha), "eta": res.eta, "eta_minus": res.eta_minus,
                     "diverse_size": res.size, "features": params.features})
        metrics[f"diverse_size_alpha_{_key(a)}"] = float(res.size)
        metrics[f"eta_minus_alpha_{_key(a)}"] = res.eta_minus
        chosen.append(_identity(ha.iloc[res.indices]).assign(m_f=ha["m_f"].iloc[res.indices].to_numpy()))
    tables["diversity"] = pd.DataFrame(rows, columns=["alpha", "n_high_quality", "eta", "eta_minus",
                                                      "diverse_size", "features"])
    tables["diverse_subset"] = (pd.concat(chosen, ignore_index=True) if chosen
                                else pd.DataFrame(columns=[*KEY_COLUMNS, "m_f"]))


def analyze(solutions: pd.DataFrame, high_quality: pd.DataFrame, beta_kg: float,
            params: StructureParams = StructureParams(), boundary_conditions: dict | None = None,
            ) -> tuple[dict[str, float], dict[str, pd.DataFrame], dict[str, Figure]]:
    """Run the whole Sec. III.B analysis; see the module docstring for what comes back.

    ``solutions``: every solve, all α (solution table); ``high_quality``: its β-filtered rows (converged,
    m_f ≥ ``beta_kg``); ``boundary_conditions``: the resource dict for Figs. 9–10 (default: the stored one).
    """
    boundary = boundary_conditions if boundary_conditions is not None else load_boundary_conditions()
    delta = params.modes.delta
    needed = ["tau_s", "tau_i", "tau_f", "m_f"]
    conv = solutions[solutions["converged"].astype(bool)].dropna(subset=needed).reset_index(drop=True)
    hq = high_quality.dropna(subset=needed).reset_index(drop=True)
    alphas = np.sort(conv["alpha"].unique())
    metrics: dict[str, float] = {"beta_kg": float(beta_kg), "delta_tu": float(delta),
                                 "n_solutions": float(len(solutions)), "n_converged": float(len(conv)),
                                 "n_high_quality": float(len(hq))}
    tables: dict[str, pd.DataFrame] = {}
    figures: dict[str, Figure] = {}

    # Hyperplanes per α (on A_α).
    modes: dict[float, np.ndarray] = {}
    mode_rows, conv_parts = [], []
    for a in alphas:
        ca = conv[conv["alpha"] == a]
        modes[a] = detect_modes(time_of_flight(ca), params.modes)
        ca = _with_planes(ca, modes[a], delta)
        conv_parts.append(ca)
        ha = _with_planes(hq[hq["alpha"] == a], modes[a], delta)
        k = _key(a)
        metrics[f"n_converged_alpha_{k}"] = float(len(ca))
        metrics[f"n_modes_alpha_{k}"] = float(len(modes[a]))
        metrics[f"hyperplane_spacing_alpha_{k}"] = hyperplane_spacing(modes[a])
        metrics[f"hyperplane_period_alpha_{k}"] = hyperplane_period(modes[a], delta)
        metrics[f"on_plane_fraction_alpha_{k}"] = float(ca["on_plane"].mean())
        for i, T in enumerate(modes[a]):
            on_c = ca[ca["on_plane"] & (ca["plane"] == i)]
            on_h = ha[ha["on_plane"] & (ha["plane"] == i)]
            mode_rows.append({"alpha": float(a), "plane": i, "tof": float(T), "n_converged": len(on_c),
                              "n_high_quality": len(on_h),
                              "m_f_best": float(on_c["m_f"].max()) if len(on_c) else math.nan})
    tables["modes"] = pd.DataFrame(mode_rows, columns=["alpha", "plane", "tof", "n_converged", "n_high_quality",
                                                       "m_f_best"])
    all_gaps = np.concatenate([np.diff(m) for m in modes.values()] or [np.empty(0)])
    metrics["hyperplane_spacing"] = float(np.median(all_gaps)) if all_gaps.size else math.nan
    conv_t = pd.concat(conv_parts) if conv_parts else _with_planes(conv, np.empty(0), delta)

    # Figs. 3–4.
    shown = _nearest_alphas(alphas, params.fig03_alphas)
    sel = conv_t[conv_t["alpha"].isin(shown)]
    figures["fig03_time_hyperplanes"] = figs.fig03_time_hyperplanes(sel, shown)
    figures["fig04_tof_histograms"] = figs.fig04_tof_histograms(sel, {a: modes[a] for a in shown},
                                                                params.histogram_bin)

    # Focus α: Figs. 5–8.
    focus = _pick_alpha(alphas, params.focus_alpha)
    metrics["focus_alpha"] = float(focus) if focus is not None else math.nan
    fmodes = modes.get(focus, np.empty(0))
    fconv = conv_t[conv_t["alpha"] == focus] if focus is not None else conv_t.iloc[:0]
    fhq = _with_planes(hq[hq["alpha"] == focus], fmodes, delta)
    near = project_to_plane(fhq[fhq["on_plane"]])
    metrics["focus_high_quality"] = float(len(fhq))
    metrics["focus_high_quality_on_plane"] = float(len(near))
    metrics["focus_m_f_best"] = float(fconv["m_f"].max()) if len(fconv) else math.nan
    figures["fig05_hyperplane_filtering"] = figs.fig05_hyperplane_filtering([
        (f"(a) converged, α = {_key(focus) if focus is not None else '–'}", fconv),
        (f"(b) β-filtered, m_f ≥ {beta_kg:g} kg", fhq),
        (f"(c) within δ = {delta:g} TU of a mode, projected", near),
    ])
    counts = near.groupby("plane_tof").size().sort_values(ascending=False, kind="stable")
    fig06_planes = sorted(counts.index[: params.fig06_max_planes])
    figures["fig06_inplane_mass_contours"] = figs.fig06_inplane_mass_contours(near, fig06_planes,
                                                                              params.contour_levels)

    tof_f, mf_f = fconv["tof"].to_numpy(), fconv["m_f"].to_numpy()
    ma_macro = moving_averages(tof_f, mf_f, params.ma_windows_macro)
    ma_micro = moving_averages(tof_f, mf_f, params.ma_windows_micro)
    tables["moving_average"] = pd.concat([ma_macro.assign(scale="macro"), ma_micro.assign(scale="micro")],
                                         ignore_index=True)
    focus_value = focus if focus is not None else math.nan
    figures["fig07_moving_average_macro"] = figs.fig07_moving_average_macro(tof_f, mf_f, ma_macro, focus_value)
    if params.micro_center is not None:
        center = float(params.micro_center)
    else:
        busiest = fconv[fconv["on_plane"]].groupby("plane_tof").size()
        center = float(busiest.idxmax()) if len(busiest) else float(np.median(tof_f)) if len(tof_f) else 0.0
    metrics["micro_center_tu"] = center
    figures["fig08_moving_average_micro"] = figs.fig08_moving_average_micro(
        tof_f, mf_f, ma_micro, focus_value, center, params.micro_half_width)

    # Funnels (Figs. 11–13, Tables 1–2) on the chosen planes of the near-plane β-filtered set.
    if params.funnel_planes is not None and len(fmodes):
        chosen = list(dict.fromkeys(float(fmodes[np.abs(fmodes - T).argmin()]) for T in params.funnel_planes))
    else:
        chosen = [float(T) for T in counts.index[:2]]
    planes = _funnel_section(near, chosen, params, metrics, tables)
    for k, (name, draw) in enumerate((("fig11_funnels", figs.fig11_funnels), ("fig12_funnels", figs.fig12_funnels))):
        plane, T = planes[k] if k < len(planes) else (None, None)
        figures[name] = draw(plane, T, params.contour_levels)
    interval_label = ("95 % confidence interval of the mean" if params.control_interval == "mean_ci"
                      else "2.5–97.5 % percentile band")
    figures["fig13_control_statistics"] = figs.fig13_control_statistics(tables["control_statistics"],
                                                                        interval_label)

    # Figs. 9–10: trajectories, from different planes and from the first funnel plane.
    refs = reference_arcs(boundary)
    across = select_across_hyperplanes(near, params.n_trajectories)
    within = select_within_hyperplane(near[near["plane_tof"] == chosen[0]] if chosen else near.iloc[:0],
                                      params.n_trajectories)
    paths_across = transfer_paths(near.loc[across], boundary, [f"Solution {ROMAN[i]}" for i in range(len(across))])
    paths_within = transfer_paths(near.loc[within], boundary, [f"Solution {chr(65 + i)}" for i in range(len(within))])
    figures["fig09_trajectories_across_hyperplanes"] = figs.fig09_trajectories_across_hyperplanes(
        paths_across, refs, boundary)
    figures["fig10_trajectories_within_hyperplane"] = figs.fig10_trajectories_within_hyperplane(
        paths_within, refs, boundary, chosen[0] if chosen else None)
    shown_rows = pd.concat([_identity(near.loc[across]).assign(figure="fig09"),
                            _identity(near.loc[within]).assign(figure="fig10")], ignore_index=True)
    paths = paths_across + paths_within
    tables["trajectories"] = shown_rows.assign(label=[p.label for p in paths], tof=[p.tof for p in paths],
                                               m_f=[p.m_f for p in paths])

    _diversity_section(hq, params.diversity, metrics, tables)
    return metrics, tables, figures
