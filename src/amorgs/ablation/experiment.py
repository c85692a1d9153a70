"""One cell of the warm-start ablation: n guesses from one sampler at one test α, each solved once.

The solves go through the same multistart pool, solver and caps as data generation, so the only thing
that differs between cells is where the initial guesses come from (paper Sec. V.B.7, Table 6).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from amorgs.models.samplers import NearestAlphaSampler, Sampler
from amorgs.problems import get_problem
from amorgs.solvers.multistart import OptionsLike, records_table, solve_guesses


def run_cell(
    problem: str,
    alpha: float,
    sampler: Sampler,
    n: int,
    seed: int,
    solver_options: OptionsLike = None,
    workers: int = 1,
    progress: bool = True,
    start_offset: int = 0,
) -> pd.DataFrame:
    """Draw ``start_offset + n`` guesses with ``default_rng(seed)`` from ``sampler`` and solve the last ``n``;
    one row per start, ``start`` numbered from ``start_offset`` (cells that share a seed and take consecutive
    slices are together one draw: the model seeds' cells of a reuse arm).

    ``solver_options``: the problem's options object (e.g. :class:`~amorgs.solvers.options.IpoptOptions`; a
    mapping or ``None`` is converted).  The table is the solution table (docs/data-format.md) with a ``sampler``
    column added, and for the reuse arms ``reuse_alpha`` and ``reuse_pool_size`` (the training α whose
    high-quality rows were drawn, and how many it holds: :meth:`~amorgs.models.samplers.NearestAlphaSampler.pool`).
    """
    prob = get_problem(problem)
    guesses = sampler.sample(alpha, start_offset + n, np.random.default_rng(seed))[start_offset:]
    records, info = solve_guesses(
        prob, alpha, guesses, workers, solver_options, progress=progress, label=f"{problem}/{sampler.name}"
    )
    table = records_table(problem, alpha, seed, guesses, records, prob.variable_names, info["options_hash"])
    table.insert(1, "sampler", sampler.name)
    table["start"] += start_offset
    if isinstance(sampler, NearestAlphaSampler):
        table["reuse_alpha"], table["reuse_pool_size"] = sampler.pool(alpha)
    return table
