"""The structure analysis (paper Sec. III.B) end to end on real CR3BP solver output.

Fast: ``tests/data/cr3bp_solutions_small.parquet`` — real converged solves (see ``tests/data/README.md`` for
how it was made).  Slow: a fresh six-start multistart at α = 1.0.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from matplotlib.figure import Figure

from amorgs.analysis.structure_report import StructureParams, analyze
from amorgs.data.filter import high_quality

FIXTURE = Path(__file__).resolve().parents[1] / "data" / "cr3bp_solutions_small.parquet"
BETA_KG = 415.0
FIGURES = (
    "fig03_time_hyperplanes", "fig04_tof_histograms", "fig05_hyperplane_filtering",
    "fig06_inplane_mass_contours", "fig07_moving_average_macro", "fig08_moving_average_micro",
    "fig09_trajectories_across_hyperplanes", "fig10_trajectories_within_hyperplane", "fig11_funnels",
    "fig12_funnels", "fig13_control_statistics",
)
TABLES = ("modes", "funnels", "control_statistics", "moving_average", "diversity", "diverse_subset", "trajectories")


def _check(metrics: dict, tables: dict, figures: dict, df: pd.DataFrame) -> None:
    assert set(FIGURES) <= set(figures) and all(isinstance(f, Figure) for f in figures.values())
    assert set(TABLES) <= set(tables)
    assert all(isinstance(v, float) for v in metrics.values())
    for name, fig in figures.items():  # every figure renders
        fig.canvas.draw()
    converged = df[df["converged"]]
    assert metrics["n_converged"] == len(converged)
    for a in converged["alpha"].unique():
        assert f"n_modes_alpha_{a:g}" in metrics
    # Every detected mode has ≥ min_members converged solutions within δ (Eq. 32).
    assert (tables["modes"]["n_converged"] >= StructureParams().modes.min_members).all()


@pytest.mark.skipif(not FIXTURE.is_file(), reason="fixture of real solves not present")
def test_analyze_on_committed_real_solutions():
    df = pd.read_parquet(FIXTURE)
    hq = high_quality(df, min_final_mass_kg=BETA_KG)
    metrics, tables, figures = analyze(df, hq, BETA_KG, StructureParams(n_trajectories=2))
    _check(metrics, tables, figures, df)
    assert metrics["n_modes_alpha_1"] >= 2
    assert 0 < metrics["hyperplane_spacing_alpha_1"] < 40
    f = tables["funnels"]
    if len(f):
        on_first = tables["modes"].query("alpha == @metrics['focus_alpha'] and tof == @metrics['funnel_plane_1_tof']")
        assert f.loc[f["plane_tof"] == metrics["funnel_plane_1_tof"], "count"].sum() == on_first[
            "n_high_quality"].iloc[0]
    d = tables["diversity"]
    assert (d["diverse_size"] <= d["n_high_quality"]).all() and (d["diverse_size"] >= 1).all()


@pytest.mark.slow
def test_analyze_on_fresh_multistart():
    from amorgs.solvers.multistart import run_multistart

    df = run_multistart("cr3bp", 1.0, 7, 6, workers=1, progress=False)
    hq = high_quality(df, min_final_mass_kg=BETA_KG)
    metrics, tables, figures = analyze(df, hq, BETA_KG, StructureParams(n_trajectories=1))
    _check(metrics, tables, figures, df)
    assert metrics["focus_alpha"] == 1.0 or math.isnan(metrics["focus_alpha"])
    assert np.isfinite(metrics["n_modes_alpha_1"]) if df["converged"].any() else True
