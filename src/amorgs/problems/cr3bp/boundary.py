"""Boundary conditions of the transfer (spec §3–4), computed once with a tight integrator and stored.

* Initial state ξ₀: end of a 1 N tangential low-thrust spiral from GTO apogee, 6.48423370092 TU long.
* Terminal state ξ_f: a point of the Earth-side stable manifold of the northern L1 halo with Jacobi
  constant C_L1 − 0.02, reached by propagating 8 TU backward from the halo at phase 0.2 T.

All integrations use scipy's DOP853 at rtol = atol = 1e-13.  The result is stored in
``resources/boundary_conditions.json`` (keys of spec §6 plus the intermediate quantities) and
:func:`load_boundary_conditions` reads it; ``amorgs boundary-conditions --check`` recomputes and compares.
"""

from __future__ import annotations

import json
import math
import os
from pathlib import Path

import numpy as np

from amorgs.problems.cr3bp import constants as K
from amorgs.problems.cr3bp.dynamics import (
    ballistic_rhs,
    gravity_accel,
    jacobi_constant,
    powered_rhs,
    variational_rhs,
)

RTOL = ATOL = 1e-13
SPIRAL_DURATION_TU = 6.48423370092
SPIRAL_THRUST_N = 1.0
HALO_ENERGY_OFFSET = 0.02  # C_halo = C_L1 − 0.02
MANIFOLD_PHASE = 0.2
MANIFOLD_EPSILON = 1e-6
MANIFOLD_BACKWARD_TU = 8.0
GTO = dict(a_km=24_510.0, e=0.72345981, i_deg=15.0, raan_deg=0.0, argp_deg=0.0, nu_deg=180.0)

DEFAULT_PATH = Path(__file__).resolve().parents[4] / "resources" / "boundary_conditions.json"


def resource_path() -> Path:
    """Where the boundary conditions live: ``$AMORGS_BOUNDARY_CONDITIONS`` or ``resources/`` of the repo."""
    return Path(os.environ.get("AMORGS_BOUNDARY_CONDITIONS", DEFAULT_PATH))


def l1_point(mu: float = K.MU) -> float:
    """x-coordinate (DU) of L1, the collinear point between Earth and Moon."""
    from scipy.optimize import brentq

    return brentq(lambda x: gravity_accel(np.array([x, 0.0, 0.0]), mu)[0], 0.5, 1 - mu - 1e-3, xtol=1e-15)


def gto_apogee_state(mu: float = K.MU) -> np.ndarray:
    """GTO apogee (spec §3.1) as a rotating-frame 6-state at t = 0 (DU, VU)."""
    a = GTO["a_km"] / K.DU_KM
    e, inc, nu = GTO["e"], math.radians(GTO["i_deg"]), math.radians(GTO["nu_deg"])
    if GTO["raan_deg"] != 0.0 or GTO["argp_deg"] != 0.0:
        raise NotImplementedError("only Ω = ω = 0 is specified")
    gm = 1.0 - mu  # Earth's GM in DU³/TU²
    p = a * (1 - e * e)
    r = p / (1 + e * math.cos(nu))
    r_pf = np.array([r * math.cos(nu), r * math.sin(nu), 0.0])
    v_pf = math.sqrt(gm / p) * np.array([-math.sin(nu), e + math.cos(nu), 0.0])
    rot = np.array([[1, 0, 0], [0, math.cos(inc), -math.sin(inc)], [0, math.sin(inc), math.cos(inc)]])
    r_in, v_in = rot @ r_pf, rot @ v_pf
    v_rot = v_in - np.cross([0.0, 0.0, 1.0], r_in)  # v_rot = v − ω × r (Earth-relative r)
    return np.concatenate([r_in + np.array([-mu, 0.0, 0.0]), v_rot])


def spiral_end_state(mu: float = K.MU) -> np.ndarray:
    """ξ₀: 7-state after the 1 N spiral along the Earth-relative inertial velocity (fuel in kg)."""
    from scipy.integrate import solve_ivp

    t_nd = K.thrust_nd(SPIRAL_THRUST_N)
    mdot_per_thrust = K.mass_flow_kg_per_tu(SPIRAL_THRUST_N) / t_nd

    def rhs(t: float, s: np.ndarray) -> np.ndarray:
        v_inertial = s[3:6] + np.array([-s[1], s[0] + mu, 0.0])
        return powered_rhs(t, s, t_nd * v_inertial / np.linalg.norm(v_inertial), mdot_per_thrust, mu)

    s0 = np.concatenate([gto_apogee_state(mu), [K.GTO_FUEL_KG]])
    sol = solve_ivp(rhs, (0.0, SPIRAL_DURATION_TU), s0, method="DOP853", rtol=RTOL, atol=ATOL)
    return sol.y[:, -1]


def propagate_stm(s0: np.ndarray, t: float, mu: float = K.MU) -> tuple[np.ndarray, np.ndarray]:
    """Ballistic state and 6×6 state-transition matrix after time t (may be negative)."""
    from scipy.integrate import solve_ivp

    y0 = np.concatenate([s0, np.eye(6).ravel()])
    sol = solve_ivp(variational_rhs, (0.0, t), y0, method="DOP853", rtol=RTOL, atol=ATOL, args=(mu,))
    return sol.y[:6, -1], sol.y[6:, -1].reshape(6, 6)


def _half_period_crossing(s0: np.ndarray, mu: float) -> tuple[float, np.ndarray, np.ndarray]:
    """Propagate until the next y = 0 crossing (after a short time); return (t, state, STM)."""
    from scipy.integrate import solve_ivp


    def event(t: float, s: np.ndarray, mu: float) -> float:
        return s[1]

    event.terminal = True
    event.direction = -1.0 if s0[4] > 0 else 1.0
    y0 = np.concatenate([s0, np.eye(6).ravel()])
    sol = solve_ivp(
        variational_rhs, (0.0, 10.0), y0, method="DOP853", rtol=RTOL, atol=ATOL, events=event, args=(mu,)
    )
    t_half = float(sol.t_events[0][0])
    y = sol.y_events[0][0]
    return t_half, y[:6], y[6:].reshape(6, 6)


def halo_orbit(c_target: float, guess: tuple[float, float, float], mu: float = K.MU, tol: float = 1e-12):
    """Northern L1 halo with Jacobi constant ``c_target`` by differential correction.

    Unknowns (x₀, z₀, ẏ₀) of the symmetric xz-plane crossing; equations ẋ = ż = 0 at the half-period
    crossing and C(x₀, z₀, ẏ₀) = c_target.  Newton with the exact state-transition matrix.
    Returns (initial 6-state at phase 0, period).
    """
    x0, z0, vy0 = guess
    for _ in range(50):
        s0 = np.array([x0, 0.0, z0, 0.0, vy0, 0.0])
        t_half, s, phi = _half_period_crossing(s0, mu)
        sdot = ballistic_rhs(0.0, s, mu)
        # Variation at the crossing with the crossing time adjusted so that y stays 0.
        cols = [0, 2, 4]
        dy_ds0 = phi[1, cols]
        dcross = phi[np.ix_([3, 5], cols)] - np.outer(sdot[[3, 5]], dy_ds0) / sdot[1]
        # Jacobi constant gradient with respect to (x, z, vy) at the initial state.
        g = gravity_accel(s0[:3], mu)
        dc = np.array([2 * (g[0]), 2 * (g[2]), -2 * vy0])
        f = np.array([s[3], s[5], jacobi_constant(s0, mu) - c_target])
        if np.max(np.abs(f)) < tol:
            return s0, 2 * t_half
        step = np.linalg.solve(np.vstack([dcross, dc]), -f)
        x0, z0, vy0 = x0 + step[0], z0 + step[1], vy0 + step[2]
    raise RuntimeError(f"halo differential correction did not converge (residual {np.max(np.abs(f)):.3e})")


def compute_boundary_conditions(mu: float = K.MU) -> dict:
    """Recompute every boundary-condition quantity of spec §3–4 (takes a few seconds)."""
    from scipy.integrate import solve_ivp

    x_l1 = l1_point(mu)
    c_l1 = float(jacobi_constant(np.array([x_l1, 0, 0, 0, 0, 0.0]), mu))
    c_halo = c_l1 - HALO_ENERGY_OFFSET
    halo0, period = halo_orbit(c_halo, (0.82339, 0.02664, 0.13734), mu)
    halo_end, monodromy = propagate_stm(halo0, period, mu)
    eigval, eigvec = np.linalg.eig(monodromy)
    order = np.argsort(np.abs(eigval))
    stable_val, unstable_val = eigval[order[0]], eigval[order[-1]]
    v_stable = np.real(eigvec[:, order[0]])
    halo_phase, phi_phase = propagate_stm(halo0, MANIFOLD_PHASE * period, mu)
    v = phi_phase @ v_stable
    v = v / np.linalg.norm(v[:3])
    if v[0] > 0:
        v = -v
    manifold0 = halo_phase + MANIFOLD_EPSILON * v
    sol = solve_ivp(
        ballistic_rhs, (0.0, -MANIFOLD_BACKWARD_TU), manifold0, method="DOP853", rtol=RTOL, atol=ATOL, args=(mu,)
    )
    terminal = sol.y[:, -1]
    initial = spiral_end_state(mu)
    earth = np.array(K.EARTH_POSITION)
    return {
        "description": "LT-CR3BP boundary conditions, spec lt-cr3bp.md §3-4; rotating frame, DU/VU/TU, fuel in kg",
        "mu": mu,
        "du_km": K.DU_KM,
        "tu_s": K.TU_S,
        "vu_km_s": K.VU_KM_S,
        "integrator": {"method": "scipy DOP853", "rtol": RTOL, "atol": ATOL},
        "gto_state": gto_apogee_state(mu).tolist(),
        "spiral_duration_tu": SPIRAL_DURATION_TU,
        "initial_state": initial.tolist(),
        "initial_state_fields": ["x", "y", "z", "vx", "vy", "vz", "fuel_kg"],
        "l1_x": x_l1,
        "jacobi_l1": c_l1,
        "halo_jacobi": c_halo,
        "halo_state": halo0.tolist(),
        "halo_period": period,
        "halo_closure_error": float(np.max(np.abs(halo_end - halo0))),
        "monodromy_eigenvalues": [float(np.real(unstable_val)), float(np.real(stable_val))],
        "manifold_phase": MANIFOLD_PHASE,
        "manifold_epsilon": MANIFOLD_EPSILON,
        "manifold_backward_tu": MANIFOLD_BACKWARD_TU,
        "manifold_departure_state": manifold0.tolist(),
        "terminal_state": terminal.tolist(),
        "terminal_state_fields": ["x", "y", "z", "vx", "vy", "vz"],
        "terminal_earth_distance_km": float(np.linalg.norm(terminal[:3] - earth) * K.DU_KM),
    }


def write_boundary_conditions(path: str | Path | None = None) -> dict:
    """Recompute and write the JSON resource atomically; returns the dict."""
    target = Path(path) if path is not None else resource_path()
    data = compute_boundary_conditions()
    target.parent.mkdir(parents=True, exist_ok=True)
    tmp = target.with_suffix(".json.tmp")
    tmp.write_text(json.dumps(data, indent=2) + "\n")
    os.replace(tmp, target)
    return data


def load_boundary_conditions(path: str | Path | None = None) -> dict:
    """Read the stored resource; a missing file or key raises an error naming it."""
    source = Path(path) if path is not None else resource_path()
    if not source.is_file():
        raise FileNotFoundError(
            f"boundary conditions file {source} not found; create it with `amorgs boundary-conditions`"
        )
    data = json.loads(source.read_text())
    for key in ("mu", "initial_state", "terminal_state", "halo_state", "halo_period"):
        if key not in data:
            raise ValueError(f"boundary conditions file {source} lacks key {key!r}")
    return data
