"""Rotating ↔ Earth-centred inertial frame of the CR3BP (amorgs.problems.cr3bp.frames)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from amorgs.problems.cr3bp import constants as K
from amorgs.problems.cr3bp import frames
from amorgs.problems.cr3bp.dynamics import ballistic_rhs


def test_round_trip_rotating_inertial_rotating():
    rng = np.random.default_rng(3)
    t = rng.uniform(0, 40, 200)
    s = np.column_stack([rng.uniform(-1.2, 1.2, (200, 3)), rng.uniform(-2, 2, (200, 3))])
    back = frames.inertial_to_rotating(t, frames.rotating_to_inertial(t, s))
    np.testing.assert_allclose(back, s, rtol=0, atol=1e-13)
    km = frames.to_km(s)
    np.testing.assert_allclose(frames.from_km(km), s, rtol=1e-15, atol=1e-15)


def test_known_states_moon_and_epoch_axes():
    moon_rot = np.array([1 - K.MU, 0, 0, 0, 0, 0])  # at rest in the rotating frame
    for t in (0.0, math.pi / 2, 1.234):
        emi = frames.rotating_to_inertial(t, moon_rot)
        # the Moon circles the Earth at 1 DU with speed ω · 1 DU = 1 VU
        np.testing.assert_allclose(emi[:3], [math.cos(t), math.sin(t), 0], atol=1e-15)
        np.testing.assert_allclose(emi[3:], [-math.sin(t), math.cos(t), 0], atol=1e-15)
    # at the epoch the axes coincide: only the Earth offset and ω × r differ
    s = np.array([0.3, 0.2, 0.1, 0.01, 0.02, 0.03])
    emi = frames.rotating_to_inertial(0.0, s)
    np.testing.assert_allclose(emi[:3], [0.3 + K.MU, 0.2, 0.1], atol=1e-15)
    np.testing.assert_allclose(emi[3:], [0.01 - 0.2, 0.02 + 0.3 + K.MU, 0.03], atol=1e-15)


def test_inertial_velocity_matches_finite_differences_of_inertial_position():
    """A ballistic CR3BP arc (rotating frame, DOP853 dense) mapped to the inertial frame: the converted velocity
    equals the central difference of the converted positions."""
    s0 = np.array([0.5, 0.1, 0.05, 0.1, 0.6, 0.02])
    sol = solve_ivp(ballistic_rhs, (0, 3.0), s0, method="DOP853", rtol=1e-12, atol=1e-12, dense_output=True)
    t = np.linspace(0.1, 2.9, 57)
    h = 1e-5
    emi = frames.rotating_to_inertial(t, sol.sol(t).T)
    plus = frames.rotating_to_inertial(t + h, sol.sol(t + h).T)[:, :3]
    minus = frames.rotating_to_inertial(t - h, sol.sol(t - h).T)[:, :3]
    fd = (plus - minus) / (2 * h)
    np.testing.assert_allclose(fd, emi[:, 3:], rtol=0, atol=1e-8)
    # in km/s: the same check with physical units
    fd_km_s = fd * K.DU_KM / K.TU_S
    np.testing.assert_allclose(fd_km_s, frames.to_km(emi)[:, 3:], rtol=0, atol=1e-8)


def test_directions_rotate_and_epochs_round_trip():
    t = np.array([0.0, math.pi / 2])
    u = np.array([[1.0, 0, 0], [1.0, 0, 0]])
    np.testing.assert_allclose(frames.rotate_direction(t, u), [[1, 0, 0], [0, 1, 0]], atol=1e-15)
    tu = np.array([0.0, 1.0, 12.345678, 40.0])
    ep = frames.epochs(tu)
    assert ep[0].isot.startswith("2030-01-01T00:00:00")
    assert ep.scale == "tdb"
    np.testing.assert_allclose(frames.tu_after_epoch(ep), tu, rtol=0, atol=1e-12)
    assert frames.seconds_after_epoch(1.0) == pytest.approx(K.TU_S)
