"""Prediction metrics on constructed data with known answers; Figs. 17–20 draw, with and without data."""

from __future__ import annotations

import io
import math

import numpy as np
import pandas as pd
import pytest
from cr3bp_synthetic import synthetic_hq
from matplotlib.figure import Figure

from amorgs.analysis.hyperplanes import ModeParams
from amorgs.analysis.prediction import METRICS, prediction_metrics, prediction_table
from amorgs.figures.prediction import (
    fig17_time_predictions,
    fig18_data_fraction,
    fig19_final_mass,
    fig20_control_statistics,
)

MODES = (12.0, 18.0, 24.0)


def table(tof: np.ndarray, m_f: np.ndarray, alpha: float) -> pd.DataFrame:
    """Rows with the given TOF split 50/25/25 over τ_s, τ_i, τ_f, and the given m_f."""
    tof = np.asarray(tof, float)
    return pd.DataFrame({"alpha": alpha, "tau_s": 0.5 * tof, "tau_i": 0.25 * tof, "tau_f": 0.25 * tof,
                         "m_f": np.asarray(m_f, float)})


@pytest.fixture
def truth() -> pd.DataFrame:
    """20 solutions on each of three TOF planes (±0.05 TU), m_f evenly spread over 420–430 kg."""
    tof = np.concatenate([T + np.linspace(-0.05, 0.05, 20) for T in MODES])
    return table(tof, np.linspace(420, 430, tof.size), 0.15)


def test_a_pure_shift_is_measured_exactly(truth):
    tof = truth["tau_s"] + truth["tau_i"] + truth["tau_f"]
    m = prediction_metrics(table(tof + 0.1, truth["m_f"] - 2.0, 0.15), truth)
    assert m["tof_w1"] == pytest.approx(0.1) and m["m_f_w1"] == pytest.approx(2.0)
    assert m["n_modes"] == 3 and m["modes_covered"] == 3
    assert m["fraction_on_hyperplanes"] == 1.0 and m["truth_fraction_on_hyperplanes"] == 1.0
    assert (m["n_samples"], m["n_truth"]) == (60, 60)
    identical = prediction_metrics(truth, truth)
    assert identical["tof_w1"] == 0.0 and identical["m_f_w1"] == 0.0


def test_hyperplane_fraction_and_coverage(truth):
    # 10 samples on the 12 TU plane, 5 at 24.2 TU (within δ = 0.25 of 24), 25 at 15 TU (3 TU from the nearest
    # planes): fraction 15/40 and two of the three planes covered; with δ = 3 every sample is on a plane.
    tof = np.r_[np.full(10, 12.0), np.full(5, 24.2), np.full(25, 15.0)]
    m = prediction_metrics(table(tof, np.full(40, 425.0), 0.15), truth)
    assert m["fraction_on_hyperplanes"] == pytest.approx(15 / 40)
    assert m["modes_covered"] == 2
    assert m["m_f_w1"] == pytest.approx(2.5, abs=0.05)  # mean |x − 425| over a uniform 420–430 spread
    wide = prediction_metrics(table(tof, np.full(40, 425.0), 0.15), truth, ModeParams(delta=3.0))
    assert wide["fraction_on_hyperplanes"] == 1.0


def test_no_ground_truth_gives_nan_not_numbers(truth):
    m = prediction_metrics(truth, truth.iloc[:0])
    assert m["n_truth"] == 0 and m["n_samples"] == 60
    assert all(math.isnan(m[k]) for k in METRICS if k not in ("n_samples", "n_truth"))


def test_table_per_alpha_and_data_fraction(truth):
    tof = truth["tau_s"] + truth["tau_i"] + truth["tau_f"]
    samples = pd.concat([
        table(tof + 0.1, truth["m_f"], 0.1500001).assign(data_fraction=1.0),
        table(tof + 1.0, truth["m_f"], 0.15).assign(data_fraction=0.1),
        table(tof, truth["m_f"], 0.85).assign(data_fraction=1.0),
    ])
    t = prediction_table(samples, truth, by=("alpha", "data_fraction"))
    assert list(t.columns) == ["alpha", "data_fraction", *METRICS] and len(t) == 3
    by_key = {(r.alpha, r.data_fraction): r for r in t.itertuples()}  # α by label: 0.1500001 is 0.15
    assert by_key[(0.15, 1.0)].tof_w1 == pytest.approx(0.1) and by_key[(0.15, 1.0)].fraction_on_hyperplanes == 1.0
    assert by_key[(0.15, 0.1)].tof_w1 == pytest.approx(1.0) and by_key[(0.15, 0.1)].fraction_on_hyperplanes == 0.0
    assert by_key[(0.85, 1.0)].n_truth == 0 and math.isnan(by_key[(0.85, 1.0)].tof_w1)
    with pytest.raises(ValueError, match="alpha"):
        prediction_table(samples, truth, by=("data_fraction",))


# --------------------------------------------------------------------------------------------- figures
def texts(fig: Figure) -> str:
    fig.savefig(io.BytesIO(), format="png", dpi=40)  # renders every artist
    return " ".join(t.get_text() for ax in fig.axes for t in ax.texts)


@pytest.fixture
def data():
    """Samples at both test α; ground truth at α = 0.15 only."""
    s = pd.concat([synthetic_hq(60, alphas=(0.15,), seed=1), synthetic_hq(60, alphas=(0.85,), seed=2)])
    return s, synthetic_hq(40, alphas=(0.15,), seed=3)


def test_figures_return_figures_and_annotate_missing_truth(data):
    samples, truth = data
    figs = [
        fig17_time_predictions(samples, truth, [0.15, 0.85]),
        fig18_data_fraction({0.1: samples, 0.5: samples, 1.0: samples}, truth, [0.15, 0.85]),
        fig19_final_mass(samples, truth, [0.15, 0.85]),
        fig20_control_statistics({"LSTM": samples, "Ground truth": truth, "Uniform": samples}, [0.15, 0.85]),
    ]
    for fig in figs:
        assert isinstance(fig, Figure)
        note = texts(fig)
        assert "α = 0.85" in note and "α = 0.15" not in note
        assert "no ground truth at α = 0.85" in note or "no data at α = 0.85: Ground truth" in note


def test_figures_with_no_samples_or_no_alpha(data):
    samples, truth = data
    empty = samples.iloc[:0]
    assert "no samples at α = 0.15" in texts(fig17_time_predictions(empty, truth, [0.15]))
    assert "no samples at α = 0.15" in texts(fig18_data_fraction({1.0: empty}, truth, [0.15]))
    assert "no ground truth at α = 0.15" in texts(fig19_final_mass(samples, truth.iloc[:0], [0.15]))
    assert "no test α" in texts(fig20_control_statistics({"LSTM": samples}, []))
    ci = fig20_control_statistics({"LSTM": samples}, [0.15], interval="percentile")
    assert "percentile" in ci._suptitle.get_text()
