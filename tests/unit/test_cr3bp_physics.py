"""Physics and boundary conditions of the LT-CR3BP (spec §1–4)."""

import json

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from amorgs.problems.cr3bp import constants as K
from amorgs.problems.cr3bp.boundary import (
    compute_boundary_conditions,
    load_boundary_conditions,
    propagate_stm,
    resource_path,
)
from amorgs.problems.cr3bp.dynamics import ballistic_rhs, jacobi_constant


@pytest.fixture(scope="module")
def stored():
    return load_boundary_conditions()


def test_units_match_spec():
    assert K.MU == pytest.approx(0.0121536631, rel=1e-9)
    assert K.TU_S == pytest.approx(375_189, rel=1e-5)
    assert K.VU_KM_S == pytest.approx(1.02455, rel=1e-5)
    # 1 N for one TU burns T/(Isp g0)·TU ≈ 38.26 kg
    assert K.mass_flow_kg_per_tu(1.0) == pytest.approx(375_189 / 9806.65, rel=1e-5)


def test_jacobi_constant_conserved_on_ballistic_arc(stored):
    s0 = np.asarray(stored["terminal_state"])
    sol = solve_ivp(ballistic_rhs, (0, -8.0), s0, method="DOP853", rtol=1e-13, atol=1e-13, dense_output=True)
    c = jacobi_constant(sol.sol(np.linspace(0, -8.0, 200)))
    assert np.max(np.abs(c - c[0]) / abs(c[0])) <= 1e-10


def test_halo_closes_and_monodromy_is_symplectic(stored):
    halo0 = np.asarray(stored["halo_state"])
    end, monodromy = propagate_stm(halo0, stored["halo_period"])
    assert np.max(np.abs(end - halo0)) <= 1e-9
    lam_u, lam_s = stored["monodromy_eigenvalues"]
    assert lam_u * lam_s == pytest.approx(1.0, rel=1e-4)
    eig = np.sort(np.abs(np.linalg.eigvals(monodromy)))
    assert eig[-1] == pytest.approx(2128, rel=1e-3) and eig[0] == pytest.approx(4.70e-4, rel=1e-2)
    assert jacobi_constant(halo0) == pytest.approx(stored["jacobi_l1"] - 0.02, abs=1e-12)


def test_boundary_values_match_spec(stored):
    x, _, z, _, vy, _ = stored["halo_state"]
    assert (x, z, vy) == pytest.approx((0.82339, 0.02664, 0.13734), abs=1e-5)
    assert stored["halo_period"] == pytest.approx(2.7477, abs=1e-4)
    assert stored["l1_x"] == pytest.approx(0.83690, abs=1e-5)
    assert stored["initial_state"][6] == pytest.approx(451.9, abs=0.05)
    assert stored["terminal_earth_distance_km"] == pytest.approx(137_750, rel=1e-3)


def test_recomputation_equals_stored_file(stored):
    fresh = json.loads(json.dumps(compute_boundary_conditions()))
    for key in ("initial_state", "terminal_state", "halo_state", "halo_period", "mu", "monodromy_eigenvalues"):
        np.testing.assert_allclose(fresh[key], stored[key], rtol=1e-9, atol=1e-11, err_msg=key)


def test_missing_resource_is_named(tmp_path):
    with pytest.raises(FileNotFoundError, match="boundary_conditions"):
        load_boundary_conditions(tmp_path / "boundary_conditions.json")
    assert resource_path().name == "boundary_conditions.json"


def test_the_constant_thrust_rhs_is_the_array_rhs_bit_for_bit():
    """The re-propagation's fast right-hand side (Python floats, fuel rate computed once per arc) returns exactly
    :func:`powered_rhs`'s values — near both primaries, far out, with and without thrust — so the independent
    verification (spec §6) and every stored ``verify_defect`` are unchanged by it."""
    from amorgs.problems.cr3bp.dynamics import constant_thrust_rhs, powered_rhs

    rng = np.random.default_rng(7)
    for i in range(3000):
        s = np.r_[rng.uniform(-1.5, 1.5, 3) * (rng.uniform(1e-3, 1) if i % 3 == 0 else 1.0),
                  rng.uniform(-2, 2, 3), rng.uniform(0, 1000)]
        if i % 4 == 0:  # near the Moon
            s[:3] = [1 - K.MU, 0.0, 0.0] + rng.normal(scale=1e-2, size=3)
        thrust = np.zeros(3) if i % 5 == 0 else rng.normal(size=3) * K.thrust_nd(rng.uniform(0.1, 1.0))
        mdot = rng.uniform(0, 50)
        assert np.array_equal(constant_thrust_rhs(thrust, mdot)(0.0, s), powered_rhs(0.0, s, thrust, mdot)), s


def test_the_match_defect_of_a_stored_solution_is_that_of_the_array_rhs(monkeypatch):
    """Re-propagating stored solutions with :func:`powered_rhs` itself (the arcs of ``_chains``) gives the
    match defect :func:`match_defect` reports, bit for bit."""
    from pathlib import Path

    import pandas as pd

    from amorgs.problems import get_problem
    from amorgs.problems.cr3bp import propagation
    from amorgs.problems.cr3bp.dynamics import powered_rhs

    problem = get_problem("cr3bp")
    table = pd.read_parquet(Path(__file__).parents[1] / "data" / "cr3bp_solutions_small.parquet")
    rows = table[table["converged"]].groupby("alpha").head(1).head(3)
    assert len(rows) >= 2
    for _, row in rows.iterrows():
        x = row[list(problem.variable_names)].to_numpy(float)
        fast = propagation.match_defect(x, row["alpha"], problem.initial_state, problem.terminal_state)

        def array_arc(state, duration, thrust, mdot_per_thrust, dense, rtol, atol):
            if duration == 0.0:
                return np.array([0.0]), state[:, None]
            sol = solve_ivp(powered_rhs, (0.0, duration), state, method="DOP853", rtol=rtol, atol=atol,
                            args=(thrust, mdot_per_thrust))
            return sol.t, sol.y

        with monkeypatch.context() as m:
            m.setattr(propagation, "_arc", array_arc)
            slow = propagation.match_defect(x, row["alpha"], problem.initial_state, problem.terminal_state)
        assert np.array_equal(fast, slow) and np.max(np.abs(fast)) <= 1e-5
