"""A real (tiny) ablation cell: uniform guesses solved by IPOPT, then the statistics and figures."""

import numpy as np
import pytest

from amorgs.ablation.experiment import run_cell
from amorgs.ablation.statistics import capped_study, table6
from amorgs.figures.ablation import fig21_solve_time_histograms, fig22_capped_convergence, fig23_amorgs_diversity
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
    for fig in (fig21_solve_time_histograms(cell, 0.0), fig22_capped_convergence({0.85: capped}),
                fig23_amorgs_diversity(cell, cell[cell["converged"]], 0.0, sampler="uniform")):
        assert fig.axes
