"""A real (tiny) ablation cell: uniform guesses solved by IPOPT, then the statistics and figures."""

import numpy as np
import pytest

from amorgs.ablation.experiment import run_cell
from amorgs.ablation.report import summarize
from amorgs.ablation.statistics import capped_study, table6
from amorgs.alphas import metric_key
from amorgs.figures.ablation import ablation_figures, fig23_amorgs_diversity
from amorgs.models.samplers import UniformSampler
from amorgs.problems import get_problem

pytestmark = pytest.mark.slow


def test_uniform_cell_statistics_and_figures():
    problem = get_problem("cr3bp")
    cell = run_cell("cr3bp", 0.85, UniformSampler(problem), n=4, seed=5, solver_options={"max_iter": 300},
                    workers=2, progress=False)
    again = UniformSampler(problem).sample(0.85, 4, np.random.default_rng(5))
    np.testing.assert_array_equal(cell[[f"guess_{v}" for v in problem.variable_names]].to_numpy(), again)
    assert list(cell["sampler"].unique()) == ["uniform"] and len(cell) == 4
    assert set(cell["status"]) <= {"Solve_Succeeded", "Solved_To_Acceptable_Level", "Maximum_Iterations_Exceeded",
                                   "Restoration_Failed", "Infeasible_Problem_Detected", "Error_In_Step_Computation",
                                   "Maximum_WallTime_Exceeded", "Invalid_Number_Detected", "Search_Direction_Becomes_Too_Small"}
    t6 = table6(cell, beta_kg=0.0)
    assert t6["percent_converged"].iloc[0] == pytest.approx(100 * cell["converged"].mean())
    capped, result = capped_study(cell, beta_kg=0.0, cap_s=float(cell["cpu_s"].max()), reference="uniform")
    assert capped["percent_within_cap"].iloc[0] == pytest.approx(100 * cell["converged"].mean())
    summary = summarize(cell, cell[cell["converged"]], beta_kg=0.0, n_boot=50)
    assert summary.metrics[metric_key("percent_hq", 0.85, "uniform")] == pytest.approx(100 * cell["converged"].mean())
    figures = ablation_figures(summary)
    figures["fig23_uniform"] = fig23_amorgs_diversity(summary.solves, summary.ground_truth, 0.0, sampler="uniform")
    for fig in figures.values():
        fig.canvas.draw()
        assert fig.axes


# The library is append-only: its shards below this number are the ones committed before 2026-12-05 and never
# change, so a test drawing from them sees the same pool however far the library grows (drawing from the whole,
# growing library changed this file's reuse guess when batches 39–42 were added, and that guess did not converge).
FROZEN_LIBRARY_SHARDS = 332


def _library_high_quality(beta_kg: float = 415.0):
    """The committed library's verified, m_f ≥ β rows of its first FROZEN_LIBRARY_SHARDS shards, in (α, shard,
    start) order: a real, small high-quality table that library growth does not change."""
    import glob

    import pandas as pd

    files = sorted(glob.glob("data/library/cr3bp/alpha=*/*.parquet"))
    if not files:
        pytest.skip("no committed CR3BP library")
    df = pd.concat([pd.read_parquet(f) for f in files], ignore_index=True)
    df = df[df["shard"] < FROZEN_LIBRARY_SHARDS].sort_values(["alpha", "shard", "start"], kind="stable")
    return df[df["converged"].astype(bool) & (df["m_f"] >= beta_kg)].reset_index(drop=True)


def test_iteration_cap_equals_a_real_capped_resolve():
    """The post-hoc iteration cap of running_time.iteration_capped equals re-solving under max_iter = cap:
    IPOPT is deterministic, so a start converging in k iterations converges identically under a cap of k and
    is stopped (not converged) under a cap below k."""
    from amorgs.ablation.running_time import iteration_capped
    from amorgs.models.samplers import NearestAlphaSampler
    from amorgs.solvers.multistart import solve_guesses

    problem = get_problem("cr3bp")
    hq = _library_high_quality()
    guess = NearestAlphaSampler(problem, hq, (0.8, 0.9)).sample(0.85, 1, np.random.default_rng(0))
    opts = {"max_iter": 1000, "max_wall_s": 120.0}
    (full,), _ = solve_guesses(problem, 0.85, guess, 1, opts, progress=False)
    assert full.converged, full.status
    k = int(full.iterations)
    assert k > 4
    (same,), _ = solve_guesses(problem, 0.85, guess, 1, {**opts, "max_iter": k}, progress=False)
    assert same.converged and int(same.iterations) == k
    np.testing.assert_allclose(same.x, full.x, rtol=1e-9, atol=1e-9)
    (cut,), _ = solve_guesses(problem, 0.85, guess, 1, {**opts, "max_iter": k // 2}, progress=False)
    assert not cut.converged and int(cut.iterations) == k // 2
    import pandas as pd

    row = pd.DataFrame({"alpha": [0.85], "sampler": ["nearest_alpha"], "converged": [True], "m_f": [full.x[3]],
                        "iterations": [k], "cpu_s": [full.cpu_s]})
    t = iteration_capped(row, 0.0, caps=[k // 2, k]).set_index("cap_iterations")
    assert t.loc[k // 2, "k_within_cap"] == int(cut.converged) == 0
    assert t.loc[k, "k_within_cap"] == int(same.converged) == 1
    assert t.loc[k // 2, "iterations_spent"] == k // 2


def test_reuse_baseline_cells_on_library_data():
    """nearest_alpha and its perturbed variant on the committed library: real solves, seeded, valid."""
    from amorgs.models.samplers import NearestAlphaPerturbedSampler, NearestAlphaSampler

    problem = get_problem("cr3bp")
    hq = _library_high_quality()
    train = (0.1, 0.13, 0.16, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9, 1.0)
    for sampler in (NearestAlphaSampler(problem, hq, train), NearestAlphaPerturbedSampler(problem, hq, train, 0.02)):
        cell = run_cell("cr3bp", 0.85, sampler, n=2, seed=3, solver_options={"max_iter": 300, "max_wall_s": 60.0},
                        workers=2, progress=False)
        assert list(cell["sampler"].unique()) == [sampler.name] and len(cell) == 2
        again = sampler.sample(0.85, 2, np.random.default_rng(3))
        np.testing.assert_array_equal(cell[[f"guess_{v}" for v in problem.variable_names]].to_numpy(), again)
        assert (cell["reuse_alpha"] == 0.8).all() and (cell["reuse_pool_size"] == sampler.pool(0.85)[1]).all()
    # a later model seed's cell: the next slice of the same draw, numbered on
    later = run_cell("cr3bp", 0.85, sampler, n=1, seed=3, solver_options={"max_iter": 300, "max_wall_s": 60.0},
                     progress=False, start_offset=1)
    assert later["start"].tolist() == [1]
    np.testing.assert_array_equal(later[[f"guess_{v}" for v in problem.variable_names]].to_numpy(), again[1:])


def test_ablation_cell_step_nearest_alpha(tmp_path, monkeypatch):
    """The ablation_cell step with sampler nearest_alpha and the high-quality table, as the workflow runs it."""
    import pandas as pd

    from amorgs import steps
    from amorgs.errors import InputError

    from config_files import load

    cfg = load("smoke")
    hq = _library_high_quality()
    monkeypatch.chdir(tmp_path)  # no results/mlflow here: tracking is a no-op
    hq.to_parquet("hq.parquet")
    cell = {"alpha": "0.850", "sampler": "nearest_alpha"}
    steps.run_step("ablation_cell", cfg, cell, {"high_quality": "hq.parquet"}, {"table": "cell.parquet"})
    table = pd.read_parquet("cell.parquet")
    assert len(table) == cfg.ablation.n_starts and set(table["sampler"]) == {"nearest_alpha"}
    assert set(table["model_seed"]) == {cfg.cr3bp_models.seed}
    assert table["reuse_pool_size"].iloc[0] > 0 and table["start"].tolist() == list(range(cfg.ablation.n_starts))
    with pytest.raises(InputError, match="nearest_alpha needs the high-quality table"):
        steps.run_step("ablation_cell", cfg, cell, {}, {"table": "x.parquet"})
