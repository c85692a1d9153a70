"""The warm-start ablation (paper Sec. V.B.7–8, issue 11): per (test α, sampler) one job solving guesses from
that sampler with the CR3BP solver options — once with the models of ``cr3bp_models.seed``, and once more per
``cr3bp_models.extra_seeds`` (replicates: their own models, their own cell seed); then the report: Table 6,
the capped studies, coverage, rates + Fisher tests, the β sweep, expected running time (per high-quality
solution and per new η-distinct optimum), the reuse pools, anytime curves with bands and Figs. 21–23."""

from __future__ import annotations

import os
from typing import Annotated, Literal

from pydantic import Field

from amorgs import layout
from amorgs.ablation.arms import SAMPLER_NAMES, get_arm
from amorgs.ablation.studies import table_files
from amorgs.alphas import alpha_label
from amorgs.config import Config, Section
from amorgs.data.seeds import cell_seed
from amorgs.errors import InputError
from amorgs.solvers.options import IpoptOptions
from amorgs.steps import Job, Step, Wildcards, once_if, resources_of
from amorgs.steps.outputs import finite_metrics, use_agg, write_figures


class CellSettings(Section):
    """One cell: ``starts`` guesses of ``sampler`` at the exact test ``alpha``, drawn with ``seed`` (derived
    from the ablation seed, α, the sampler and — for a replicate of a learned arm — the model seed), solved
    with ``solver``.  The reuse baselines draw from the training-α rows (``train_alphas``) of the high-quality
    table; their cells of every model seed share one seed and take consecutive slices of one draw
    (``start_offset`` = the model seed's position × ``starts``), so the pooled starts are drawn without
    replacement until the pool is exhausted."""

    alpha: float
    sampler: Literal[SAMPLER_NAMES]  # type: ignore[valid-type]
    model_seed: Annotated[int, Field(ge=0)]
    starts: Annotated[int, Field(ge=1)]
    seed: Annotated[int, Field(ge=0)]
    solver: IpoptOptions
    train_alphas: tuple[float, ...]
    perturbation_scale: Annotated[float, Field(ge=0)]
    gmm_components: Annotated[int, Field(ge=1)]
    selection_oversample: Annotated[int, Field(ge=1)] = 5
    data_fraction: Annotated[float, Field(gt=0, le=1)] = 1.0
    start_offset: Annotated[int, Field(ge=0)] = 0


def _cell_settings(cfg: Config, w: Wildcards) -> CellSettings:
    a, cr3bp = cfg.ablation, cfg.problems.cr3bp
    alpha = cr3bp.alpha_values()[w["alpha"]]
    replicate, fraction = "mseed" in w, float(w.get("fraction", 1.0))
    name, offset = w["sampler"], 0
    model_seed = int(w["mseed"]) if replicate else cfg.cr3bp_models.seed
    if get_arm(name).pooled:  # one draw over the model seeds' cells: each takes its slice
        offset = cfg.cr3bp_models.seeds.index(model_seed) * a.n_starts
    elif replicate:
        name += f"@seed={w['mseed']}"
    if "fraction" in w:
        name += f"@fraction={w['fraction']}"
    return CellSettings(alpha=alpha, sampler=w["sampler"], model_seed=model_seed,
                        starts=a.n_starts, seed=cell_seed(a.seed, "cr3bp", alpha, name), solver=cr3bp.solver,
                        train_alphas=cr3bp.alphas.train_values(), perturbation_scale=a.perturbation_scale,
                        gmm_components=a.gmm_components, selection_oversample=a.selection_oversample,
                        data_fraction=fraction, start_offset=offset)


def cell_sampler(rule: str, job: Job):
    """The sampler of a cell job's arm (``job.settings.sampler``), built from the job's inputs — the checkpoints
    it loads, the high-quality table, the transfer selector (:func:`cell_inputs`) — and the settings' training α,
    σ of the perturbed reuse arm, GMM components and selection oversampling; one line naming ``rule`` and the
    missing input otherwise.  Ablation and global-search cells build their samplers here."""
    from amorgs.ablation.arms import build_sampler
    from amorgs.problems import get_problem

    s = job.settings
    arm = get_arm(s.sampler)
    models = job.input.get("models", [])
    if arm.high_quality and "high_quality" not in job.input:
        raise InputError(f"{rule}: {s.sampler} needs the high-quality table (input high_quality)")
    if len(models) < len(arm.models):
        raise InputError(f"{rule}: {s.sampler} needs the checkpoints {arm.models} (input models)")
    if arm.transfer and "selector" not in job.input:
        raise InputError(f"{rule}: {s.sampler} needs the transfer selector (input selector)")
    hq = None
    if arm.high_quality:
        import pandas as pd

        hq = pd.read_parquet(job.input["high_quality"])
    return build_sampler(s.sampler, get_problem("cr3bp"), os.path.dirname(models[0]) if models else None,
                         high_quality=hq, train_alphas=s.train_alphas, perturbation_scale=s.perturbation_scale,
                         gmm_components=s.gmm_components, selector=job.input.get("selector"),
                         selection_oversample=s.selection_oversample)


def run_cell(job: Job, run) -> None:
    from amorgs.ablation.experiment import run_cell as solve_cell
    from amorgs.data.io import write_parquet

    s: CellSettings = job.settings
    sampler = cell_sampler("ablation_cell", job)
    df = solve_cell("cr3bp", s.alpha, sampler, s.starts, s.seed, s.solver, job.threads, start_offset=s.start_offset)
    df.insert(2, "model_seed", s.model_seed)
    if s.data_fraction < 1.0:  # a learning-curve cell: its models saw this fraction of the training rows
        df.insert(3, "data_fraction", s.data_fraction)
    write_parquet(df, job.output["table"])
    conv = df[df["converged"]]
    run.log_metrics({
        "starts": len(df),
        "converged": len(conv),
        "converged_fraction": len(conv) / len(df),
        "iterations_median": conv["iterations"].median() if len(conv) else None,
        "solve_wall_s_total": df["wall_s"].sum(),
    })
    print(f"{job.output['table']}: {len(df)} solves, {len(conv)} converged")


def cell_jobs(cfg: Config) -> list[dict[str, str]]:
    if not cfg.ablation.enabled:
        return []
    return [{"alpha": label, "sampler": s} for label in _test_labels(cfg) for s in cfg.ablation.samplers]


def replicate_cell_jobs(cfg: Config) -> list[dict[str, str]]:
    return [{"mseed": str(m), **w} for m in cfg.cr3bp_models.extra_seeds for w in cell_jobs(cfg)]


def fraction_cell_jobs(cfg: Config) -> list[dict[str, str]]:
    """The learning curve: each of ``ablation.fraction_samplers`` with the models of every data fraction."""
    if not (cfg.ablation.enabled and cfg.cr3bp_models.enabled):
        return []
    return [{"fraction": layout.fraction_label(f), "alpha": label, "sampler": s}
            for f in cfg.cr3bp_models.data_fractions for label in _test_labels(cfg) for s in cfg.ablation.fraction_samplers]


def _test_labels(cfg: Config) -> list[str]:
    return [alpha_label(a) for a in cfg.problems.cr3bp.alphas.test]


def cell_inputs(sampler: str, model_template: str, wildcards: Wildcards) -> dict[str, str | list[str]]:
    """The named inputs of a cell of ``sampler``: ``models``, the checkpoints its arm loads (none for uniform
    and the reuse baselines), for the arms that draw on it ``high_quality``, the filtered table, and for the
    arms that rank by it ``selector``, the transfer selector."""
    arm = get_arm(sampler)
    inputs: dict[str, str | list[str]] = {
        "models": [model_template.format_map({**dict(wildcards), "model": m}) for m in arm.models]}
    if arm.high_quality:
        inputs["high_quality"] = layout.HIGH_QUALITY.format(problem="cr3bp")
    if arm.transfer:
        inputs["selector"] = layout.SELECTOR_MODEL
    return inputs


class ReportSettings(Section):
    """β (kg) of a high-quality solution, the β sweep (kg), the Fig. 22 iteration caps fixed before the
    solves (≤ ``max_iter``), ``n_boot`` bootstrap resamples drawn with ``seed``, the high-quality solutions
    wanted per new α of the break-even table, the training α (whose solves are the arms' data) and η of the
    η-distinct optima (Eq. 12, dimensionless: the structure analysis's ``params.diversity.eta``)."""

    beta_kg: float
    beta_sweep_kg: tuple[float, ...]
    iteration_caps: tuple[int, ...]
    max_iter: int
    n_boot: int
    seed: int
    break_even_solutions: tuple[int, ...]
    train_alphas: tuple[float, ...]
    eta: float


def _report_settings(cfg: Config, w: Wildcards) -> ReportSettings:
    a = cfg.ablation
    return ReportSettings(beta_kg=cfg.problems.cr3bp.filter.min_final_mass_kg, beta_sweep_kg=a.beta_sweep_kg,
                          iteration_caps=a.iteration_caps, max_iter=cfg.problems.cr3bp.solver.max_iter,
                          n_boot=a.n_boot, seed=a.seed, break_even_solutions=a.break_even_solutions,
                          train_alphas=cfg.problems.cr3bp.alphas.train_values(),
                          eta=cfg.cr3bp_analysis.params.diversity.eta)


def upfront_cpu(alpha_tables: list[str], train_alphas, training_reports: list[str]) -> dict[str, float]:
    """Arm → CPU seconds spent before the first new α: every solve at the training α (the data the reuse
    baselines draw from and the models learn from), plus, for the learned arms, the training CPU of the
    models they load (:attr:`~amorgs.ablation.arms.Arm.models`, the models of the main training seed).  An arm
    that draws on neither (uniform multi-start) needs nothing."""
    import pandas as pd

    from amorgs.alphas import rows_at_any
    from amorgs.data.io import read_json

    data_s = sum(float(rows_at_any(pd.read_parquet(p, columns=["alpha", "cpu_s"]), train_alphas)["cpu_s"].sum())
                 for p in alpha_tables)
    training = {r["model"]: float(r["train_cpu_s"]) for r in map(read_json, training_reports)}
    return {s: data_s + sum(training.get(m, 0.0) for m in get_arm(s).models) if get_arm(s).upfront else 0.0
            for s in SAMPLER_NAMES}


def run_report(job: Job, run) -> None:
    use_agg()
    import pandas as pd

    from amorgs.ablation.report import markdown_table, summarize
    from amorgs.ablation.studies import STUDIES
    from amorgs.models.names import resolve
    from amorgs.data.io import atomic_path, write_json
    from amorgs.figures.ablation import ablation_figures

    s: ReportSettings = job.settings
    cells = job.input["cells"]
    truth = pd.read_parquet(job.input["high_quality"])
    run.log_params({"cells": len(cells)})
    run.log_dataset(truth, job.input["high_quality"], "evaluation")  # the ground truth at the test α
    upfront = upfront_cpu(job.input.get("alpha_tables", []), s.train_alphas, job.input.get("training_reports", []))
    run.log_metrics({f"upfront_cpu_h/{arm}": v / 3600 for arm, v in upfront.items()})
    report = summarize(pd.concat([pd.read_parquet(p) for p in cells], ignore_index=True), truth, s.beta_kg,
                       n_boot=s.n_boot, seed=s.seed, beta_sweep=s.beta_sweep_kg, iteration_caps=s.iteration_caps,
                       max_iter=s.max_iter, upfront_cpu_s=upfront, break_even_solutions=s.break_even_solutions,
                       eta=s.eta)
    by_name = {os.path.basename(p): p for p in job.output["tables"]}
    for study in STUDIES:
        table = report.tables[study.name]
        if table.columns.empty:  # a study the config did not ask for: say so rather than leave an empty file
            table = pd.DataFrame({"status": [f"not requested by the config ({study.name})"]})
        with atomic_path(by_name[f"{study.stem}.csv"]) as tmp:
            table.to_csv(tmp, index=False)
        if study.markdown or study.title:
            text = (resolve(study.markdown)(table) + "\n" if study.markdown
                    else markdown_table(table, f"**{study.title}**"))
            with atomic_path(by_name[f"{study.stem}.md"]) as tmp:
                tmp.write_text(text)
    write_json(report.metrics, job.output["summary"])
    run.log_metrics(finite_metrics(report.metrics))
    for path in [job.output["summary"], *job.output["tables"]]:
        run.log_artifact(path, "tables")
    write_figures(ablation_figures(report), job.output["figures"], run)
    print(f"{job.output['summary']}: {len(report.metrics)} metrics over {len(cells)} cells")


STAGE = 7
STEPS = (
    Step("ablation_cell", CellSettings, _cell_settings, run_cell, cell_jobs,
         lambda w: {"table": layout.ABLATION_CELL.format_map(w)},
         resources=lambda cfg, w: cfg.ablation.job(),
         description="solve the guesses of one sampler at one test α → cell table"),
    Step("ablation_cell_replicate", CellSettings, _cell_settings, run_cell, replicate_cell_jobs,
         lambda w: {"table": layout.ABLATION_REPLICATE_CELL.format_map(w)},
         resources=lambda cfg, w: cfg.ablation.job(),
         description="a cell with the models of an extra training seed"),
    Step("ablation_cell_fraction", CellSettings, _cell_settings, run_cell, fraction_cell_jobs,
         lambda w: {"table": layout.ABLATION_FRACTION_CELL.format_map(w)},
         resources=lambda cfg, w: cfg.ablation.job(),
         description="a learned arm with models trained on a fraction of the data (learning curve)"),
    Step("ablation_report", ReportSettings, _report_settings, run_report, once_if("ablation"),
         lambda w: {"summary": layout.ABLATION_SUMMARY,
                    "tables": [layout.TABLE.format(name=n) for n in table_files()],
                    "figures": [layout.FIGURE.format(name=n) for n in layout.ABLATION_FIGURES]},
         resources=resources_of("figure"),
         report=("ablation", "CR3BP ablation"),
         description="Table 6, capped studies, coverage, rates, β sweep, aRT, anytime curves; Figs. 21–23"),
)
