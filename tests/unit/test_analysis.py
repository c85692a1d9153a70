"""Unit tests of the solution-structure analysis (paper Sec. III.B) on constructed data with known answers."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest

from amorgs.analysis import controls, diversity, funnels, hyperplanes, moving_average
from amorgs.analysis.structure_params import StructureParams


def _plane_points(rng, planes, per_plane, jitter):
    """Points (τ_s, τ_i, τ_f) ≥ 0 with τ_s + τ_i + τ_f = T + N(0, jitter) for each T in ``planes``."""
    rows = []
    for T in planes:
        w = rng.dirichlet([4.0, 2.0, 2.0], size=per_plane)
        tof = T + jitter * rng.standard_normal(per_plane)
        rows.append(w * tof[:, None])
    return np.vstack(rows)


def _table(tau, m_f=None, alpha=1.0):
    df = pd.DataFrame(tau, columns=list(hyperplanes.TIME_COLUMNS))
    df["m_f"] = 420.0 if m_f is None else m_f
    df["alpha"] = alpha
    return df


# -- hyperplanes -------------------------------------------------------------------------------------------
def test_detect_modes_recovers_constructed_planes():
    rng = np.random.default_rng(0)
    truth = np.array([12.3, 18.75, 25.2, 31.7, 38.15])
    tau = _plane_points(rng, truth, 12, 0.05)
    # Background noise between planes: single solutions must not become planes.
    noise = _plane_points(rng, [15.5, 22.0, 28.4], 1, 0.0)
    tof = hyperplanes.time_of_flight(_table(np.vstack([tau, noise])))
    modes = hyperplanes.detect_modes(tof)
    assert len(modes) == len(truth)
    np.testing.assert_allclose(modes, truth, atol=0.06)
    assert hyperplanes.hyperplane_spacing(modes) == pytest.approx(np.median(np.diff(truth)), abs=0.1)


def test_hyperplane_period_of_interleaved_ladders():
    ladder = 11.5 + 6.47 * np.arange(5)
    modes = np.sort(np.r_[ladder, ladder[:4] + 1.45])
    assert hyperplanes.hyperplane_spacing(modes) < 5.1  # a mix of the two offsets 1.45 and 5.02, not the period
    assert hyperplanes.hyperplane_period(modes, 0.25) == pytest.approx(6.47, abs=1e-9)
    assert math.isnan(hyperplanes.hyperplane_period(np.array([3.0]), 0.25))


def test_detect_modes_small_and_degenerate_inputs():
    p = hyperplanes.ModeParams()
    assert hyperplanes.detect_modes(np.array([]), p).size == 0
    assert hyperplanes.detect_modes(np.array([np.nan, 20.0]), p).size == 0  # one solution is not a plane
    modes = hyperplanes.detect_modes(np.array([20.0, 20.05, 19.98]), p)
    np.testing.assert_allclose(modes, [20.01], atol=0.03)
    assert math.isnan(hyperplanes.hyperplane_spacing(modes))
    with pytest.raises(ValueError, match="delta"):
        hyperplanes.ModeParams(delta=0.0)


def test_membership_is_eq32():
    modes = np.array([10.0, 16.5])
    tof = np.array([10.2, 10.3, 16.25, 13.0, np.nan])
    np.testing.assert_array_equal(hyperplanes.assign_hyperplane(tof, modes, 0.25), [0, -1, 1, -1, -1])
    np.testing.assert_array_equal(hyperplanes.assign_hyperplane(tof, np.empty(0), 0.25), [-1] * 5)


def test_frame_is_orthonormal_right_handed_with_exact_normal():
    R = hyperplanes.FRAME
    np.testing.assert_allclose(R @ R.T, np.eye(3), atol=1e-15)
    assert np.linalg.det(R) == pytest.approx(1.0)
    np.testing.assert_allclose(R[2], np.ones(3) / math.sqrt(3), atol=1e-15)


def test_transform_maps_plane_to_constant_normal_coordinate():
    rng = np.random.default_rng(1)
    tau = _plane_points(rng, [18.0, 24.5], 20, 0.0)
    t = hyperplanes.transform(tau, np.array([18.0, 24.5]))
    for T in (18.0, 24.5):
        on = t[t["plane_tof"] == T]
        assert len(on) == 20
        np.testing.assert_allclose(on["tau3p"], T / math.sqrt(3), atol=1e-12)
        np.testing.assert_allclose(on["normal_offset"], 0.0, atol=1e-12)
    # Distances are preserved (rotation) and in-plane distances equal 3-D distances within a plane.
    a, b = tau[0], tau[5]
    ta = t[["tau1p", "tau2p"]].to_numpy()
    assert np.linalg.norm(ta[0] - ta[5]) == pytest.approx(np.linalg.norm(a - b), rel=1e-12)
    # A point off the plane: normal offset is the signed distance (TOF − T)/√3.
    off = hyperplanes.transform(np.array([[10.0, 4.0, 4.2]]), np.array([18.0]))
    assert off["normal_offset"].iloc[0] == pytest.approx(0.2 / math.sqrt(3))
    proj = hyperplanes.project_to_plane(off)
    assert proj["tau3p"].iloc[0] == pytest.approx(18.0 / math.sqrt(3))
    assert proj["tau1p"].iloc[0] == off["tau1p"].iloc[0]


# -- funnels -----------------------------------------------------------------------------------------------
def test_funnels_separate_well_separated_blobs_and_name_by_size():
    rng = np.random.default_rng(2)
    a = rng.normal([0.0, 0.0], 0.1, size=(40, 2))
    b = rng.normal([3.0, 1.0], 0.1, size=(20, 2))
    xy = np.vstack([a, b])
    m = np.r_[np.full(40, 420.0), np.full(20, 430.0)]
    res = funnels.cluster_funnels(xy, m, funnels.FunnelParams(seed=0))
    assert res.n_funnels == 2
    np.testing.assert_array_equal(res.labels, np.r_[np.zeros(40), np.ones(20)])
    assert min(res.bic, key=res.bic.get) == 2
    # The clustering does not depend on the row order.
    perm = rng.permutation(60)
    shuffled = funnels.cluster_funnels(xy[perm], m[perm], funnels.FunnelParams(seed=0))
    np.testing.assert_array_equal(shuffled.labels, res.labels[perm])
    # Two stray solutions far away do not make a funnel of their own (min_per_funnel = 3).
    stray = funnels.cluster_funnels(np.vstack([a, [[8.0, 8.0], [8.2, 7.9]]]), np.full(42, 420.0))
    assert np.bincount(stray.labels).min() >= 3
    # Too few points for two funnels of min_per_funnel: a single funnel, no fit.
    small = funnels.cluster_funnels(xy[:7], m[:7], funnels.FunnelParams(min_per_funnel=5))
    assert small.n_funnels == 1 and not small.bic
    assert funnels.cluster_funnels(np.empty((0, 2)), np.empty(0)).n_funnels == 0


def test_funnel_table_counts_and_means():
    plane = pd.DataFrame({"tau_s": [6.0, 7.0, 10.0], "tau_i": [6.0, 5.0, 4.0], "tau_f": [6.0, 6.0, 4.0],
                          "m_f": [420.0, 430.0, 416.0], "tau1p": [0.0, 0.5, 2.0], "tau2p": [0.0, 0.1, 1.0]})
    t = funnels.funnel_table(plane, np.array([0, 0, 1]), 18.0)
    assert list(t["funnel"]) == ["A", "B"]
    assert list(t["count"]) == [2, 1]
    row = t.iloc[0]
    assert row["tau_s_mean"] == 6.5 and row["coast_mean"] == 11.5 and row["tof_mean"] == 18.0
    assert row["m_f_best"] == 430.0 and row["m_f_mean"] == 425.0


# -- moving averages ---------------------------------------------------------------------------------------
def test_moving_average_of_constant_is_constant_and_counts_window():
    rng = np.random.default_rng(3)
    tof = rng.uniform(10, 40, 200)
    ma = moving_average.moving_average(tof, np.full(200, 421.5), 0.5)
    np.testing.assert_allclose(ma["m_f_ma"], 421.5)
    assert np.all(np.diff(ma["tof"]) >= 0)
    brute = [np.sum(np.abs(tof - t) <= 0.25) for t in ma["tof"]]
    np.testing.assert_array_equal(ma["count"], brute)


def test_moving_average_known_values():
    ma = moving_average.moving_average(np.array([0.0, 1.0, 2.0, 10.0]), np.array([1.0, 2.0, 3.0, 7.0]), 2.0)
    np.testing.assert_allclose(ma["m_f_ma"], [1.5, 2.0, 2.5, 7.0])
    long = moving_average.moving_averages(np.arange(5.0), np.arange(5.0), (0.5, 4.0))
    assert set(long["window"]) == {0.5, 4.0}
    with pytest.raises(ValueError, match="window"):
        moving_average.moving_average(np.arange(3.0), np.arange(3.0), 0.0)


# -- diversity ---------------------------------------------------------------------------------------------
def test_greedy_subset_is_eta_diverse_and_maximal():
    rng = np.random.default_rng(4)
    x = rng.uniform(0, 1, size=(300, 3))
    eta = 0.15
    idx = diversity.greedy_diverse_subset(x, eta, quality=rng.uniform(size=300))
    assert diversity.is_eta_diverse(x, idx, eta)
    d = np.linalg.norm(x[:, None] - x[None, idx], axis=-1)
    others = np.setdiff1d(np.arange(300), idx)
    assert np.all(d[others].min(axis=1) <= eta)  # maximal: every left-out point conflicts with a chosen one


def test_greedy_prefers_low_degree_and_quality():
    # A path a–b–c (spacing 1, η = 1.5): the two ends beat the centre.
    x = np.array([[0.0], [1.0], [2.0]])
    np.testing.assert_array_equal(diversity.greedy_diverse_subset(x, 1.5), [0, 2])
    # Two isolated pairs: the better of each pair is kept.
    y = np.array([[0.0], [0.1], [5.0], [5.1]])
    np.testing.assert_array_equal(diversity.greedy_diverse_subset(y, 0.5, np.array([1, 2, 4, 3])), [1, 2])


def test_eta_minus_and_diverse_subset_on_table():
    df = _table(np.array([[10.0, 3.0, 3.0], [10.0, 3.0, 3.3], [20.0, 5.0, 5.0]]), m_f=[420.0, 425.0, 430.0])
    p = diversity.DiversityParams(eta=0.05)
    feats = diversity.diversity_features(df, p)
    np.testing.assert_allclose(feats[0], [0.25, 0.2, 0.2])
    res = diversity.diverse_subset(df, p)
    assert res.eta_minus == pytest.approx(0.3 / 15)
    # Rows 0 and 1 are 0.02 apart (≤ η): only the better one (row 1, 425 kg) stays.
    np.testing.assert_array_equal(res.indices, [1, 2])
    assert res.size == 2 and res.eta == 0.05
    assert diversity.diverse_subset(df, diversity.DiversityParams(eta=0.01)).size == 3


# -- controls ----------------------------------------------------------------------------------------------
def _controls_table(theta, phi, rho):
    n, N = theta.shape
    cols = {}
    for k in range(N):
        cols[f"theta_{k + 1:02d}"] = theta[:, k]
        cols[f"phi_{k + 1:02d}"] = phi[:, k]
        cols[f"rho_{k + 1:02d}"] = rho[:, k]
    return pd.DataFrame(cols)


def test_thrust_components_known_directions():
    theta = np.array([[0.0, math.pi / 2, 1.0]])
    phi = np.array([[0.0, 0.0, math.pi / 2]])
    rho = np.array([[1.0, 0.5, 0.2]])
    u = controls.thrust_components(_controls_table(theta, phi, rho))
    assert u.shape == (1, 3, 3)
    np.testing.assert_allclose(u[0], [[1, 0, 0], [0, 0.5, 0], [0, 0, 0.2]], atol=1e-15)


def test_segment_statistics_shapes_and_known_case():
    rng = np.random.default_rng(5)
    n, N = 10, 20
    df = _controls_table(rng.uniform(0, 2 * math.pi, (n, N)), rng.uniform(-1, 1, (n, N)), rng.uniform(0, 1, (n, N)))
    u = controls.thrust_components(df)
    s = controls.segment_statistics(u)
    assert len(s) == N * 3 and set(s["component"]) == set(controls.COMPONENTS)
    assert (s["lower"] <= s["mean"]).all() and (s["mean"] <= s["upper"]).all()
    # Known case: values 1, 2, 3 → mean 2, s = 1, t(0.975, 2) = 4.3027 → half-width 4.3027/√3.
    known = np.array([1.0, 2.0, 3.0])[:, None, None] * np.ones((3, 1, 3))
    k = controls.segment_statistics(known)
    np.testing.assert_allclose(k["mean"], 2.0)
    np.testing.assert_allclose(k["upper"] - k["mean"], 4.302652729911275 / math.sqrt(3), rtol=1e-9)
    p = controls.segment_statistics(known, interval="percentile")
    np.testing.assert_allclose(p["lower"], 1.05)
    np.testing.assert_allclose(p["upper"], 2.95)
    one = controls.segment_statistics(known[:1])
    assert one["lower"].isna().all() and (one["n"] == 1).all()
    g = controls.group_statistics(df, np.array(["A"] * 4 + ["B"] * 6))
    assert len(g) == 2 * N * 3 and list(g.columns)[0] == "group"
    assert set(g.loc[g["group"] == "B", "n"]) == {6}


def test_structure_params_from_dict():
    p = StructureParams.from_dict({"modes": {"delta": 0.3}, "diversity": {"eta": 0.05, "time_scale": [1, 1, 1]},
                                   "ma_windows_macro": [0.5], "funnel_planes": [18.7, 38.2]})
    assert p.modes.delta == 0.3 and p.diversity.time_scale == (1, 1, 1) and p.ma_windows_macro == (0.5,)
    assert p.funnel_planes == (18.7, 38.2)
    with pytest.raises(ValueError, match="unknown"):
        StructureParams.from_dict({"delta": 0.3})
    with pytest.raises(ValueError, match=r"modes\.bandwidthz"):
        StructureParams.from_dict({"modes": {"bandwidthz": 0.3}})


@pytest.mark.parametrize("values, field", [
    ({"histogram_bin": 0.0}, "StructureParams.histogram_bin"),
    ({"fig03_alphas": [0.1, -0.3]}, "StructureParams.fig03_alphas"),
    ({"n_trajectories": 7}, "StructureParams.n_trajectories"),
    ({"control_interval": "band"}, "StructureParams.control_interval"),
    ({"modes": {"delta": 0.0}}, "ModeParams.delta"),
    ({"funnels": {"n_init": 0}}, "FunnelParams.n_init"),
    ({"diversity": {"time_scale": [40.0, 0.0, 15.0]}}, "DiversityParams.time_scale"),
])
def test_structure_params_out_of_range_names_the_field(values, field):
    with pytest.raises(ValueError, match=field):
        StructureParams.from_dict(values)


def test_structure_params_module_is_stdlib_only():
    """The config validates ``cr3bp_analysis.params`` with these classes: importing them loads no numerics."""
    import subprocess
    import sys

    code = "import sys, amorgs.analysis.structure_params; print(sorted({'numpy', 'pandas', 'scipy'} & set(sys.modules)))"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"


@pytest.mark.parametrize("n, converged", [(0, True), (4, False), (2, True)])
def test_analyze_degrades_on_tiny_sets(n, converged):
    """No converged solutions, or too few for any hyperplane: every figure still draws, nothing is made up."""
    from amorgs.analysis.structure_report import analyze
    from amorgs.figures.structure import structure_figures
    from amorgs.layout import ANALYSIS_FIGURES
    from amorgs.problems.cr3bp.transcription import variable_names

    rng = np.random.default_rng(6)
    x = rng.uniform(0, 1, (n, 64)) * np.r_[40.0, 15.0, 15.0, 0.0, np.ones(60)] + np.r_[0, 0, 0, 420.0, np.zeros(60)]
    df = pd.DataFrame(x, columns=variable_names()).assign(alpha=1.0, converged=converged)
    result = analyze(df, df[df["converged"]], 415.0)
    figures = structure_figures(result)
    assert sorted(figures) == sorted(ANALYSIS_FIGURES)
    for fig in figures.values():
        fig.canvas.draw()
    assert result.tables["modes"].empty and result.tables["funnels"].empty
    if converged and n:
        assert result.metrics["n_modes/alpha_1.000"] == 0.0  # 2 solutions < min_members: no hyperplane
    else:
        assert "n_modes/alpha_1.000" not in result.metrics  # no converged solution at α = 1
    assert math.isnan(result.metrics["hyperplane_spacing"])
