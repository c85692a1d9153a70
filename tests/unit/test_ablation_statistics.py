"""Ablation statistics on constructed tables with known answers."""

import math

import numpy as np
import pandas as pd
import pytest

from amorgs.ablation.statistics import capped_study, hyperplane_coverage, table6, time_cap, wilson_interval


def cell(sampler, times, hq_flags, tof=20.0, alpha=0.15):
    n = len(times)
    return pd.DataFrame(
        {
            "alpha": alpha,
            "sampler": sampler,
            "start": np.arange(n),
            "converged": np.array(hq_flags, bool),
            "m_f": np.where(hq_flags, 430.0, 300.0),
            "tau_s": np.full(n, tof - 2.0),
            "tau_i": np.ones(n),
            "tau_f": np.ones(n),
            "cpu_s": np.array(times, float),
        }
    )


@pytest.fixture
def ablation():
    # AmorGS: 3 of 4 HQ, fast; uniform: 1 of 4 HQ, slow.
    return pd.concat(
        [cell("amorgs", [1, 2, 3, 10], [1, 1, 1, 0]), cell("uniform", [8, 10, 10, 10], [1, 0, 0, 0], tof=25.0)]
    )


def test_table6(ablation):
    t = table6(ablation, beta_kg=415).set_index("sampler")
    assert t.loc["amorgs", "percent_high_quality"] == 75.0
    assert t.loc["uniform", "percent_high_quality"] == 25.0
    assert t.loc["amorgs", "time_median_s"] == 2.0 and t.loc["amorgs", "time_min_s"] == 1.0
    assert t.loc["amorgs", "ci95_low"] < 75.0 < t.loc["amorgs", "ci95_high"]


def test_capped_study_and_acceleration(ablation):
    assert time_cap(ablation, 415) == 2.0
    table, result = capped_study(ablation, 415, n_boot=200)
    t = table.set_index("sampler")
    # cap 2 s: amorgs finds 2 HQ for 1+2+2+2 = 7 s; uniform finds 0 for 8 s.
    assert t.loc["amorgs", "percent_within_cap"] == 50.0
    assert t.loc["amorgs", "hq_per_cpu_hour"] == pytest.approx(3600 * 2 / 7)
    assert result["acceleration"] == math.inf
    _, result = capped_study(ablation, 415, cap_s=10.0, n_boot=200)
    # cap 10: amorgs 3 HQ / 16 s, uniform 1 HQ / 38 s
    assert result["acceleration"] == pytest.approx((3 / 16) / (1 / 38))
    lo, hi = result["acceleration_ci95"]
    assert lo <= result["acceleration"] <= hi


def test_wilson_interval_bounds():
    lo, hi = wilson_interval(0, 10)
    assert lo == pytest.approx(0.0, abs=1e-9) and 0 < hi < 40
    assert wilson_interval(5, 0) == (math.nan, math.nan) or all(math.isnan(v) for v in wilson_interval(5, 0))


def test_hyperplane_coverage_equal_cpu(ablation):
    cov = hyperplane_coverage(ablation, 415, modes=np.array([20.0, 25.0, 31.0])).set_index("sampler")
    # equal budget = min(16, 38) = 16 s: amorgs uses all 4 starts (HQ at TOF 20), uniform only the first.
    assert cov.loc["amorgs", "hyperplanes_reached"] == 1
    assert cov.loc["uniform", "hyperplanes_reached"] == 1
    assert cov.loc["uniform", "hq_solutions"] == 1
    assert (cov["cpu_budget_s"] == 16.0).all()


def test_summarize_report(ablation):
    from amorgs.ablation.report import summarize, table6_markdown

    rng = np.random.default_rng(0)
    truth = pd.DataFrame({"alpha": 0.15, "tau_s": rng.normal(18, 0.05, 30), "tau_i": np.ones(30), "tau_f": np.ones(30),
                          "m_f": np.full(30, 430.0), "converged": True})
    ablation = ablation.assign(guess_tau_s=5.0, guess_tau_i=1.0, guess_tau_f=1.0, guess_m_f=400.0)
    metrics, tables, figures = summarize(ablation, truth, 415.0, n_boot=100)
    assert metrics["percent_hq_a0.150_amorgs"] == 75.0
    assert metrics["hyperplanes_ground_truth_a0.150"] == 1.0
    assert metrics["hyperplanes_reached_a0.150_amorgs"] == 1.0
    assert set(figures) == {"fig21_solve_time_histograms", "fig22_capped_convergence", "fig23_amorgs_diversity"}
    md = table6_markdown(tables["table6"])
    assert "| | Uniform | AmorGS |" in md and "| Percentage (%) | 25.0 | 75.0 |" in md
