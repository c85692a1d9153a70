"""Dense transfer trajectories and the reference arcs drawn around them (paper Figs. 9–10).

Selection rules (deterministic, documented so a reader knows why these solutions are shown):

- *across hyperplanes* (Fig. 9): from up to ``k`` hyperplanes spread over the TOF range (the lowest, highest
  and evenly spaced ones between), the best-m_f solution of each;
- *within a hyperplane* (Fig. 10): the best-m_f solution of the plane, then farthest-point picks in the
  in-plane coordinates (τ1', τ2') so that the ``k`` solutions differ as much as the plane allows.

Reference arcs come from the boundary-condition resource: the L1 halo orbit (one period from ``halo_state``)
and the stable-manifold arc from ξ_f to the halo, re-created exactly as ξ_f was made — ``manifold_backward_tu``
backward from ``manifold_departure_state`` — and shown in forward time.  Positions are in DU (rotating frame).
"""

from __future__ import annotations

import numpy as np
import pandas as pd
from scipy.integrate import solve_ivp

from amorgs.analysis.hyperplanes import time_of_flight
from amorgs.analysis.structure_result import TransferPath
from amorgs.problems.cr3bp.dynamics import ballistic_rhs
from amorgs.problems.cr3bp.propagation import propagate
from amorgs.problems.cr3bp.transcription import variable_names

REFERENCE_RTOL = 1e-11


def select_across_hyperplanes(plane_rows: pd.DataFrame, k: int) -> list:
    """Index labels of the best-m_f solution in each of up to ``k`` planes spread over TOF.

    ``plane_rows`` has ``plane_tof`` (T of each solution's hyperplane) and ``m_f``.
    """
    if plane_rows.empty or k < 1:
        return []
    planes = np.sort(plane_rows["plane_tof"].unique())
    picks = planes[np.unique(np.round(np.linspace(0, len(planes) - 1, min(k, len(planes)))).astype(int))]
    return [plane_rows.loc[plane_rows["plane_tof"] == T, "m_f"].idxmax() for T in picks]


def select_within_hyperplane(plane_rows: pd.DataFrame, k: int) -> list:
    """Index labels: the best-m_f solution, then farthest-point picks in (tau1p, tau2p), up to ``k``."""
    if plane_rows.empty or k < 1:
        return []
    xy = plane_rows[["tau1p", "tau2p"]].to_numpy(dtype=float)
    chosen = [int(np.argmax(plane_rows["m_f"].to_numpy(dtype=float)))]
    while len(chosen) < min(k, len(plane_rows)):
        d = np.min(np.linalg.norm(xy[:, None, :] - xy[None, chosen, :], axis=-1), axis=1)
        chosen.append(int(np.argmax(d)))
    return [plane_rows.index[i] for i in chosen]


def transfer_paths(rows: pd.DataFrame, boundary: dict, labels: list[str]) -> list[TransferPath]:
    """Re-propagate each solution row (DOP853, :func:`propagate`) into a :class:`TransferPath`."""
    names = list(variable_names())
    tof = time_of_flight(rows)
    paths = []
    for (index, row), label, T in zip(rows.iterrows(), labels, tof):
        traj = propagate(row[names].to_numpy(dtype=float), float(row["alpha"]), boundary["initial_state"],
                         boundary["terminal_state"])
        paths.append(TransferPath(label=label, tof=float(T), m_f=float(row["m_f"]), alpha=float(row["alpha"]),
                                  t=traj.t, positions=traj.states[:3], row=int(index)))
    return paths


def reference_arcs(boundary: dict) -> dict[str, np.ndarray]:
    """Positions (3, n) in DU of the ``halo`` orbit (one period) and the ``manifold`` arc ξ_f → halo."""
    mu = float(boundary["mu"])
    halo = solve_ivp(ballistic_rhs, (0.0, float(boundary["halo_period"])), np.asarray(boundary["halo_state"], float),
                     method="DOP853", rtol=REFERENCE_RTOL, atol=REFERENCE_RTOL, args=(mu,), dense_output=True)
    t_halo = np.linspace(0.0, float(boundary["halo_period"]), 400)
    back = float(boundary["manifold_backward_tu"])
    manifold = solve_ivp(ballistic_rhs, (0.0, -back), np.asarray(boundary["manifold_departure_state"], float),
                         method="DOP853", rtol=REFERENCE_RTOL, atol=REFERENCE_RTOL, args=(mu,), dense_output=True)
    t_man = np.linspace(-back, 0.0, 600)
    return {"halo": halo.sol(t_halo)[:3], "manifold": manifold.sol(t_man)[:3]}
