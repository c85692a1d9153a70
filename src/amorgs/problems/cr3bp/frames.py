"""Rotating (synodic) ↔ Earth-centred inertial frame, with units and a nominal epoch.

Frames
------
*Rotating frame* (the problem's own, spec §1): origin at the Earth–Moon barycentre, Earth at (−μ, 0, 0), Moon
at (1 − μ, 0, 0), z along the angular velocity of the Earth–Moon line (ω = 1 rad/TU).  Nondimensional: DU, VU,
TU (:mod:`amorgs.problems.cr3bp.constants`).

*Earth-centred inertial frame* ("EMI", for Earth–Moon inertial): origin at the Earth's centre, axes fixed in
inertial space and equal to the rotating axes at the **epoch** ``t = 0`` (the start of the transfer): x
towards the Moon at the epoch, z along the Earth–Moon orbital angular momentum (the rotating frame's z), y
completing the right-handed triad.  At time t (TU after the epoch) the rotating axes have turned by θ = ω t
about z.  This is *not* a standard frame such as EME2000/GCRF: the CR3BP is time-invariant and circular, so
it fixes no orientation relative to the equator or the ecliptic; the epoch only labels t = 0.  Strictly, the
Earth circles the barycentre in the CR3BP, so this Earth-centred frame is non-rotating but not inertial (the
same is true of GCRF in the real solar system).

The nominal epoch is :data:`EPOCH_ISO` in the TDB time scale: t TU after departure is the instant
``EPOCH + t · TU_S`` seconds (TDB, SI seconds).  Nothing in the dynamics depends on it.

Transformations (r' = r − r_Earth, the Earth-relative position in rotating axes, R(θ) the rotation by θ
about z)::

    r_I = R(θ) r',            v_I = R(θ) (v + ω ẑ × r'),         θ = ω t
    r'  = R(−θ) r_I,          v   = R(−θ) v_I − ω ẑ × r'
    direction vectors (thrust): û_I = R(θ) û

All functions take arrays of shape (..., 3) or (..., 6) with t broadcast against the leading dimensions.
"""

from __future__ import annotations

import numpy as np

from amorgs.problems.cr3bp import constants as K

#: Nominal epoch of t = 0 (the start of the transfer), TDB.
EPOCH_ISO = "2030-01-01T00:00:00"
EPOCH_SCALE = "tdb"
#: Angular velocity of the rotating frame, rad/TU.
OMEGA = 1.0
#: Name of the inertial frame in exported files (not a SANA-registered frame: see the module docstring).
INERTIAL_FRAME_NAME = "EMI_CR3BP"
INERTIAL_FRAME_DESCRIPTION = (
    "Earth-centred, non-rotating frame of the CR3BP: axes equal to the rotating (synodic) axes at the epoch "
    f"{EPOCH_ISO} TDB (start of the transfer): x towards the Moon at the epoch, z along the Earth-Moon orbital "
    "angular momentum, y completing the right-handed triad. Not EME2000/GCRF: the CR3BP fixes no orientation "
    "relative to the equator or ecliptic."
)


def _rot_z(theta: np.ndarray) -> np.ndarray:
    """Rotation matrices about z by ``theta`` (rad), shape (..., 3, 3)."""
    c, s = np.cos(theta), np.sin(theta)
    z, o = np.zeros_like(c), np.ones_like(c)
    return np.stack([np.stack([c, -s, z], -1), np.stack([s, c, z], -1), np.stack([z, z, o], -1)], -2)


def _apply(rot: np.ndarray, v: np.ndarray) -> np.ndarray:
    return np.einsum("...ij,...j->...i", rot, v)


def _omega_cross(r: np.ndarray) -> np.ndarray:
    """ω ẑ × r for r of shape (..., 3)."""
    return OMEGA * np.stack([-r[..., 1], r[..., 0], np.zeros_like(r[..., 0])], -1)


def rotating_to_inertial(t: np.ndarray, state: np.ndarray) -> np.ndarray:
    """Barycentric rotating state (x, y, z, vx, vy, vz) in DU, VU at t TU after the epoch → Earth-centred
    inertial state in DU, VU (same nondimensional units; multiply by :data:`DU_KM`, :data:`VU_KM_S`)."""
    t = np.asarray(t, float)
    state = np.asarray(state, float)
    r_rel = state[..., :3] - np.asarray(K.EARTH_POSITION)
    rot = _rot_z(OMEGA * t)
    r_i = _apply(rot, r_rel)
    v_i = _apply(rot, state[..., 3:6] + _omega_cross(r_rel))
    return np.concatenate([r_i, v_i], -1)


def inertial_to_rotating(t: np.ndarray, state: np.ndarray) -> np.ndarray:
    """Inverse of :func:`rotating_to_inertial` (DU, VU in, DU, VU out; barycentric rotating)."""
    t = np.asarray(t, float)
    state = np.asarray(state, float)
    rot_back = _rot_z(-OMEGA * t)
    r_rel = _apply(rot_back, state[..., :3])
    v = _apply(rot_back, state[..., 3:6]) - _omega_cross(r_rel)
    return np.concatenate([r_rel + np.asarray(K.EARTH_POSITION), v], -1)


def rotate_direction(t: np.ndarray, u: np.ndarray) -> np.ndarray:
    """A direction (e.g. the thrust unit vector) in rotating axes → the same direction in inertial axes."""
    return _apply(_rot_z(OMEGA * np.asarray(t, float)), np.asarray(u, float))


def to_km(state_nd: np.ndarray) -> np.ndarray:
    """(…, 6) state in DU, VU → km, km/s."""
    s = np.array(state_nd, float, copy=True)
    s[..., :3] *= K.DU_KM
    s[..., 3:6] *= K.VU_KM_S
    return s


def from_km(state_km: np.ndarray) -> np.ndarray:
    """(…, 6) state in km, km/s → DU, VU."""
    s = np.array(state_km, float, copy=True)
    s[..., :3] /= K.DU_KM
    s[..., 3:6] /= K.VU_KM_S
    return s


def seconds_after_epoch(t_tu: np.ndarray) -> np.ndarray:
    """TU after the epoch → seconds after the epoch."""
    return np.asarray(t_tu, float) * K.TU_S


def epochs(t_tu: np.ndarray):
    """astropy ``Time`` (TDB) of times ``t_tu`` TU after :data:`EPOCH_ISO`."""
    from astropy.time import Time, TimeDelta

    return Time(EPOCH_ISO, scale=EPOCH_SCALE) + TimeDelta(seconds_after_epoch(t_tu), format="sec")


def tu_after_epoch(times) -> np.ndarray:
    """astropy ``Time`` (any scale) → TU after :data:`EPOCH_ISO` (TDB)."""
    from astropy.time import Time

    return np.asarray((times.tdb - Time(EPOCH_ISO, scale=EPOCH_SCALE)).sec, float) / K.TU_S


DU_KM = K.DU_KM
VU_KM_S = K.VU_KM_S
TU_S = K.TU_S
