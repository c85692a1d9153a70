"""Global search at the CR3BP test α (issue 41): per (test α, strategy, sampler) one job running the configured
number of seeded searches (:mod:`amorgs.ablation.global_search`: multi-start, or monotonic basin hopping from the
sampler's starts), then the report: the expected iterations to come within δ of the best known m_f per cell
with bootstrap intervals, the runtime ECDF (figure) and the distinct near-best trajectories, logged to MLflow.
The samplers are built as the ablation builds them (its models, high-quality table and training α)."""

from __future__ import annotations

import math
import os
from typing import Annotated, Literal

from pydantic import Field

from amorgs import layout
from amorgs.ablation.arms import SAMPLER_NAMES
from amorgs.alphas import alpha_label, metric_key
from amorgs.config import Config, Section
from amorgs.data.seeds import cell_seed
from amorgs.errors import InputError
from amorgs.solvers.basin_hopping import HOP_DISTRIBUTIONS, STRATEGIES, HopSettings, hop_solver_options
from amorgs.solvers.options import IpoptOptions
from amorgs.steps import Job, Step, Wildcards, once_if, resources_of
from amorgs.steps.ablation import cell_inputs, cell_sampler
from amorgs.steps.outputs import finite_metrics, use_agg, write_figures


class SearchCellSettings(Section):
    """One cell: ``searches`` searches of ``strategy`` from ``sampler``'s starts at the test ``alpha`` (N), each of
    ``budget`` IPOPT iterations, seeded from ``seed`` (derived from ``global_search.seed``, α, strategy and
    sampler) and search index; hops of ``hop_distribution`` × ``hop_scale`` of the box width (Pareto tail
    ``hop_shape``; of the ``hop_variables`` only, where named), a restart after ``patience`` misses; solved with
    ``solver``.  The reuse arms draw on the training-α rows (``train_alphas``) of the high-quality table."""

    alpha: float
    strategy: Literal[tuple(STRATEGIES)]  # type: ignore[valid-type]
    sampler: Literal[SAMPLER_NAMES]  # type: ignore[valid-type]
    searches: Annotated[int, Field(ge=1)]
    budget: Annotated[int, Field(ge=1)]
    seed: Annotated[int, Field(ge=0)]
    hop_distribution: Literal[tuple(HOP_DISTRIBUTIONS)]  # type: ignore[valid-type]
    hop_scale: float
    hop_shape: float
    patience: Annotated[int, Field(ge=1)]
    hop_variables: tuple[str, ...] = ()
    solver: IpoptOptions
    train_alphas: tuple[float, ...]
    perturbation_scale: Annotated[float, Field(ge=0)]
    gmm_components: Annotated[int, Field(ge=1)]
    selection_oversample: Annotated[int, Field(ge=1)]


def _cell_settings(cfg: Config, w: Wildcards) -> SearchCellSettings:
    g, a, cr3bp = cfg.global_search, cfg.ablation, cfg.problems.cr3bp
    alpha = cr3bp.alpha_values()[w["alpha"]]
    return SearchCellSettings(
        alpha=alpha, strategy=w["strategy"], sampler=w["sampler"], searches=g.searches, budget=g.budget,
        seed=cell_seed(g.seed, "cr3bp", alpha, f"{w['strategy']}/{w['sampler']}"),
        hop_distribution=g.hop_distribution, hop_scale=g.hop_scale, hop_shape=g.hop_shape, patience=g.patience,
        hop_variables=g.hop_variables, solver=cr3bp.solver, train_alphas=cr3bp.alphas.train_values(),
        perturbation_scale=a.perturbation_scale, gmm_components=a.gmm_components,
        selection_oversample=a.selection_oversample)


def run_cell(job: Job, run) -> None:
    from amorgs.ablation.global_search import Cell
    from amorgs.ablation.global_search import run_cell as search_cell
    from amorgs.data.io import write_parquet
    from amorgs.problems import get_problem

    s: SearchCellSettings = job.settings
    problem = get_problem("cr3bp")
    sampler = cell_sampler("global_search_cell", job)
    cell = Cell(sampler=s.sampler, strategy=s.strategy, alpha=s.alpha, searches=s.searches, budget=s.budget,
                seed=s.seed, hops=HopSettings(distribution=s.hop_distribution, scale=s.hop_scale, shape=s.hop_shape,
                                              patience=s.patience, variables=s.hop_variables))
    warm = hop_solver_options(s.strategy, s.solver)
    events, solutions = search_cell(cell, sampler.sample, problem.make_local_solver(s.solver), problem.lower,
                                    problem.upper, problem.variable_names,
                                    problem.make_local_solver(warm) if warm is not None else None)
    if not len(events):
        raise InputError(f"global_search_cell: {s.sampler} gave no start at α = {s.alpha:g}")
    write_parquet(events, job.output["events"])
    write_parquet(solutions, job.output["solutions"])
    best = float(-solutions["objective"].min()) if len(solutions) else float("nan")
    run.log_metrics(finite_metrics({"solves": len(events), "feasible": len(solutions), "best_m_f": best,
                                    "hops": int((events["kind"] == "hop").sum()),
                                    "accepted_hops": int(((events["kind"] == "hop") & events["accepted"]).sum())}))
    print(f"{job.output['events']}: {s.searches} searches, {len(events)} solves, {len(solutions)} feasible, "
          f"best m_f {best:.3f} kg")


def cell_jobs(cfg: Config) -> list[dict[str, str]]:
    g = cfg.global_search
    if not g.enabled:
        return []
    return [{"alpha": alpha_label(a), "strategy": t, "sampler": s}
            for a in cfg.problems.cr3bp.alphas.test for t in g.strategies for s in g.samplers]


def search_cell_inputs(sampler: str, wildcards: Wildcards) -> dict[str, str | list[str]]:
    """What the cell's sampler draws on, as for an ablation cell (:func:`amorgs.steps.ablation.cell_inputs`)."""
    return cell_inputs(sampler, layout.CR3BP_MODEL, wildcards)


class SearchReportSettings(Section):
    """The targets ``deltas_kg`` (kg below the best known m_f), ``n_boot`` bootstrap resamples drawn with
    ``seed``, the budget (iterations: hits beyond it do not count; the figure's x range), and the library whose
    verified rows at each test α join the best known (``library_path``; empty: none) with the best-known record
    beside it (``record_path``, :mod:`amorgs.data.best_known`, read where it exists)."""

    deltas_kg: tuple[float, ...]
    n_boot: int
    seed: int
    budget: int
    library_path: str
    record_path: str = ""


def _report_settings(cfg: Config, w: Wildcards) -> SearchReportSettings:
    g, lib = cfg.global_search, cfg.problems.cr3bp.library
    from amorgs.data.best_known import DEFAULT_PATH

    return SearchReportSettings(deltas_kg=g.deltas_kg, n_boot=cfg.ablation.n_boot, seed=g.seed, budget=g.budget,
                                library_path=lib.path if lib.enabled else "",
                                record_path=DEFAULT_PATH if lib.enabled else "")


def run_report(job: Job, run) -> None:
    use_agg()
    import pandas as pd

    from amorgs.ablation.global_search import (
        best_known,
        distinct_near_best,
        ert_ratios,
        runtime_ecdf,
        runtime_to_target,
    )
    from amorgs.ablation.global_study import compare
    from amorgs.data import best_known as bk
    from amorgs.data.io import atomic_path, write_json
    from amorgs.figures.global_search import fig_runtime_ecdf

    s: SearchReportSettings = job.settings
    events = pd.concat([pd.read_parquet(p) for p in job.input["events"]], ignore_index=True)
    solutions = pd.concat([pd.read_parquet(p) for p in job.input["solutions"]], ignore_index=True)
    runtime, ratios, ecdf, distinct, best_rows, metrics = [], [], [], [], [], {}
    for alpha, cell_events in events.groupby("alpha"):
        found = solutions[solutions["alpha"] == alpha] if len(solutions) else solutions
        library = _library_best(s.library_path, alpha)
        record = -bk.best_m_f_lifted(bk.read_record(s.record_path), alpha) if s.record_path else math.nan
        best = best_known([library], [record], found["objective"] if len(found) else [])
        if best != best:  # NaN: nothing feasible anywhere
            raise InputError(f"global_search_report: no feasible solution at α = {alpha:g} to time against")
        source = "library" if best == library else "best-known record" if best == record else "search"
        best_rows.append({"alpha": alpha, "best_m_f": -best, "source": source, "library_best_m_f": -library})
        table = runtime_to_target(cell_events, best, s.deltas_kg, n_boot=s.n_boot, seed=s.seed, budget=s.budget)
        runtime.append(table)
        ratios.append(ert_ratios(cell_events, best, s.deltas_kg, baseline=_baseline(cell_events), n_boot=s.n_boot,
                                 seed=s.seed, budget=s.budget))
        ecdf.append(runtime_ecdf(cell_events, best, s.deltas_kg, budget=s.budget))
        if len(found):
            distinct.append(distinct_near_best(found, best, s.deltas_kg))
        for r in table.itertuples(index=False):
            qualifiers = (r.strategy, r.sampler, f"delta_{r.delta:g}kg")
            metrics[metric_key("ert", alpha, *qualifiers)] = r.ert
            metrics[metric_key("success_rate", alpha, *qualifiers)] = r.success_rate
    runtime_all = pd.concat(runtime, ignore_index=True)
    best_m_f = {r["alpha"]: r["best_m_f"] for r in best_rows}
    figures = {layout.GLOBAL_SEARCH_FIGURE: fig_runtime_ecdf(pd.concat(ecdf, ignore_index=True), runtime_all,
                                                              best_m_f, s.deltas_kg, s.budget)}
    tables = {"global_search_runtime.csv": runtime_all, "global_search_ratios.csv": pd.concat(ratios, ignore_index=True),
              "global_search_ecdf.csv": pd.concat(ecdf, ignore_index=True),
              "global_search_distinct.csv": pd.concat(distinct, ignore_index=True) if distinct else pd.DataFrame(
                  {"status": ["no feasible solution"]}),
              "global_search_best_known.csv": pd.DataFrame(best_rows)}
    by_name = {os.path.basename(p): p for p in job.output["tables"]}
    for name, table in tables.items():
        with atomic_path(by_name[name]) as tmp:
            table.to_csv(tmp, index=False)
    with atomic_path(by_name["global_search_runtime.md"]) as tmp:
        tmp.write_text("\n\n".join(f"**α = {a:g}**: ERT in IPOPT iterations (95 % bootstrap), successes/searches\n\n"
                                   + compare(t).to_markdown() for a, t in runtime_all.groupby("alpha")) + "\n")
    write_json({"best_known": best_rows, "metrics": finite_metrics(metrics)}, job.output["summary"])
    run.log_metrics(finite_metrics(metrics))
    for path in [job.output["summary"], *job.output["tables"]]:
        run.log_artifact(path, "tables")
    write_figures(figures, job.output["figures"], run)
    print(f"{job.output['summary']}: {len(runtime_all)} (cell, δ) rows over {events['alpha'].nunique()} α")


def _baseline(events) -> tuple[str, str]:
    """The cell every other is divided by: multi-start from uniform starts where the run has it, else the first
    (strategy, sampler) of the run."""
    cells = sorted(set(zip(events["strategy"], events["sampler"])))
    return ("multistart", "uniform") if ("multistart", "uniform") in cells else cells[0]


def _library_best(library_path: str, alpha: float) -> float:
    """The lowest objective (−m_f, kg) of the library's verified rows at ``alpha``; NaN without a library or
    rows."""
    if not library_path:
        return float("nan")
    from amorgs.data.library import read_library, read_manifest

    if read_manifest(library_path, "cr3bp") is None:
        return float("nan")
    rows = read_library(library_path, "cr3bp", alpha_label(alpha))
    verified = rows[rows["converged"]] if len(rows) else rows
    return float(-verified["m_f"].max()) if len(verified) else float("nan")


STAGE = 8
STEPS = (
    Step("global_search_cell", SearchCellSettings, _cell_settings, run_cell, cell_jobs,
         lambda w: {"events": layout.GLOBAL_SEARCH_EVENTS.format_map(w),
                    "solutions": layout.GLOBAL_SEARCH_SOLUTIONS.format_map(w)},
         resources=lambda cfg, w: cfg.global_search.job(),
         description="R seeded searches of one strategy from one sampler's starts at one test α"),
    Step("global_search_report", SearchReportSettings, _report_settings, run_report, once_if("global_search"),
         lambda w: {"summary": layout.GLOBAL_SEARCH_SUMMARY,
                    "tables": [layout.TABLE.format(name=n) for n in layout.GLOBAL_SEARCH_TABLES],
                    "figures": [layout.FIGURE.format(name=layout.GLOBAL_SEARCH_FIGURE)]},
         resources=resources_of("figure"),
         report=("global_search", "CR3BP global search"),
         description="runtime to the best known m_f: ERT per cell with bootstrap intervals, runtime ECDF, "
                     "distinct near-best trajectories"),
)
