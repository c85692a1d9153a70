"""De Jong's 5th function: objective, gradient, BFGS solver records, input validation, metrics, figures."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest
import scipy.optimize
from matplotlib.figure import Figure
from scipy.optimize import minimize

from amorgs.analysis.dejong_eval import prediction_metrics
from amorgs.figures.dejong import fig02_foxholes, fig16_dejong_predictions
from amorgs.problems import get_problem
from amorgs.problems.dejong import (
    A_PAPER,
    DeJong5,
    dejong5,
    dejong5_gradient,
    foxholes_25,
    minima_matrix,
    true_minima,
)
from amorgs.solvers.options import BfgsOptions

ALPHAS = (0.0, math.pi / 9, 0.7, math.pi / 2)


def reference_minimiser(centre: np.ndarray, alpha: float) -> np.ndarray:
    """The local minimiser next to a hole centre by a derivative-free method (Nelder–Mead, tight tolerances)."""
    A = minima_matrix(alpha)
    sol = minimize(lambda x: dejong5(x, A), centre, method="Nelder-Mead",
                   options={"xatol": 1e-10, "fatol": 1e-16, "maxiter": 5000})
    assert sol.success and np.abs(dejong5_gradient(sol.x, A)).max() < 1e-8
    return sol.x


def test_registry_and_layout():
    p = get_problem("dejong")
    assert isinstance(p, DeJong5)
    assert p.name == "dejong" and p.variable_names == ("x1", "x2")
    np.testing.assert_array_equal(p.lower, [-50, -50])
    np.testing.assert_array_equal(p.upper, [50, 50])
    assert p.alpha_range == (0.0, math.pi / 2)


def test_minima_matrix_rotates_eq38():
    np.testing.assert_allclose(minima_matrix(0.0), A_PAPER)
    # a quarter turn maps (x1, x2) to (−x2, x1)
    np.testing.assert_allclose(minima_matrix(math.pi / 2), np.vstack([-A_PAPER[1], A_PAPER[0]]), atol=1e-12)
    tm = true_minima(0.7)
    assert tm.shape == (8, 2)
    np.testing.assert_allclose(np.linalg.norm(tm, axis=1), np.linalg.norm(A_PAPER, axis=0))


def test_foxholes_25_grid():
    A = foxholes_25()
    assert A.shape == (2, 25)
    assert len({tuple(c) for c in A.T}) == 25
    assert set(A[0]) == set(A[1]) == {-32.0, -16.0, 0.0, 16.0, 32.0}


def test_dejong5_vectorised_and_plateau():
    A = minima_matrix(0.3)
    x = np.random.default_rng(0).uniform(-50, 50, size=(3, 4, 2))
    J = dejong5(x, A)
    assert J.shape == (3, 4)
    loop = [[dejong5(x[i, j], A) for j in range(4)] for i in range(3)]
    np.testing.assert_allclose(J, loop, rtol=1e-14)
    # far from every hole J → 1/0.002
    assert dejong5(np.array([-50.0, -50.0]), foxholes_25() + 200.0) == pytest.approx(500.0, rel=1e-9)


def test_gradient_matches_finite_differences():
    A = minima_matrix(0.4)
    rng = np.random.default_rng(1)
    points = np.vstack([rng.uniform(-45, 45, size=(5, 2)), true_minima(0.4) + 0.7])
    h = 1e-4
    for x in points:
        fd = [(dejong5(x + h * e, A) - dejong5(x - h * e, A)) / (2 * h) for e in np.eye(2)]
        np.testing.assert_allclose(dejong5_gradient(x, A), fd, rtol=1e-5, atol=1e-9)


@pytest.mark.parametrize("alpha", ALPHAS)
def test_objective_at_true_minima_is_the_local_minimum_value(alpha):
    A = minima_matrix(alpha)
    for centre in true_minima(alpha):
        x_star = reference_minimiser(centre, alpha)
        assert np.linalg.norm(x_star - centre) < 0.3  # the minimiser sits at ≈ the hole centre
        j_centre, j_star = dejong5(centre, A), dejong5(x_star, A)
        assert j_star <= j_centre
        assert j_centre == pytest.approx(j_star, rel=1e-3)
        # a lone hole would give 1/1.002; its neighbours deepen it slightly
        assert 0.99 < j_star < 1 / 1.002


@pytest.mark.parametrize("alpha", ALPHAS)
def test_bfgs_from_near_a_minimum_converges_to_it(alpha):
    solver = DeJong5().make_local_solver()
    for k in (0, 5):  # one hole of each cluster
        centre = true_minima(alpha)[k]
        rec = solver.solve(centre + np.array([0.6, -0.4]), alpha)
        assert rec.converged and rec.solver_success and rec.status == "success"
        assert np.linalg.norm(rec.x - reference_minimiser(centre, alpha)) < 1e-3


def test_solve_record_fields():
    p = DeJong5()
    rec = p.make_local_solver({"gtol": 1e-6, "maxiter": 200}).solve(np.array([10.0, -10.0]), 0.2)
    assert isinstance(rec.status, str) and rec.status == "success"
    assert rec.converged is True and rec.solver_success is True
    assert rec.x.shape == (2,)
    assert rec.objective == pytest.approx(dejong5(rec.x, minima_matrix(0.2)), rel=1e-12)
    assert rec.iterations > 0
    assert rec.wall_s >= 0 and rec.cpu_s >= 0
    assert math.isnan(rec.defect) and math.isnan(rec.verify_defect)
    row = rec.to_row(p.variable_names)
    assert row["x1"] == rec.x[0] and row["x2"] == rec.x[1] and row["status"] == "success"


def test_iteration_cap_is_a_status_not_a_success():
    rec = DeJong5().make_local_solver({"maxiter": 1}).solve(np.array([10.0, -10.0]), 0.2)
    assert rec.status == "max_iterations"
    assert not rec.converged and not rec.solver_success
    assert rec.iterations == 1


def test_plateau_stop_is_converged_with_a_large_objective():
    # the gradient at this corner is ≈ 2e-5: below a loose gtol BFGS stops at once, far from every hole
    rec = DeJong5().make_local_solver({"gtol": 1e-4}).solve(np.array([50.0, -50.0]), 0.0)
    assert rec.converged and rec.iterations == 0
    assert rec.objective > 100


def test_numerical_failure_is_a_record(monkeypatch):
    def boom(*args, **kwargs):
        raise FloatingPointError("overflow in line search")

    monkeypatch.setattr(scipy.optimize, "minimize", boom)  # the solver imports it when it solves
    rec = DeJong5().make_local_solver().solve(np.array([1.0, 2.0]), 0.5)
    assert rec.status == "exception" and not rec.converged and not rec.solver_success
    assert np.isnan(rec.x).all() and "overflow" in rec.message
    assert rec.wall_s >= 0


@pytest.mark.parametrize("alpha", [-0.1, 2.0, float("nan"), "abc", None])
def test_bad_alpha_raises_naming_the_field(alpha):
    p = DeJong5()
    with pytest.raises(ValueError, match="alpha"):
        p.make_local_solver().solve(np.array([1.0, 2.0]), alpha)
    with pytest.raises(ValueError, match="alpha"):
        p.sample_uniform(alpha, 3, np.random.default_rng(0))


@pytest.mark.parametrize(
    ("x0", "match"),
    [
        ([1.0, float("nan")], "'x2'"),
        ([float("inf"), 0.0], "'x1'"),
        ([1.0, 2.0, 3.0], "length 2"),
        ([[1.0, 2.0]], "length 2"),
        ([60.0, 0.0], "'x1'.*bounds"),
    ],
)
def test_bad_guess_raises_naming_the_field(x0, match):
    p = DeJong5()
    with pytest.raises(ValueError, match=match):
        p.check_guess(np.array(x0))
    with pytest.raises(ValueError, match=match):
        p.make_local_solver().solve(np.array(x0), 0.3)


def test_bad_solver_options_raise():
    with pytest.raises(ValueError, match="tolerance"):
        DeJong5().make_local_solver({"tolerance": 1e-6})
    with pytest.raises(ValueError, match="gtol"):
        DeJong5().make_local_solver({"gtol": 0.0})


def test_solver_takes_typed_options_and_mappings_alike():
    typed = DeJong5().make_local_solver(BfgsOptions(maxiter=3))
    assert DeJong5.options_type is BfgsOptions and typed.options == BfgsOptions(maxiter=3)
    assert typed.options_hash == BfgsOptions(maxiter=3).digest()
    a = typed.solve(np.array([10.0, -10.0]), 0.2)
    b = DeJong5().make_local_solver({"maxiter": 3}).solve(np.array([10.0, -10.0]), 0.2)
    assert a.status == b.status == "max_iterations" and np.array_equal(a.x, b.x) and a.objective == b.objective


def test_sample_uniform_shape_bounds_determinism():
    p = DeJong5()
    x = p.sample_uniform(0.5, 1000, np.random.default_rng(42))
    assert x.shape == (1000, 2)
    assert (x >= -50).all() and (x <= 50).all()
    assert x.min() < -45 and x.max() > 45  # fills the box
    np.testing.assert_array_equal(x, p.sample_uniform(0.5, 1000, np.random.default_rng(42)))
    assert not np.array_equal(x, p.sample_uniform(0.5, 1000, np.random.default_rng(43)))
    assert p.sample_uniform(0.5, 0, np.random.default_rng(0)).shape == (0, 2)


def test_prediction_metrics():
    alpha = 2 * math.pi / 9
    tm = true_minima(alpha)
    exact = prediction_metrics(np.repeat(tm, 10, axis=0), alpha)
    assert exact["fraction_within_radius"] == 1.0 and exact["minima_covered"] == 8
    assert exact["n_samples"] == 80 and exact["radius"] == 3.0
    # samples 2.9 units off the first five minima, outward from their cluster's centre (so > 3 units from
    # every other minimum), plus 5 far misses and a NaN
    centre = np.repeat([tm[:4].mean(axis=0), tm[4:].mean(axis=0)], 4, axis=0)
    out = (tm - centre) / np.linalg.norm(tm - centre, axis=1, keepdims=True)
    near = (tm + 2.9 * out)[:5]
    far = np.full((5, 2), 49.0)
    m = prediction_metrics(np.vstack([near, far, [[np.nan, 0.0]]]), alpha)
    assert m["minima_covered"] == 5
    assert m["fraction_within_radius"] == pytest.approx(5 / 11)
    assert prediction_metrics(tm + 3.5 * out, alpha, radius=3.0)["minima_covered"] == 0


def test_figures_build():
    fig = fig02_foxholes(resolution=41)
    assert isinstance(fig, Figure) and len(fig.axes) == 3  # surface, contour, colorbar
    rng = np.random.default_rng(0)
    rows = [{"alpha": a, "x1": x[0], "x2": x[1]} for a in (0.0, 0.314159, 0.628319) for x in true_minima(a)]
    train_df = pd.DataFrame(rows)
    test = [math.pi / 9, 2 * math.pi / 9, math.pi / 3, 4 * math.pi / 9]
    samples = {a: true_minima(a)[rng.integers(0, 8, 50)] + rng.normal(0, 1, (50, 2)) for a in test}
    fig = fig16_dejong_predictions(train_df, samples, [0.0, 0.3142])
    assert isinstance(fig, Figure) and len(fig.axes) == 1 + 1 + 4  # (a), its colorbar, four (b) panels
    assert "2 α" in fig.axes[0].get_title()  # 0.628 was not requested
