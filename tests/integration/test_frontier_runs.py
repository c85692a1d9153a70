"""The frontier end to end around the workflow: fold directories from `amorgs frontier-plan`, the `amorgs
frontier` aggregation of their cell tables (real solves of the committed library) into a table, a figure and
one run in a real MLflow SQLite store; and the real ablation_cell step of a leave-one-out fold, solving with
IPOPT, never reusing its test α."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from amorgs import cli, steps, tracking
from amorgs.ablation.frontier import gap
from amorgs.ablation.statistics import high_quality
from amorgs.alphas import alpha_label, rows_at
from amorgs.config import load_config
from amorgs.data.library import read_library
from amorgs.frontier import plan

ROOT = Path(__file__).resolve().parents[2]
LIBRARY = ROOT / "data" / "library"
BASE = ROOT / "config" / "frontier.yaml"


def _finish(run: Path, solves: pd.DataFrame) -> None:
    """Write every cell table the fold's config declares, made of real library solves at the cell's α (the
    reuse arm marked with the nearest training α) — a finished fold, as far as the aggregation reads it."""
    cfg = load_config(run / "config.yaml")
    used: dict[str, int] = {}
    for rule in ("ablation_cell", "ablation_cell_replicate"):
        for w in steps.registry()[rule].jobs(cfg):
            n = cfg.ablation.n_starts
            at = rows_at(solves, w["alpha"]).reset_index(drop=True)
            first = used.get(w["alpha"], 0)
            cell = at.iloc[first:first + n].assign(sampler=w["sampler"], start=np.arange(n),
                                                  model_seed=int(w.get("mseed", cfg.cr3bp_models.seed)))
            used[w["alpha"]] = first + n
            if w["sampler"] == "nearest_alpha":
                cell["reuse_alpha"] = gap(float(w["alpha"]), cfg.problems.cr3bp.alphas.train_values())[0]
                cell["reuse_pool_size"] = 100
            path = run / steps.registry()[rule].outputs(w)["table"]
            path.parent.mkdir(parents=True, exist_ok=True)
            cell.to_parquet(path)


def test_frontier_command_writes_the_table_the_figure_and_one_mlflow_run(tmp_path, monkeypatch, capsys):
    monkeypatch.delenv(tracking.TRACKING_URI_ENV, raising=False)
    folds = plan(BASE, tmp_path / "runs", loo=(0.5,), sparse=(3,), sets=("ablation.n_starts=8",))
    solves = pd.concat([read_library(LIBRARY, "cr3bp", alpha_label(a)) for a in (0.3, 0.5, 0.7)], ignore_index=True)
    for _, run in folds:
        _finish(run, solves)
    dest, store = tmp_path / "frontier", tmp_path / "mlflow"
    cli.main(["frontier", *(str(r) for _, r in folds), "--dest", str(dest), "--mlflow-dir", str(store),
              "--n-boot", "200"])
    out = capsys.readouterr().out
    assert "loo-0.500" in out and "sparse-3" in out and "aRT ÷ reuse" in out
    table = pd.read_csv(dest / "frontier.csv")
    assert set(table["design"]) == {"loo", "sparse-3"} and sorted(table["alpha"].unique()) == [0.3, 0.5, 0.7]
    learned = table[(table["sampler"] == "amorgs") & (table["target"] == "high_quality")
                    & (table["unit"] == "iterations")].set_index("alpha")
    assert (learned["n"] == 24).all() and (learned["model_seeds"] == 3).all()
    assert learned.loc[0.5, "gap"] == pytest.approx(0.1) and learned.loc[0.7, "gap_relative"] == pytest.approx(0.2 / 0.7)
    assert (dest / "fig_frontier.png").stat().st_size > 10_000 and "ratio_to_reuse" in (dest / "frontier.md").read_text()

    from mlflow.tracking import MlflowClient

    client = MlflowClient(tracking.tracking_uri(store))
    (run,) = client.search_runs([client.get_experiment_by_name("amorgs-frontier").experiment_id])
    assert run.info.status == "FINISHED" and run.data.params["designs"] == "loo,sparse-3"
    key = "frontier_ratio/loo-0.500/alpha_0.500/amorgs/iterations"
    assert run.data.metrics[key] == pytest.approx(learned.loc[0.5, "ratio_to_reuse"], rel=1e-9)
    assert {a.path for a in client.list_artifacts(run.info.run_id, "frontier")} == {
        "frontier/frontier.csv", "frontier/frontier.md", "frontier/fig_frontier.png"}

    # an unfinished fold: one line naming the missing cell, no traceback
    missing = folds[0][1] / "results/cr3bp/ablation/seed=13/alpha=0.500/amorgs.parquet"
    missing.unlink()
    with pytest.raises(SystemExit, match="not finished: .*seed=13/alpha=0.500/amorgs.parquet"):
        cli.main(["frontier", str(folds[0][1]), "--dest", str(dest), "--no-mlflow"])


def test_plan_prints_the_command_of_every_fold(tmp_path, capsys):
    cli.main(["frontier-plan", "--config", str(BASE), "--runs-dir", str(tmp_path), "--loo", "1.0", "--sparse", "5"])
    out = capsys.readouterr().out
    assert "# loo-1.000: train [0.1, 0.13" in out and "test [1.0]" in out
    assert "# sparse-5: train [0.1, 0.3, 0.5, 0.8, 1.0], test [0.2, 0.4, 0.6, 0.9]" in out
    assert f"--directory {tmp_path / 'sparse-5'} --configfile {tmp_path / 'sparse-5' / 'config.yaml'}" in out
    assert "amorgs frontier" in out
    with pytest.raises(SystemExit, match="no fold"):
        cli.main(["frontier-plan", "--config", str(BASE), "--runs-dir", str(tmp_path)])


@pytest.mark.slow
def test_the_ablation_cell_of_a_leave_out_fold_never_reuses_its_test_alpha(tmp_path, monkeypatch):
    """The real ablation_cell step (IPOPT solves, 3 starts at a 20-iteration cap) of the fold that leaves out
    α = 0.5, on a high-quality table holding α = 0.5's own solutions: every start is a solution of the nearest
    training α 0.4 and none is one of α = 0.5."""
    (_, run), = plan(BASE, tmp_path / "runs", loo=(0.5,),
                     sets=("ablation.n_starts=3", "ablation.workers=1", "problems.cr3bp.solver={max_iter: 20}",
                           "ablation.iteration_caps=[10]"))
    cfg = load_config(run / "config.yaml")
    solves = pd.concat([read_library(LIBRARY, "cr3bp", alpha_label(a)) for a in (0.4, 0.5, 0.6)], ignore_index=True)
    hq = solves[high_quality(solves, 415.0)].reset_index(drop=True)
    monkeypatch.chdir(tmp_path)  # no results/mlflow here: tracking is a no-op
    hq.to_parquet("hq.parquet")
    steps.run_step("ablation_cell", cfg, {"alpha": "0.500", "sampler": "nearest_alpha"}, {"high_quality": "hq.parquet"},
                   {"table": "cell.parquet"})
    cell = pd.read_parquet("cell.parquet")
    assert len(cell) == 3 and (cell["reuse_alpha"] == 0.4).all() and (cell["iterations"] <= 20).all()
    from amorgs.models.samplers import make_valid
    from amorgs.problems import get_problem

    problem = get_problem("cr3bp")
    names = list(problem.variable_names)
    guesses = cell[[f"guess_{v}" for v in names]].to_numpy()

    def found_in(alpha):
        ref = make_valid(rows_at(hq, alpha)[names].to_numpy(), problem)
        return np.all(np.isclose(guesses[:, None, :], ref[None], rtol=0, atol=1e-9), axis=2).any(axis=1)

    assert found_in(0.4).all() and not found_in(0.5).any() and not math.isnan(cell["cpu_s"].sum())
