"""The structure analysis (paper Sec. III.B) end to end on real CR3BP solver output.

Fast: ``tests/data/cr3bp_solutions_small.parquet`` — real converged solves (see ``tests/data/README.md`` for
how it was made).  Slow: a fresh six-start multistart at α = 1.0.
"""

from __future__ import annotations

import math
from pathlib import Path

import pandas as pd
import pytest
from matplotlib.figure import Figure

from amorgs.alphas import alpha_label, distinct_alphas, metric_key, rows_at
from amorgs.analysis.structure_report import StructureParams, StructureResult, analyze
from amorgs.figures.structure import structure_figures
from amorgs.layout import ANALYSIS_FIGURES, ANALYSIS_TABLES
from amorgs.problems.cr3bp import Cr3bpFilter

FIXTURE = Path(__file__).resolve().parents[1] / "data" / "cr3bp_solutions_small.parquet"
BETA_KG = 415.0


def _check(result: StructureResult, df: pd.DataFrame) -> None:
    """What holds for any solution set: declared tables and figures, counts, one mode entry per α."""
    metrics, tables = result.metrics, result.tables
    assert sorted(tables) == sorted(ANALYSIS_TABLES)
    figures = structure_figures(result)
    assert sorted(figures) == sorted(ANALYSIS_FIGURES)
    for fig in figures.values():  # every figure renders
        assert isinstance(fig, Figure)
        fig.canvas.draw()
    assert all(isinstance(v, float) for v in metrics.values())
    converged = df[df["converged"]]
    assert metrics["n_converged"] == len(converged)
    for a in distinct_alphas(converged["alpha"]):
        assert metrics[metric_key("n_converged", a)] == len(rows_at(converged, a))
        assert metrics[metric_key("n_modes", a)] == len(rows_at(tables["modes"], a)) == len(result.modes[a])
    # Every detected mode has ≥ min_members converged solutions within δ (Eq. 32).
    assert (tables["modes"]["n_converged"] >= result.params.modes.min_members).all()


@pytest.mark.skipif(not FIXTURE.is_file(), reason="fixture of real solves not present")
def test_analyze_on_committed_real_solutions():
    df = pd.read_parquet(FIXTURE)
    hq = Cr3bpFilter(min_final_mass_kg=BETA_KG).select(df)
    result = analyze(df, hq, BETA_KG, StructureParams(n_trajectories=2))
    _check(result, df)
    metrics, tables = result.metrics, result.tables
    # Data at α = 0.1, 0.5, 1.0: the paper's Fig. 3 choice (0.1, 0.3, 1.0) becomes the nearest untaken α.
    assert result.shown_alphas == [0.1, 0.5, 1.0]
    assert metrics["focus_alpha"] == 1.0
    assert metrics[metric_key("n_modes", 1.0)] >= 2
    assert 0 < metrics[metric_key("hyperplane_spacing", 1.0)] < 40
    # Tables 1–2: each funnel plane's funnels share out exactly its β-filtered solutions on that mode.
    f, modes = tables["funnels"], rows_at(tables["modes"], 1.0)
    assert len(result.funnel_planes) == 2
    for j, (plane, T) in enumerate(result.funnel_planes, start=1):
        assert metrics[f"funnel_plane_{j}_tof"] == T
        assert metrics[f"funnels_plane_{j}"] == f.loc[f["plane_tof"] == T, "funnel"].nunique() >= 1
        on_mode = modes.loc[(modes["tof"] - T).abs() < 1e-9, "n_high_quality"]
        assert f.loc[f["plane_tof"] == T, "count"].sum() == on_mode.iloc[0] == len(plane)
    # Figs. 9–10: the requested number of transfers, each from the β-filtered set on a hyperplane.
    assert len(result.paths_across) == len(result.paths_within) == 2
    assert all(p.m_f >= BETA_KG and alpha_label(p.alpha) == "1.000" for p in result.paths_across)
    d = tables["diversity"]
    assert (d["diverse_size"] <= d["n_high_quality"]).all() and (d["diverse_size"] >= 1).all()
    assert d["n_high_quality"].sum() == len(hq)


@pytest.mark.slow
def test_analyze_on_fresh_multistart():
    from amorgs.problems import get_problem
    from amorgs.solvers.multistart import run_multistart

    df = run_multistart(get_problem("cr3bp"), 1.0, 7, 6, workers=1, progress=False)
    hq = Cr3bpFilter(min_final_mass_kg=BETA_KG).select(df)
    result = analyze(df, hq, BETA_KG, StructureParams(n_trajectories=1))
    _check(result, df)
    if df["converged"].any():
        assert result.metrics["focus_alpha"] == 1.0
        assert result.metrics[metric_key("n_modes", 1.0)] == len(result.modes[1.0])
    else:  # nothing converged: no focus α and no per-α metric is made up
        assert math.isnan(result.metrics["focus_alpha"])
        assert metric_key("n_modes", 1.0) not in result.metrics
