"""Units and physical constants of the Earth–Moon low-thrust problem (spec §1).

Canonical units: DU = Earth–Moon distance, TU such that the mean motion is 1 rad/TU, VU = DU/TU.  Masses in
the state are *fuel* masses in kg; thrust acceleration divides by the wet mass ``DRY_MASS_KG + m``.
"""

from __future__ import annotations

import math

G_KM3_PER_KG_S2 = 6.6743e-20
EARTH_MASS_KG = 5.97219e24
MOON_MASS_KG = 7.3477e22
MU = MOON_MASS_KG / (EARTH_MASS_KG + MOON_MASS_KG)
DU_KM = 384_400.0
TU_S = math.sqrt(DU_KM**3 / (G_KM3_PER_KG_S2 * (EARTH_MASS_KG + MOON_MASS_KG)))
VU_KM_S = DU_KM / TU_S

G0_M_S2 = 9.80665
ISP_S = 1000.0
EXHAUST_SPEED_M_S = ISP_S * G0_M_S2
DRY_MASS_KG = 300.0
GTO_FUEL_KG = 700.0

EARTH_POSITION = (-MU, 0.0, 0.0)


def thrust_nd(thrust_n: float) -> float:
    """Thrust in newtons → kg·DU/TU² (divide by a mass in kg to get an acceleration in DU/TU²)."""
    return thrust_n * 1e-3 * TU_S**2 / DU_KM


def mass_flow_kg_per_tu(thrust_n: float) -> float:
    """Fuel mass flow at full throttle, kg per TU, for a thrust in newtons: T / (Isp g0) · TU."""
    return thrust_n / EXHAUST_SPEED_M_S * TU_S
