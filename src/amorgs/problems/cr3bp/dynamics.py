"""CR3BP + fuel-mass dynamics in the rotating frame, as plain numpy functions (spec §2).

State ξ = (x, y, z, vx, vy, vz, m) in DU, VU and kg of fuel.  Thrust ``thrust_vec_nd`` is the thrust
vector in kg·DU/TU² (magnitude T·ρ, see :func:`constants.thrust_nd`), so the acceleration is
thrust_vec / (m_dry + m) and ṁ = −|thrust| / c.  These functions feed scipy's integrators (boundary
conditions, independent verification, dense trajectories); the NLP uses the CasADi twin in
:mod:`amorgs.problems.cr3bp.transcription`.
"""

from __future__ import annotations

import math

import numpy as np

from amorgs.problems.cr3bp.constants import DRY_MASS_KG, MU


def gravity_accel(r: np.ndarray, mu: float = MU) -> np.ndarray:
    """Gravity + centrifugal acceleration ∇Ū(r) (DU/TU²) for positions r of shape (3,) or (3, n)."""
    x, y, z = r
    r1 = np.sqrt((x + mu) ** 2 + y**2 + z**2)
    r2 = np.sqrt((x - 1 + mu) ** 2 + y**2 + z**2)
    k1, k2 = (1 - mu) / r1**3, mu / r2**3
    return np.array([x - k1 * (x + mu) - k2 * (x - 1 + mu), y - k1 * y - k2 * y, -k1 * z - k2 * z])


def ballistic_rhs(t: float, s: np.ndarray, mu: float = MU) -> np.ndarray:
    """d/dt of the 6-state (x, y, z, vx, vy, vz) without thrust."""
    g = gravity_accel(s[:3], mu)
    return np.concatenate([s[3:6], [g[0] + 2 * s[4], g[1] - 2 * s[3], g[2]]])


def potential_hessian(r: np.ndarray, mu: float = MU) -> np.ndarray:
    """∂²Ū/∂r² (3×3) — the lower-left block of the variational equations."""
    x, y, z = r
    d1 = np.array([x + mu, y, z])
    d2 = np.array([x - 1 + mu, y, z])
    r1, r2 = np.linalg.norm(d1), np.linalg.norm(d2)
    h = np.diag([1.0, 1.0, 0.0])
    for k, d, rr in ((1 - mu, d1, r1), (mu, d2, r2)):
        h += k * (3 * np.outer(d, d) / rr**5 - np.eye(3) / rr**3)
    return h


def variational_rhs(t: float, s: np.ndarray, mu: float = MU) -> np.ndarray:
    """d/dt of the 6-state plus its row-major 6×6 state-transition matrix (42 entries)."""
    a = np.zeros((6, 6))
    a[:3, 3:] = np.eye(3)
    a[3:, :3] = potential_hessian(s[:3], mu)
    a[3, 4], a[4, 3] = 2.0, -2.0
    phi = s[6:].reshape(6, 6)
    return np.concatenate([ballistic_rhs(t, s[:6], mu), (a @ phi).ravel()])


def powered_rhs(t: float, s: np.ndarray, thrust_vec_nd: np.ndarray, mdot_per_thrust: float, mu: float = MU) -> np.ndarray:
    """d/dt of the 7-state under a constant thrust vector (kg·DU/TU²).

    ``mdot_per_thrust`` converts |thrust_vec_nd| into kg of fuel per TU (= 1/c in matching units).
    """
    d = ballistic_rhs(t, s[:6], mu)
    d[3:6] += thrust_vec_nd / (DRY_MASS_KG + s[6])
    return np.concatenate([d, [-np.linalg.norm(thrust_vec_nd) * mdot_per_thrust]])


def constant_thrust_rhs(thrust_vec_nd: np.ndarray, mdot_per_thrust: float, mu: float = MU):
    """:func:`powered_rhs` for one constant thrust vector (kg·DU/TU²), as ``f(t, s)`` for scipy's integrators: the
    same operations in the same order on Python floats (the gravity terms of :func:`ballistic_rhs`, then the thrust
    acceleration; the fuel rate −|thrust|·``mdot_per_thrust`` computed once), so bit for bit the same values at
    ≈ 1/7 of the array version's cost.  The independent re-propagation (spec §6) spends most of its time here;
    :func:`powered_rhs` stays the readable twin, and serves a thrust that changes along the arc."""
    tx, ty, tz = (float(v) for v in thrust_vec_nd)
    fuel_rate = float(-np.linalg.norm(thrust_vec_nd) * mdot_per_thrust)
    sqrt = math.sqrt

    def rhs(t: float, s: np.ndarray) -> np.ndarray:
        x, y, z, vx, vy, vz, m = s.tolist()
        r1 = sqrt((x + mu) ** 2 + y**2 + z**2)
        r2 = sqrt((x - 1 + mu) ** 2 + y**2 + z**2)
        k1, k2 = (1 - mu) / r1**3, mu / r2**3
        mass = DRY_MASS_KG + m
        return np.array([vx, vy, vz,
                         x - k1 * (x + mu) - k2 * (x - 1 + mu) + 2 * vy + tx / mass,
                         y - k1 * y - k2 * y - 2 * vx + ty / mass,
                         -k1 * z - k2 * z + tz / mass,
                         fuel_rate])

    return rhs


def jacobi_constant(s: np.ndarray, mu: float = MU) -> np.ndarray:
    """C = x² + y² + 2(1−μ)/r₁ + 2μ/r₂ − v² for states of shape (6,) or (6, n) (or 7-states)."""
    x, y, z, vx, vy, vz = s[:6]
    r1 = np.sqrt((x + mu) ** 2 + y**2 + z**2)
    r2 = np.sqrt((x - 1 + mu) ** 2 + y**2 + z**2)
    return x**2 + y**2 + 2 * (1 - mu) / r1 + 2 * mu / r2 - (vx**2 + vy**2 + vz**2)
