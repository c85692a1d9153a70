"""Independent re-propagation of stored solutions with scipy's adaptive DOP853 (spec §6).

This is deliberately a different integrator from the NLP's fixed-step RK8: a solution counts as
converged only if its match point closes here to within ``verify_tol``
(:class:`~amorgs.solvers.options.IpoptOptions`) in each of position (DU), velocity (VU) and fuel (kg / 1000).
The same code returns dense trajectories for figures.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.integrate import solve_ivp

from amorgs.problems.cr3bp import constants as K
from amorgs.problems.cr3bp.dynamics import constant_thrust_rhs

VERIFY_RTOL = 1e-12
VERIFY_ATOL = 1e-12


@dataclass
class Trajectory:
    """Dense trajectory in time order: ``t`` (TU from departure, shape (n,)), ``states`` (7, n) with fuel
    in kg, and ``match_defect`` = backward − forward state at the match point in (DU, VU, kg/1000)."""

    t: np.ndarray
    states: np.ndarray
    match_defect: np.ndarray
    match_time: float


def _arc(state, duration, thrust_vec_nd, mdot_per_thrust, dense, rtol, atol):
    if duration == 0.0:
        return np.array([0.0]), state[:, None]
    sol = solve_ivp(
        constant_thrust_rhs(thrust_vec_nd, mdot_per_thrust),
        (0.0, duration),
        state,
        method="DOP853",
        rtol=rtol,
        atol=atol,
        dense_output=False,
        t_eval=np.linspace(0.0, duration, 40) if dense else None,
    )
    if not sol.success:
        raise FloatingPointError(sol.message)
    return sol.t, sol.y


def _chains(x: np.ndarray, alpha: float, initial_state, terminal_state, dense: bool, rtol: float, atol: float):
    n = (len(x) - 4) // 3
    tau_s, tau_i, tau_f, m_f = x[:4]
    t_nd = K.thrust_nd(alpha)
    mdot_per_thrust = K.mass_flow_kg_per_tu(alpha) / t_nd if t_nd else 0.0
    dt = tau_s / n

    def thrust(k: int) -> np.ndarray:
        th, ph, rho = x[4 + 3 * k : 7 + 3 * k]
        return t_nd * rho * np.array([np.cos(ph) * np.cos(th), np.cos(ph) * np.sin(th), np.sin(ph)])

    zero = np.zeros(3)
    fwd_plan = [(tau_i, zero)] + [(dt, thrust(k)) for k in range(n // 2)]
    bwd_plan = [(-tau_f, zero)] + [(-dt, thrust(k)) for k in range(n - 1, n // 2 - 1, -1)]
    out = []
    for plan, start in ((fwd_plan, np.asarray(initial_state, float)), (bwd_plan, np.r_[terminal_state[:6], m_f])):
        s, t0 = start.copy(), 0.0
        ts, ys = [], []
        for duration, tv in plan:
            t, y = _arc(s, float(duration), tv, mdot_per_thrust, dense, rtol, atol)
            ts.append(t0 + t)
            ys.append(y)
            s, t0 = y[:, -1], t0 + float(duration)
        out.append((np.concatenate(ts), np.hstack(ys), s))
    return out


def match_defect(x, alpha, initial_state, terminal_state, rtol=VERIFY_RTOL, atol=VERIFY_ATOL) -> np.ndarray:
    """(Δr, Δv, Δm/1000) backward − forward at the match point, re-propagated with DOP853."""
    (_, _, end_f), (_, _, end_b) = _chains(np.asarray(x, float), alpha, initial_state, terminal_state, False, rtol, atol)
    d = end_b - end_f
    d[6] /= 1000.0
    return d


def independent_defect(x, alpha, initial_state, terminal_state) -> float:
    """Max-abs re-propagated match defect in (DU, VU, kg/1000); ``inf`` if the integration fails."""
    try:
        d = match_defect(x, alpha, initial_state, terminal_state)
    except (ArithmeticError, ValueError):  # a step through a primary (division by zero) or an overflow
        return float("inf")
    return float(np.max(np.abs(d))) if np.all(np.isfinite(d)) else float("inf")


def propagate(x, alpha, initial_state, terminal_state) -> Trajectory:
    """Dense trajectory of a stored decision vector (forward arc, then the backward arc in time order)."""
    x = np.asarray(x, float)
    (t_f, y_f, end_f), (t_b, y_b, end_b) = _chains(x, alpha, initial_state, terminal_state, True, 1e-10, 1e-10)
    tof = x[0] + x[1] + x[2]
    d = end_b - end_f
    d[6] /= 1000.0
    t = np.concatenate([t_f, tof + t_b[::-1]])
    states = np.hstack([y_f, y_b[:, ::-1]])
    return Trajectory(t=t, states=states, match_defect=d, match_time=float(x[1] + x[0] / 2))
