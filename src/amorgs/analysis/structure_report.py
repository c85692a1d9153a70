"""Structure analysis of the LT-CR3BP solution set in one call (paper Sec. III.B, Figs. 3–13, Tables 1–2).

``analyze(solutions, high_quality, beta_kg, params)`` runs every step and returns a
:class:`~amorgs.analysis.structure_result.StructureResult` — data only; :mod:`amorgs.figures.structure`
draws it:

- ``metrics``: flat ``{key: float}`` (MLflow-ready, keys from :func:`amorgs.alphas.metric_key`), e.g.
  ``n_modes/alpha_1.000``, ``hyperplane_spacing/alpha_1.000`` (TU), ``funnels_plane_1`` (funnels in the
  first funnel plane), ``diverse_size/alpha_1.000``;
- ``tables``: ``modes`` (hyperplanes per α), ``funnels`` (Tables 1–2), ``control_statistics`` (Fig. 13),
  ``moving_average`` (Figs. 7–8), ``diversity`` (Eq. 12–13 per α), ``diverse_subset`` (the chosen rows),
  ``trajectories`` (rows shown in Figs. 9–10);
- the data of Figs. 3–13 (solution sets with their hyperplane coordinates, the chosen planes, trajectories).

Data sets, as in the paper: hyperplanes (modes) are detected per α on every *converged* solution (A_α);
Figs. 5b–13 and the funnels use the β-filtered set A_{α,β} at the focus α (paper: α = 1.0), restricted to
solutions within δ of a mode; the moving averages use all converged solutions at the focus α (Fig. 7: A_1.0);
diversity is per α over A_{α,β}.  α are told apart by their labels (:mod:`amorgs.alphas`).
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from amorgs.alphas import distinct_alphas, metric_key, rows_at, same_alpha
from amorgs.analysis.controls import group_statistics
from amorgs.analysis.diversity import diverse_subset
from amorgs.analysis.funnels import TABLE_COLUMNS as FUNNEL_COLUMNS
from amorgs.analysis.funnels import cluster_funnels, funnel_name, funnel_table
from amorgs.analysis.hyperplanes import (
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
from amorgs.analysis.structure_params import DiversityParams, StructureParams
from amorgs.analysis.structure_result import StructureResult
from amorgs.analysis.trajectories import (
    reference_arcs,
    select_across_hyperplanes,
    select_within_hyperplane,
    transfer_paths,
)
from amorgs.problems.cr3bp.boundary import load_boundary_conditions

__all__ = ["StructureParams", "StructureResult", "analyze"]

KEY_COLUMNS = ("problem", "alpha", "seed", "start")
ROMAN = ("I", "II", "III", "IV", "V", "VI")


def _pick_alpha(available: list[float], wanted: float) -> float | None:
    """``wanted`` if it is among ``available``, else the largest available α; None if there is none."""
    if not available:
        return None
    hit = [a for a in available if same_alpha(a, wanted)]
    return hit[0] if hit else max(available)


def _nearest_alphas(available: list[float], wanted: tuple[float, ...]) -> list[float]:
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
    for a in distinct_alphas(hq["alpha"]):
        ha = rows_at(hq, a).reset_index(drop=True)
        res = diverse_subset(ha, params)
        rows.append({"alpha": a, "n_high_quality": len(ha), "eta": res.eta, "eta_minus": res.eta_minus,
                     "diverse_size": res.size, "features": params.features})
        metrics[metric_key("diverse_size", a)] = float(res.size)
        metrics[metric_key("eta_minus", a)] = res.eta_minus
        chosen.append(_identity(ha.iloc[res.indices]).assign(m_f=ha["m_f"].iloc[res.indices].to_numpy()))
    tables["diversity"] = pd.DataFrame(rows, columns=["alpha", "n_high_quality", "eta", "eta_minus",
                                                      "diverse_size", "features"])
    tables["diverse_subset"] = (pd.concat(chosen, ignore_index=True) if chosen
                                else pd.DataFrame(columns=[*KEY_COLUMNS, "m_f"]))


def analyze(solutions: pd.DataFrame, high_quality: pd.DataFrame, beta_kg: float,
            params: StructureParams = StructureParams(), boundary_conditions: dict | None = None,
            ) -> StructureResult:
    """Run the whole Sec. III.B analysis; see the module docstring for what comes back.

    ``solutions``: every solve, all α (solution table); ``high_quality``: its β-filtered rows (converged,
    m_f ≥ ``beta_kg``, kg); ``boundary_conditions``: the resource dict for Figs. 9–10 (default: the stored one).
    """
    boundary = boundary_conditions if boundary_conditions is not None else load_boundary_conditions()
    delta = params.modes.delta
    needed = ["tau_s", "tau_i", "tau_f", "m_f"]
    conv = solutions[solutions["converged"].astype(bool)].dropna(subset=needed).reset_index(drop=True)
    hq = high_quality.dropna(subset=needed).reset_index(drop=True)
    alphas = distinct_alphas(conv["alpha"])
    metrics: dict[str, float] = {"beta_kg": float(beta_kg), "delta_tu": float(delta),
                                 "n_solutions": float(len(solutions)), "n_converged": float(len(conv)),
                                 "n_high_quality": float(len(hq))}
    tables: dict[str, pd.DataFrame] = {}

    # Hyperplanes per α (on A_α).
    modes: dict[float, np.ndarray] = {}
    mode_rows, conv_parts = [], []
    for a in alphas:
        ca = rows_at(conv, a)
        modes[a] = detect_modes(time_of_flight(ca), params.modes)
        ca = _with_planes(ca, modes[a], delta)
        conv_parts.append(ca)
        ha = _with_planes(rows_at(hq, a), modes[a], delta)
        metrics[metric_key("n_converged", a)] = float(len(ca))
        metrics[metric_key("n_modes", a)] = float(len(modes[a]))
        metrics[metric_key("hyperplane_spacing", a)] = hyperplane_spacing(modes[a])
        metrics[metric_key("hyperplane_period", a)] = hyperplane_period(modes[a], delta)
        metrics[metric_key("on_plane_fraction", a)] = float(ca["on_plane"].mean())
        for i, T in enumerate(modes[a]):
            on_c = ca[ca["on_plane"] & (ca["plane"] == i)]
            on_h = ha[ha["on_plane"] & (ha["plane"] == i)]
            mode_rows.append({"alpha": a, "plane": i, "tof": float(T), "n_converged": len(on_c),
                              "n_high_quality": len(on_h),
                              "m_f_best": float(on_c["m_f"].max()) if len(on_c) else math.nan})
    tables["modes"] = pd.DataFrame(mode_rows, columns=["alpha", "plane", "tof", "n_converged", "n_high_quality",
                                                       "m_f_best"])
    all_gaps = np.concatenate([np.diff(m) for m in modes.values()] or [np.empty(0)])
    metrics["hyperplane_spacing"] = float(np.median(all_gaps)) if all_gaps.size else math.nan
    conv_t = pd.concat(conv_parts) if conv_parts else _with_planes(conv, np.empty(0), delta)

    # Focus α: Figs. 5–8.
    focus = _pick_alpha(alphas, params.focus_alpha)
    metrics["focus_alpha"] = float(focus) if focus is not None else math.nan
    fmodes = modes.get(focus, np.empty(0))
    fconv = rows_at(conv_t, focus) if focus is not None else conv_t.iloc[:0]
    fhq = _with_planes(rows_at(hq, focus) if focus is not None else hq.iloc[:0], fmodes, delta)
    near = project_to_plane(fhq[fhq["on_plane"]])
    metrics["focus_high_quality"] = float(len(fhq))
    metrics["focus_high_quality_on_plane"] = float(len(near))
    metrics["focus_m_f_best"] = float(fconv["m_f"].max()) if len(fconv) else math.nan
    counts = near.groupby("plane_tof").size().sort_values(ascending=False, kind="stable")

    tof_f, mf_f = fconv["tof"].to_numpy(), fconv["m_f"].to_numpy()
    ma_macro = moving_averages(tof_f, mf_f, params.ma_windows_macro)
    ma_micro = moving_averages(tof_f, mf_f, params.ma_windows_micro)
    tables["moving_average"] = pd.concat([ma_macro.assign(scale="macro"), ma_micro.assign(scale="micro")],
                                         ignore_index=True)
    if params.micro_center is not None:
        center = float(params.micro_center)
    else:
        busiest = fconv[fconv["on_plane"]].groupby("plane_tof").size()
        center = float(busiest.idxmax()) if len(busiest) else float(np.median(tof_f)) if len(tof_f) else 0.0
    metrics["micro_center_tu"] = center

    # Funnels (Figs. 11–13, Tables 1–2) on the chosen planes of the near-plane β-filtered set.
    if params.funnel_planes is not None and len(fmodes):
        chosen = list(dict.fromkeys(float(fmodes[np.abs(fmodes - T).argmin()]) for T in params.funnel_planes))
    else:
        chosen = [float(T) for T in counts.index[:2]]
    planes = _funnel_section(near, chosen, params, metrics, tables)

    # Figs. 9–10: trajectories, from different planes and from the first funnel plane.
    across = select_across_hyperplanes(near, params.n_trajectories)
    within = select_within_hyperplane(near[near["plane_tof"] == chosen[0]] if chosen else near.iloc[:0],
                                      params.n_trajectories)
    paths_across = transfer_paths(near.loc[across], boundary, [f"Solution {ROMAN[i]}" for i in range(len(across))])
    paths_within = transfer_paths(near.loc[within], boundary, [f"Solution {chr(65 + i)}" for i in range(len(within))])
    shown_rows = pd.concat([_identity(near.loc[across]).assign(figure="fig09"),
                            _identity(near.loc[within]).assign(figure="fig10")], ignore_index=True)
    paths = paths_across + paths_within
    tables["trajectories"] = shown_rows.assign(label=[p.label for p in paths], tof=[p.tof for p in paths],
                                               m_f=[p.m_f for p in paths])

    _diversity_section(hq, params.diversity, metrics, tables)
    return StructureResult(
        metrics=metrics, tables=tables, params=params, beta_kg=float(beta_kg), modes=modes, converged=conv_t,
        shown_alphas=_nearest_alphas(alphas, params.fig03_alphas), focus_alpha=focus, focus_high_quality=fhq,
        near_plane=near, fig06_planes=sorted(counts.index[: params.fig06_max_planes]), micro_center=center,
        funnel_planes=planes, paths_across=paths_across, paths_within=paths_within,
        reference_arcs=reference_arcs(boundary), boundary=boundary,
    )
