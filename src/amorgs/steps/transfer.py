"""Transfer data (issue 38 §1): which known solutions transfer to another α, and at what cost.

One job per (training α_from → training α_to, shard): ``transfer.starts_per_pair`` high-quality solutions of
α_from, drawn as the reuse arm draws them (a seeded permutation of α_from's high-quality rows, repeated draws
only once the pool is exhausted; :class:`~amorgs.models.baselines.NearestAlphaSampler` with the pool pinned to
α_from), are solved as warm starts at α_to with the CR3BP solver (the ablation's options).  The table is the
solution table (docs/data-format.md) — the guess columns are the source solutions, the solution columns where
each landed — plus ``source_alpha``, ``source_pool_size`` and ``gap_relative`` = |α_to − α_from| / α_to.  Only
training α take part (in a fold: the fold's training α), so the data never see a test α.
"""

from __future__ import annotations

import time
from typing import Annotated, Literal

from pydantic import Field

from amorgs import layout
from amorgs.alphas import alpha_label
from amorgs.config import Config, Section
from amorgs.data.seeds import transfer_seed
from amorgs.solvers.options import IpoptOptions
from amorgs.steps import Job, Step, Wildcards

PROBLEM = "cr3bp"


class TransferSettings(Section):
    """One transfer shard: ``starts`` high-quality solutions of ``source_alpha`` solved at ``alpha`` (both in N)
    with ``seed`` (derived from ``transfer.seed``, the pair and the shard), ``workers`` processes and ``solver``;
    ``min_final_mass_kg`` (β, kg) counts the high-quality landings in the job's metrics."""

    problem: Literal["cr3bp"]
    alpha: float
    source_alpha: float
    seed: Annotated[int, Field(ge=0)]
    starts: Annotated[int, Field(ge=1)]
    workers: Annotated[int, Field(ge=1)]
    min_final_mass_kg: float
    solver: IpoptOptions


def transfer_pairs(cfg: Config) -> list[tuple[float, float]]:
    """Every ordered pair (α_from, α_to) of distinct CR3BP training α with |α_to − α_from| / α_to ≤
    ``transfer.max_relative_gap``, in ascending (α_to, α_from)."""
    train = sorted(cfg.problems.cr3bp.alphas.train_values())
    gap = cfg.transfer.max_relative_gap
    return [(a, b) for b in train for a in train if a != b and abs(b - a) / b <= gap + 1e-12]


def transfer_jobs(cfg: Config) -> list[dict[str, str]]:
    if not (cfg.transfer.enabled and cfg.problems.cr3bp.enabled):
        return []
    return [{"problem": PROBLEM, "alpha": alpha_label(b), "source": alpha_label(a), "shard": str(k)}
            for a, b in transfer_pairs(cfg) for k in range(cfg.transfer.shards)]


def transfer_settings(cfg: Config, w: Wildcards) -> TransferSettings:
    values = cfg.problems.cr3bp.alpha_values()
    alpha, source = values[w["alpha"]], values[w["source"]]
    return TransferSettings(problem=PROBLEM, alpha=alpha, source_alpha=source,
                            seed=transfer_seed(cfg.transfer.seed, PROBLEM, source, alpha, int(w["shard"])),
                            starts=cfg.transfer.starts_per_pair, workers=cfg.transfer.workers,
                            min_final_mass_kg=cfg.problems.cr3bp.filter.min_final_mass_kg,
                            solver=cfg.problems.cr3bp.solver)


def transfer_table(high_quality, s: TransferSettings, workers: int, progress: bool = True):
    """The transfer table of one shard (module docstring) from the run's high-quality table."""
    import numpy as np

    from amorgs.models.baselines import NearestAlphaSampler
    from amorgs.problems import get_problem
    from amorgs.solvers.multistart import records_table, solve_guesses

    problem = get_problem(s.problem)
    reuse = NearestAlphaSampler(problem, high_quality, [s.source_alpha])  # the pool: α_from's rows only
    source, pool_size = reuse.pool(s.alpha)
    guesses = reuse.sample(s.alpha, s.starts, np.random.default_rng(s.seed))
    records, info = solve_guesses(problem, s.alpha, guesses, workers, s.solver, progress=progress,
                                  label=f"{s.problem} transfer {s.source_alpha:g}→{s.alpha:g}")
    table = records_table(s.problem, s.alpha, s.seed, guesses, records, problem.variable_names, info["options_hash"])
    table.insert(2, "source_alpha", source)
    table.insert(3, "source_pool_size", pool_size)
    table.insert(4, "gap_relative", abs(s.alpha - source) / s.alpha)
    return table


def run_transfer(job: Job, run) -> None:
    import pandas as pd

    from amorgs.data.io import write_parquet
    from amorgs.problems.cr3bp import Cr3bpFilter

    s: TransferSettings = job.settings
    t0 = time.perf_counter()
    table = transfer_table(pd.read_parquet(job.input["high_quality"]), s, job.threads)
    table.insert(int(table.columns.get_loc("seed")) + 1, "shard", int(job.wildcards["shard"]))
    write_parquet(table, job.output["table"])
    conv = table[table["converged"]]
    hq = Cr3bpFilter(min_final_mass_kg=s.min_final_mass_kg).select(table)
    run.log_metrics({
        "starts": len(table), "converged": len(conv), "converged_fraction": len(conv) / len(table),
        "high_quality": len(hq), "high_quality_fraction": len(hq) / len(table),
        "iterations_mean": float(table["iterations"].mean()), "solve_cpu_s_total": float(table["cpu_s"].sum()),
        "job_wall_s": time.perf_counter() - t0,
    })
    print(f"{job.output['table']}: {len(table)} transfers {s.source_alpha:g} → {s.alpha:g} N, {len(conv)} converged, "
          f"{len(hq)} high-quality")


STAGE = 4.5
STEPS = (
    Step("transfer", TransferSettings, transfer_settings, run_transfer, transfer_jobs,
         lambda w: {"table": layout.TRANSFER_SHARD.format_map(w)},
         resources=lambda cfg, w: cfg.transfer.job(),
         description="high-quality solutions of one training α solved at another → transfer table (selector data)"),
)
