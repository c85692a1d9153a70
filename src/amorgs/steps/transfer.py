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
from amorgs.steps import Job, Step, Wildcards, resources_of

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


class SelectorSettings(Section):
    """The transfer selector (:class:`~amorgs.models.selector.TransferSelector`): trained on every transfer
    shard of the run for β = ``beta_kg`` (kg) with ``seed`` and ``max_iter`` boosting iterations per ensemble."""

    beta_kg: float
    seed: Annotated[int, Field(ge=0)]
    max_iter: Annotated[int, Field(ge=1)] = 200


def selector_settings(cfg: Config, w: Wildcards) -> SelectorSettings:
    return SelectorSettings(beta_kg=cfg.problems.cr3bp.filter.min_final_mass_kg, seed=cfg.transfer.seed)


def selector_jobs(cfg: Config) -> list[dict[str, str]]:
    return [{}] if transfer_jobs(cfg) else []


def held_out_auc(table, settings: SelectorSettings, names) -> dict[str, float | None]:
    """How well the selector predicts a high-quality landing at a target α it never saw: for each target α, fit
    on the other targets' rows and score its rows; the ROC AUC of P(hq) over every held-out row (None when the
    labels hold one class) and Spearman's ρ of predicted vs actual iterations."""
    import numpy as np
    from scipy.stats import spearmanr
    from sklearn.metrics import roc_auc_score

    from amorgs.models.selector import TransferSelector, training_set, transfer_labels

    p, k, hq, iters = [], [], [], []
    for alpha in sorted(table["alpha"].unique()):
        train, test = table[table["alpha"] != alpha], table[table["alpha"] == alpha]
        if not len(train):
            continue
        model = TransferSelector(settings.beta_kg, settings.seed, settings.max_iter).fit(train, names)
        pp, kk = model.predict(training_set(test, names))
        y, it = transfer_labels(test, settings.beta_kg)
        p.append(pp), k.append(kk), hq.append(y), iters.append(it)
    if not p:
        return {"heldout_auc": None, "heldout_iterations_spearman": None}
    p, k, hq, iters = (np.concatenate(v) for v in (p, k, hq, iters))
    auc = float(roc_auc_score(hq, p)) if 0 < hq.sum() < len(hq) else None
    rho = float(spearmanr(k, iters).statistic) if len(set(iters)) > 1 and len(set(k)) > 1 else None
    return {"heldout_auc": auc, "heldout_iterations_spearman": rho}


def run_selector(job: Job, run) -> None:
    import pandas as pd

    from amorgs.data.io import write_json
    from amorgs.models.selector import TransferSelector
    from amorgs.problems import get_problem

    s: SelectorSettings = job.settings
    names = get_problem(PROBLEM).variable_names
    tables = {p: pd.read_parquet(p) for p in job.input["tables"]}
    table = pd.concat(tables.values(), ignore_index=True)
    for path, t in tables.items():
        run.log_dataset(t, path, "training")
    t0 = time.process_time()
    selector = TransferSelector(s.beta_kg, s.seed, s.max_iter).fit(table, names)
    train_cpu_s = time.process_time() - t0
    selector.save(job.output["model"])
    hq = (table["converged"].astype(bool) & (table["m_f"] >= s.beta_kg))
    report = {"model": "selector", "rows": int(len(table)), "shards": len(tables), "high_quality": int(hq.sum()),
              "pairs": int(table.groupby(["source_alpha", "alpha"]).ngroups), "beta_kg": s.beta_kg,
              "train_cpu_s": train_cpu_s, **held_out_auc(table, s, names)}
    write_json(report, job.output["report"])
    run.log_metrics({k: v for k, v in report.items() if isinstance(v, (int, float)) and k != "model"})
    run.log_artifact(job.output["model"])
    run.log_artifact(job.output["report"])
    print(f"{job.output['model']}: selector on {len(table)} transfers ({int(hq.sum())} high-quality), held-out AUC "
          f"{report['heldout_auc']}")


STAGE = 4.5
STEPS = (
    Step("transfer", TransferSettings, transfer_settings, run_transfer, transfer_jobs,
         lambda w: {"table": layout.TRANSFER_SHARD.format_map(w)},
         resources=lambda cfg, w: cfg.transfer.job(),
         description="high-quality solutions of one training α solved at another → transfer table (selector data)"),
    Step("train_selector", SelectorSettings, selector_settings, run_selector, selector_jobs,
         lambda w: {"model": layout.SELECTOR_MODEL, "report": layout.SELECTOR_REPORT},
         resources=resources_of("train"),
         description="every transfer table → the transfer selector (P(high quality), E[iterations]) + report"),
)
