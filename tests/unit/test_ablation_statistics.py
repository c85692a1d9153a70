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
            "iterations": 100 * np.array(times, float),
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
    assert all(math.isnan(v) for v in wilson_interval(5, 0))


def test_hyperplane_coverage_equal_cpu(ablation):
    cov = hyperplane_coverage(ablation, 415, modes=np.array([20.0, 25.0, 31.0])).set_index("sampler")
    # equal budget = min(16, 38) = 16 s: amorgs uses all 4 starts (HQ at TOF 20), uniform only the first.
    assert cov.loc["amorgs", "hyperplanes_reached"] == 1
    assert cov.loc["uniform", "hyperplanes_reached"] == 1
    assert cov.loc["uniform", "hq_solutions"] == 1
    assert (cov["cpu_budget_s"] == 16.0).all()


def test_summarize_report(ablation):
    from amorgs.ablation.report import summarize, table6_markdown
    from amorgs.figures.ablation import ablation_figures
    from amorgs.layout import ABLATION_FIGURES

    rng = np.random.default_rng(0)
    truth = pd.DataFrame({"alpha": 0.15, "tau_s": rng.normal(18, 0.05, 30), "tau_i": np.ones(30), "tau_f": np.ones(30),
                          "m_f": np.full(30, 430.0), "converged": True})
    ablation = ablation.assign(guess_tau_s=5.0, guess_tau_i=1.0, guess_tau_f=1.0, guess_m_f=400.0)
    # the truth also holds rows at another α and an α written with float noise (same label, same α)
    truth = pd.concat([truth, truth.assign(alpha=0.5)]).assign(alpha=lambda d: d["alpha"] + 1e-9)
    summary = summarize(ablation, truth, 415.0, n_boot=100, beta_sweep=(425.0, 435.0),
                        iteration_caps=(200, 1000), max_iter=1000)
    metrics, tables = summary.metrics, summary.tables
    assert metrics["percent_hq/alpha_0.150/amorgs"] == 75.0
    assert metrics["hyperplanes_ground_truth/alpha_0.150"] == 1.0
    assert metrics["hyperplanes_reached/alpha_0.150/amorgs"] == 1.0
    # amorgs 3 HQ in 1600 iterations, uniform 1 in 3800: speed-up (3800/1) / (1600/3)
    assert metrics["aRT_iterations/alpha_0.150/amorgs"] == pytest.approx(1600 / 3)
    assert metrics["speedup_iterations/alpha_0.150/amorgs"] == pytest.approx(3800 / (1600 / 3))
    assert metrics["rate_percent/alpha_0.150/amorgs"] == 75.0
    assert metrics["rate_percent/alpha_0.150/amorgs/beta_435"] == 0.0  # every solve has m_f ≤ 430 kg < 435 kg
    assert metrics["itcap_percent/alpha_0.150/amorgs/cap_200"] == 50.0  # the 100- and 200-iteration solves
    assert set(tables["beta_sweep"]["beta_kg"]) == {415.0, 425.0, 435.0}
    assert metrics["best_m_f/alpha_0.150/amorgs"] == 430.0
    assert summary.solves["high_quality"].sum() == 3 + 1
    assert len(summary.ground_truth) == 30  # the α = 0.5 rows are not ground truth of α = 0.15
    figures = ablation_figures(summary)
    assert sorted(figures) == sorted(ABLATION_FIGURES)
    for fig in figures.values():
        fig.canvas.draw()
    md = table6_markdown(tables["table6"])
    assert "| | Uniform | AmorGS |" in md and "| Percentage (%) | 25.0 | 75.0 |" in md
    # one table per record of the study table, and the rates are the β sweep's rows at β
    from amorgs.ablation.studies import STUDIES, table_files

    assert list(tables) == [study.name for study in STUDIES]
    at_beta = tables["beta_sweep"][tables["beta_sweep"]["beta_kg"] == 415.0].reset_index(drop=True)
    pd.testing.assert_frame_equal(tables["rates"], at_beta)
    files = table_files()
    assert len(set(files)) == len(files) and "table6.md" in files and "ablation_anytime.md" not in files


# ----------------------------------------------------------------- issue 11: statistics at modest n


def arm(sampler, iterations, hq_flags, m_f=None, alpha=0.15, tau_s=None, cpu_per_iteration=0.01):
    n = len(iterations)
    hq = np.array(hq_flags, bool)
    return pd.DataFrame({
        "alpha": alpha, "sampler": sampler, "start": np.arange(n), "converged": hq,
        "m_f": np.where(hq, 430.0, 300.0) if m_f is None else np.asarray(m_f, float),
        "tau_s": np.full(n, 18.0) if tau_s is None else np.asarray(tau_s, float),
        "tau_i": np.ones(n), "tau_f": np.ones(n),
        "iterations": np.asarray(iterations, float), "cpu_s": cpu_per_iteration * np.asarray(iterations, float),
    })


@pytest.fixture
def three_arms():
    # uniform: 2 HQ of 6, 1000 iterations total; nearest: 6 of 6 in 30 each; amorgs: 3 of 6, 600 in total
    return pd.concat([
        arm("uniform", [100, 300, 150, 150, 150, 150], [1, 1, 0, 0, 0, 0]),
        arm("nearest_alpha", [30] * 6, [1] * 6),
        arm("amorgs", [50, 50, 200, 100, 100, 100], [1, 1, 1, 0, 0, 0]),
    ], ignore_index=True)


def test_fisher_and_rates(three_arms):
    from scipy.stats import fisher_exact

    from amorgs.ablation.statistics import fisher_greater, rates

    assert fisher_greater(6, 6, 2, 6) == pytest.approx(fisher_exact([[6, 0], [2, 4]], alternative="greater")[1])
    assert fisher_greater(2, 6, 6, 6) == pytest.approx(1.0)  # "lower" is never evidence of "higher"
    r = rates(three_arms, [415.0]).set_index("sampler")
    assert r.loc["nearest_alpha", "percent"] == 100.0 and r.loc["nearest_alpha", "k_high_quality"] == 6
    assert r.loc["nearest_alpha", "p_gt_uniform"] == pytest.approx(fisher_greater(6, 6, 2, 6))
    assert r.loc["amorgs", "p_gt_nearest_alpha"] == pytest.approx(1.0)
    # the reverse one-sided test: AmorGS (3 of 6) lower than reuse (6 of 6)
    assert r.loc["amorgs", "p_lt_nearest_alpha"] == pytest.approx(fisher_greater(6, 6, 3, 6))
    assert r.loc["amorgs", "p_lt_nearest_alpha"] < 0.1 and math.isnan(r.loc["nearest_alpha", "p_lt_nearest_alpha"])
    assert math.isnan(r.loc["uniform", "p_gt_uniform"])
    assert r.loc["amorgs", "ci95_low"] < 50.0 < r.loc["amorgs", "ci95_high"]


def test_beta_sweep_is_monotone_in_beta():
    from amorgs.ablation.statistics import rates

    df = arm("amorgs", [10] * 4, [1, 1, 1, 1], m_f=[416.0, 426.0, 431.0, 440.0])
    sweep = rates(df, [415, 425, 430, 435]).set_index("beta_kg")
    assert sweep["k_high_quality"].tolist() == [4, 3, 2, 1]


def test_expected_running_time_and_speedups(three_arms):
    from amorgs.ablation.running_time import expected_running_time

    ert = expected_running_time(three_arms, 415.0, n_boot=500, seed=1)
    it = ert[ert["unit"] == "iterations"].set_index("sampler")
    assert it.loc["uniform", "aRT"] == pytest.approx(1000 / 2)
    assert it.loc["nearest_alpha", "aRT"] == pytest.approx(180 / 6)
    assert it.loc["amorgs", "aRT"] == pytest.approx(600 / 3)
    assert it.loc["nearest_alpha", "speedup"] == pytest.approx(500 / 30)
    assert it.loc["uniform", "speedup"] == pytest.approx(1.0)
    lo, hi = it.loc["amorgs", ["speedup_ci95_low", "speedup_ci95_high"]]
    assert lo <= 2.5 <= hi and lo < hi
    # against reuse: AmorGS needs 200 iterations per HQ solution where nearest_alpha needs 30
    assert it.loc["amorgs", "versus_reuse"] == pytest.approx(30 / 200)
    assert it.loc["nearest_alpha", "versus_reuse"] == pytest.approx(1.0)
    lo, hi = it.loc["amorgs", ["versus_reuse_ci95_low", "versus_reuse_ci95_high"]]
    assert lo <= 0.15 <= hi < 1  # reuse is faster, and the interval says so
    no_reuse = expected_running_time(three_arms, 415.0, reuse="absent", n_boot=500, seed=1)
    assert no_reuse["versus_reuse"].isna().all()  # no such arm: nothing to compare against
    speedups = ["speedup", "speedup_ci95_low", "speedup_ci95_high"]
    pd.testing.assert_frame_equal(no_reuse[speedups], ert[speedups])  # the reuse bootstrap has its own stream
    cpu = ert[ert["unit"] == "cpu_s"].set_index("sampler")
    assert cpu.loc["amorgs", "aRT"] == pytest.approx(600 * 0.01 / 3)  # 0.01 s per iteration
    again = expected_running_time(three_arms, 415.0, n_boot=500, seed=1)
    pd.testing.assert_frame_equal(ert, again)  # seeded bootstrap


def test_learning_curve_compares_each_fraction_with_uniform_and_reuse(three_arms):
    from amorgs.ablation.running_time import expected_running_time, learning_curve

    # AmorGS with models that saw 10 % of the data: 1 HQ of 6 in 600 iterations
    partial = arm("amorgs", [100] * 6, [1, 0, 0, 0, 0, 0]).assign(data_fraction=0.1)
    curve = learning_curve(three_arms, partial, 415.0, n_boot=300, seed=4)
    it = curve[curve["unit"] == "iterations"].set_index("data_fraction")
    assert list(it.index) == [0.1, 1.0] and set(it["sampler"]) == {"amorgs"}
    assert it.loc[0.1, "aRT"] == pytest.approx(600) and it.loc[1.0, "aRT"] == pytest.approx(200)
    assert it.loc[0.1, "speedup"] == pytest.approx(500 / 600)
    assert it.loc[0.1, "versus_reuse"] == pytest.approx(30 / 600)
    # fraction 1 is the full-data cells with the same bootstrap as the main aRT table
    full = expected_running_time(three_arms, 415.0, n_boot=300, seed=4).query("unit == 'iterations'")
    row = full.set_index("sampler").loc["amorgs"]
    for column in ("speedup_ci95_low", "speedup_ci95_high", "versus_reuse_ci95_low", "versus_reuse_ci95_high"):
        assert it.loc[1.0, column] == pytest.approx(row[column]), column


def test_seed_spread_per_model_seed(three_arms):
    from amorgs.ablation.running_time import seed_spread

    assert seed_spread(three_arms, 415.0).empty  # one seed: nothing to spread
    two = pd.concat([three_arms.assign(model_seed=11), three_arms.assign(model_seed=12)], ignore_index=True)
    two.loc[(two["model_seed"] == 12) & (two["sampler"] == "amorgs"), ["converged", "m_f"]] = [True, 430.0]
    t = seed_spread(two, 415.0).set_index(["sampler", "model_seed"])
    assert len(t) == 6 and (t["n"] == 6).all()
    assert t.loc[("amorgs", 11), "k_high_quality"] == 3 and t.loc[("amorgs", 12), "k_high_quality"] == 6
    assert t.loc[("amorgs", 11), "aRT_iterations"] == pytest.approx(200)
    assert t.loc[("amorgs", 12), "aRT_iterations"] == pytest.approx(100)
    lo, hi = t.loc[("uniform", 11), ["ci95_low", "ci95_high"]]
    assert lo < 100 * 2 / 6 < hi


def test_expected_running_time_when_nothing_found():
    from amorgs.ablation.running_time import expected_running_time

    df = pd.concat([arm("uniform", [100, 100], [0, 0]), arm("amorgs", [10, 10], [1, 0])])
    it = expected_running_time(df, 415.0, n_boot=100).query("unit == 'iterations'").set_index("sampler")
    assert it.loc["uniform", "aRT"] == math.inf and it.loc["amorgs", "speedup"] == math.inf
    assert math.isnan(it.loc["amorgs", "versus_reuse"])  # no nearest_alpha arm in this table


def test_iteration_capped_is_a_real_cap(three_arms):
    from amorgs.ablation.running_time import iteration_capped

    t = iteration_capped(three_arms, 415.0, caps=[100, 1000], max_iter=1000)
    c100 = t[t["cap_iterations"] == 100].set_index("sampler")
    # cap 100: uniform keeps the 100-iteration HQ solve only (the 300 one is cut), spends 100 × 6
    assert c100.loc["uniform", "k_within_cap"] == 1
    assert c100.loc["uniform", "iterations_spent"] == 600
    # amorgs: 50, 50 in; the 200 one is charged 100 and fails; spends 50+50+100+100+100+100
    assert c100.loc["amorgs", "k_within_cap"] == 2 and c100.loc["amorgs", "iterations_spent"] == 500
    assert c100.loc["amorgs", "percent_ratio"] == pytest.approx(2.0)
    assert c100.loc["amorgs", "throughput_ratio"] == pytest.approx((2 / 500) / (1 / 600))
    c1000 = t[t["cap_iterations"] == 1000].set_index("sampler")
    assert c1000.loc["uniform", "k_within_cap"] == 2
    with pytest.raises(ValueError, match="max_iter"):
        iteration_capped(three_arms, 415.0, caps=[2000], max_iter=1000)


def test_anytime_curves():
    from amorgs.ablation.running_time import anytime_curves

    # HQ at starts 0, 2, 3; start 3 repeats start 0's times (not a new optimum), start 2 is 4 TU away (new)
    df = arm("amorgs", [10, 20, 30, 40], [1, 0, 1, 1], m_f=[420.0, 300.0, 433.0, 425.0], tau_s=[18, 18, 22, 18])
    c = anytime_curves(df, 415.0, eta=0.02)
    assert c["iterations_cumulative"].tolist() == [10, 30, 60, 100]
    assert c["best_m_f"].tolist() == [420.0, 420.0, 433.0, 433.0]
    assert c["distinct_optima"].tolist() == [1, 1, 2, 2]
    assert np.all(np.diff(c["cpu_s_cumulative"]) > 0)


def test_fig22_iteration_capped_draws_when_no_ratio_is_defined():
    """The smoke run's 50-iteration caps can leave uniform without a single high-quality start: every
    ratio is undefined and nothing is plotted, yet the figure must still draw (log x axis, fixed limits)."""
    from amorgs.figures.ablation import fig22_iteration_capped

    capped = pd.DataFrame({"alpha": 0.15, "sampler": ["uniform", "amorgs"] * 2, "cap_iterations": [10, 10, 50, 50],
                           "n": 2, "percent_ratio": np.nan, "throughput_ratio": np.nan})
    fig = fig22_iteration_capped(capped)
    fig.canvas.draw()
    assert fig.axes[0].get_xlim()[0] == pytest.approx(10 / 1.3)


def test_break_even_is_upfront_over_the_saving_per_alpha():
    from amorgs.ablation.running_time import break_even

    # uniform: 600 iterations × 0.01 s for 1 HQ → 6 s per HQ; reuse: 40 iterations for 2 HQ → 0.2 s per HQ
    df = pd.concat([arm("uniform", [100, 200, 300], [1, 0, 0]), arm("nearest_alpha", [10, 10, 20], [1, 1, 0]),
                    arm("amorgs", [500, 500], [0, 0])])
    upfront = {"nearest_alpha": 58.0, "amorgs": 1000.0}
    t = break_even(df, 415.0, upfront, (10, 100), n_boot=200, seed=1).set_index(["sampler", "solutions_wanted"])
    row = t.loc[("nearest_alpha", 10)]
    assert row["saving_cpu_s_per_solution"] == pytest.approx(6.0 - 0.2)
    assert row["break_even_new_alphas"] == pytest.approx(58.0 / (10 * 5.8))  # = 1 new α
    assert t.loc[("nearest_alpha", 100), "break_even_new_alphas"] == pytest.approx(0.1)
    assert row["ci95_low"] <= row["break_even_new_alphas"] <= row["ci95_high"]
    assert t.loc[("amorgs", 10), "break_even_new_alphas"] == math.inf  # it found nothing: it never repays
    assert "uniform" not in t.index.get_level_values(0)
    assert t.loc[("nearest_alpha", 10), "upfront_cpu_h"] == pytest.approx(58.0 / 3600)


# ----------------------------------------------------------------- issue 21: what a designer wants


def test_first_come_diverse_keeps_new_optima_in_order():
    from amorgs.analysis.diversity import conflicts, first_come_diverse, is_eta_diverse

    # four solutions on a line: 0 and 1 are 0.01 apart (one optimum at η = 0.02), 2 and 3 far from both
    feats = np.array([[0.0], [0.01], [0.5], [1.0]])
    close = conflicts(feats, 0.02)
    assert first_come_diverse(close, np.array([0, 1, 2, 3])).tolist() == [True, False, True, True]
    assert first_come_diverse(close, np.array([1, 0, 0, -1, 3])).tolist() == [True, False, False, False, True]
    # resamples, one per row: a repeat is never new, a start without a solution (-1) neither
    both = first_come_diverse(close, np.array([[2, 2, 1], [3, -1, 0]]))
    assert both.tolist() == [[True, False, True], [True, False, True]]
    kept = np.flatnonzero(first_come_diverse(close, np.arange(4)))
    assert is_eta_diverse(feats, kept, 0.02)


def test_expected_running_time_per_distinct_optimum():
    from amorgs.ablation.running_time import expected_running_time

    # reuse: 4 HQ of 4 starts, but starts 1 and 3 land where 0 did (a repeated pool row): 2 distinct optima;
    # amorgs: 2 HQ of 4, both distinct; uniform: 1 HQ
    df = pd.concat([
        arm("nearest_alpha", [10, 10, 10, 10], [1, 1, 1, 1], tau_s=[18.0, 18.0, 26.0, 18.0]),
        arm("amorgs", [20, 20, 20, 20], [1, 0, 1, 0], tau_s=[18.0, 30.0, 26.0, 22.0]),
        arm("uniform", [50, 50, 50, 50], [0, 0, 1, 0]),
    ], ignore_index=True)
    ert = expected_running_time(df, 415.0, n_boot=400, seed=3, target="distinct", eta=0.02)
    it = ert[ert["unit"] == "iterations"].set_index("sampler")
    assert it.loc["nearest_alpha", "k_high_quality"] == 4 and it.loc["nearest_alpha", "k_distinct"] == 2
    assert it.loc["nearest_alpha", "aRT"] == pytest.approx(40 / 2)
    assert it.loc["amorgs", "aRT"] == pytest.approx(80 / 2)
    assert it.loc["amorgs", "versus_reuse"] == pytest.approx(20 / 40)
    assert it.loc["amorgs", "speedup"] == pytest.approx(200 / 40)
    lo, hi = it.loc["amorgs", ["versus_reuse_ci95_low", "versus_reuse_ci95_high"]]
    assert lo <= 0.5 <= hi
    assert (it["eta"] == 0.02).all()
    # per high-quality solution reuse looks twice as good as per distinct optimum
    per_hq = expected_running_time(df, 415.0, n_boot=400, seed=3).query("unit == 'iterations'").set_index("sampler")
    assert per_hq.loc["nearest_alpha", "aRT"] == pytest.approx(40 / 4)
    again = expected_running_time(df, 415.0, n_boot=400, seed=3, target="distinct", eta=0.02)
    pd.testing.assert_frame_equal(ert, again)  # seeded
    with pytest.raises(ValueError, match="target"):
        expected_running_time(df, 415.0, target="best")


def test_the_interval_per_distinct_optimum_brackets_its_estimate():
    from amorgs.ablation.running_time import art_interval, expected_running_time

    # 100 starts landing in 40 basins (τ_s 1 TU apart, far beyond η): a resample holds ≈ 63 of the starts, so
    # recounting the distinct optima per resample found ≈ 30 % fewer and put the whole interval above the aRT
    rng = np.random.default_rng(5)
    df = arm("amorgs", rng.integers(50, 150, 100), np.ones(100), tau_s=rng.integers(0, 40, 100).astype(float))
    ert = expected_running_time(df, 415.0, n_boot=400, seed=1, target="distinct").query("unit == 'iterations'")
    lo, hi = art_interval(df, 415.0, n_boot=400, seed=1, target="distinct")[("amorgs", "iterations")]
    assert lo < float(ert["aRT"].iloc[0]) < hi


def test_reuse_pools_say_how_the_reuse_arm_drew():
    from amorgs.ablation.statistics import reuse_pools

    assert reuse_pools(arm("uniform", [10], [1])).empty
    # two model seeds' cells of 3 starts, slices 0–2 and 3–5 of one draw from a pool of 4 rows
    small = pd.concat([arm("nearest_alpha", [10] * 3, [1] * 3).assign(model_seed=11),
                       arm("nearest_alpha", [10] * 3, [1] * 3).assign(model_seed=12, start=[3, 4, 5])])
    small = small.assign(reuse_alpha=0.16, reuse_pool_size=4)
    large = arm("nearest_alpha_perturbed", [10] * 2, [1] * 2).assign(reuse_alpha=0.16, reuse_pool_size=3,
                                                                     model_seed=11)
    t = reuse_pools(pd.concat([small, large, arm("uniform", [10], [1])], ignore_index=True)).set_index("sampler")
    assert list(t.index) == ["nearest_alpha", "nearest_alpha_perturbed"]
    assert t.loc["nearest_alpha", "pool_size"] == 4 and t.loc["nearest_alpha", "cells"] == 2
    assert t.loc["nearest_alpha", "n"] == 6 and t.loc["nearest_alpha", "starts_with_replacement"] == 2
    assert t.loc["nearest_alpha", "starts_without_replacement"] == 4 and "then with replacement" in t.loc[
        "nearest_alpha", "draw"]
    assert t.loc["nearest_alpha_perturbed", "draw"] == "without replacement"


def test_anytime_bands_bracket_the_curve():
    from amorgs.ablation.running_time import anytime_bands

    df = arm("amorgs", [10, 20, 30, 40], [1, 0, 1, 1], m_f=[420.0, 300.0, 433.0, 425.0], tau_s=[18, 18, 22, 30])
    b = anytime_bands(df, 415.0, eta=0.02, n_boot=300, seed=1, points=11)
    assert set(b["unit"]) == {"iterations", "cpu_s"} and set(b["measure"]) == {"best_m_f", "distinct_optima"}
    d = b[(b["unit"] == "iterations") & (b["measure"] == "distinct_optima")]
    assert d["budget"].tolist() == pytest.approx(np.linspace(0, 100, 11))
    assert d["low"].iloc[0] == 0 and (d["low"] <= d["median"]).all() and (d["median"] <= d["high"]).all()
    assert d["high"].iloc[-1] <= 4 and d["high"].iloc[-1] >= 3
    m = b[(b["unit"] == "iterations") & (b["measure"] == "best_m_f")]
    assert m["high"].max() == pytest.approx(433.0) and np.isnan(m["low"].iloc[0])  # nothing found at budget 0
    pd.testing.assert_frame_equal(b, anytime_bands(df, 415.0, eta=0.02, n_boot=300, seed=1, points=11))


def test_iteration_capped_ratio_intervals(three_arms):
    from amorgs.ablation.statistics import ratio_of_rates_interval
    from amorgs.ablation.running_time import iteration_capped

    t = iteration_capped(three_arms, 415.0, caps=[100, 1000], max_iter=1000, n_boot=300, seed=2)
    row = t[(t["cap_iterations"] == 1000) & (t["sampler"] == "amorgs")].iloc[0]
    assert (row["percent_ratio_ci95_low"], row["percent_ratio_ci95_high"]) == pytest.approx(
        ratio_of_rates_interval(3, 6, 2, 6))
    assert row["percent_ratio"] == pytest.approx(1.5)
    assert row["percent_ratio_ci95_low"] < 1.5 < row["percent_ratio_ci95_high"]
    assert row["throughput_ratio_ci95_low"] <= row["throughput_ratio"] <= row["throughput_ratio_ci95_high"]
    assert all(math.isnan(v) for v in ratio_of_rates_interval(0, 6, 2, 6))


def test_ablation_figures_label_and_bound_what_they_plot(ablation):
    """Fig. 21's density axes are labelled; Fig. 22 says it plots the high-quality rate and draws intervals;
    the anytime curves have bands; Fig. 23's panels share one colour range."""
    from matplotlib.collections import LineCollection, PathCollection, PolyCollection

    from amorgs.ablation.report import summarize
    from amorgs.figures.ablation import ablation_figures

    truth = ablation[ablation["converged"]].assign(m_f=[425.0, 431.0, 436.0, 433.0])
    cells = ablation.assign(guess_tau_s=5.0, guess_tau_i=1.0, guess_tau_f=1.0, guess_m_f=[300.0, 500.0] * 4)
    summary = summarize(cells, truth, 415.0, n_boot=50, iteration_caps=(200, 1000), max_iter=1000)
    figures = ablation_figures(summary)
    for ax in figures["fig21_solve_time_histograms"].axes:
        assert "density" in ax.get_ylabel()
    fig22 = figures["fig22_capped_convergence"].axes[0]
    assert "high-quality rate" in fig22.get_ylabel() and "converged within" not in fig22.get_ylabel()
    assert len(fig22.containers) >= 2  # the bars and their error bars
    capped = summary.tables["capped"].set_index("sampler")
    assert (capped["ci95_low"] <= capped["percent_within_cap"]).all()
    assert (capped["percent_within_cap"] <= capped["ci95_high"]).all()
    itcap = figures["fig22_iteration_capped"].axes
    assert "high-quality rate" in itcap[0].get_ylabel()
    assert all(any(isinstance(c, LineCollection) for c in ax.collections) for ax in itcap[:3])  # intervals
    anytime = figures["ablation_anytime"].axes
    assert len(anytime) == 4 and all(any(isinstance(c, PolyCollection) for c in ax.collections) for ax in anytime)
    assert "η-distinct" in anytime[2].get_ylabel()
    fig23 = figures["fig23_amorgs_diversity"]
    scatters = [c for ax in fig23.axes for c in ax.collections if isinstance(c, PathCollection)]
    assert len(scatters) == 3  # samples, solutions, ground truth
    assert {(c.norm.vmin, c.norm.vmax) for c in scatters} == {(425.0, 436.0)}  # the solutions' and truth's m_f
    for fig in figures.values():
        fig.canvas.draw()


def test_speedup_figure_compares_with_reuse_per_distinct_optimum(three_arms):
    from amorgs.ablation.running_time import expected_running_time
    from amorgs.figures.ablation import ablation_speedups

    ert = expected_running_time(three_arms, 415.0, n_boot=50)
    distinct = expected_running_time(three_arms, 415.0, n_boot=50, target="distinct")
    labels = [ax.get_ylabel() for ax in ablation_speedups(ert, distinct).axes]
    assert len(labels) == 4 and any("η-distinct" in label and "reuse" in label for label in labels)
    assert len(ablation_speedups(ert, distinct.iloc[0:0]).axes) == 3  # no distinct table: the row is left out
