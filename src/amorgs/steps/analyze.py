"""The structure of the CR3BP solution set (paper Sec. III.B): hyperplanes, funnels, moving averages,
diversity and control statistics as tables and metrics (:mod:`amorgs.analysis.structure_report`), Figs. 3–13
drawn from them (:func:`amorgs.figures.structure.structure_figures`)."""

from __future__ import annotations

from amorgs import layout
from amorgs.analysis.structure_params import StructureParams
from amorgs.config import Config, Section
from amorgs.steps import Job, Step, Wildcards, once_if, resources_of
from amorgs.steps.outputs import by_name, finite_metrics, use_agg, write_figures


class AnalyzeSettings(Section):
    """β (kg) of a high-quality solution and the analysis parameters (``cr3bp_analysis.params``)."""

    beta_kg: float
    params: StructureParams


def _settings(cfg: Config, w: Wildcards) -> AnalyzeSettings:
    return AnalyzeSettings(beta_kg=cfg.problems.cr3bp.filter.min_final_mass_kg, params=cfg.cr3bp_analysis.params)


def run_analyze(job: Job, run) -> None:
    use_agg()
    import pandas as pd

    from amorgs.analysis.structure_report import analyze
    from amorgs.data.io import write_json, write_parquet
    from amorgs.figures.structure import structure_figures

    s: AnalyzeSettings = job.settings
    solutions = pd.concat([pd.read_parquet(p) for p in job.input["solutions"]], ignore_index=True)
    result = analyze(solutions, pd.read_parquet(job.input["high_quality"]), s.beta_kg, s.params)
    paths = by_name(job.output["tables"], result.tables, ".parquet", "analysis tables")
    for name, table in result.tables.items():
        write_parquet(table, paths[name])
    write_json(result.metrics, job.output["metrics"])
    run.log_metrics(finite_metrics(result.metrics))
    run.log_artifact(job.output["metrics"])
    write_figures(structure_figures(result), job.output["figures"], run)
    print(f"{job.output['metrics']}: {len(result.metrics)} metrics, {len(result.tables)} tables")


STAGE = 4
STEPS = (
    Step("analyze_cr3bp", AnalyzeSettings, _settings, run_analyze, once_if("cr3bp_analysis"),
         lambda w: {"metrics": layout.CR3BP_ANALYSIS_METRICS,
                    "tables": [layout.CR3BP_ANALYSIS_TABLE.format(name=n) for n in layout.ANALYSIS_TABLES],
                    "figures": [layout.FIGURE.format(name=n) for n in layout.ANALYSIS_FIGURES]},
         resources=resources_of("analyze"),
         report=("cr3bp_structure", "CR3BP structure"),
         description="structure analysis of the CR3BP solutions; Figs. 3–13"),
)
