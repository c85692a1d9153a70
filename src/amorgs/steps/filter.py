"""Stage 2: the β-filter over every α table of a problem, with a per-α quality report."""

from __future__ import annotations

from typing import Literal

from amorgs import layout
from amorgs.alphas import metric_key
from amorgs.config import Config, Section
from amorgs.problems import PROBLEMS
from amorgs.steps import Job, Step, Wildcards, resources_of


class FilterSettings(Section):
    """Keep converged solves with m_f ≥ ``min_final_mass_kg`` (kg, CR3BP) and/or objective ≤ ``max_objective``
    (De Jong); a threshold set to null is not applied."""

    problem: Literal[PROBLEMS]  # type: ignore[valid-type]
    min_final_mass_kg: float | None = None
    max_objective: float | None = None


def filter_settings(cfg: Config, w: Wildcards) -> FilterSettings:
    return FilterSettings(problem=w["problem"], **getattr(cfg.problems, w["problem"]).filter_thresholds())


def run_filter(job: Job, run) -> None:
    import pandas as pd

    from amorgs.data.filter import high_quality, quality_report
    from amorgs.data.io import write_json, write_parquet

    s: FilterSettings = job.settings
    thresholds = {"min_final_mass_kg": s.min_final_mass_kg, "max_objective": s.max_objective}
    tables = {path: pd.read_parquet(path) for path in job.input["tables"]}
    for path, table in tables.items():
        run.log_dataset(table, path, "training")
    df = pd.concat(tables.values(), ignore_index=True)
    hq = high_quality(df, **thresholds)
    report = {"problem": s.problem, **quality_report(df, hq, thresholds)}
    write_parquet(hq, job.output["table"])
    write_json(report, job.output["report"])
    run.log_metrics({"rows": report["n"], "converged": report["converged"], "high_quality": report["high_quality"]})
    for entry in report["per_alpha"]:
        run.log_metrics({metric_key(k, entry["alpha"]): v for k, v in entry.items() if k != "alpha"})
    run.log_artifact(job.output["report"])
    print(f"{job.output['table']}: {len(hq)} high-quality of {len(df)} solves")


STAGE = 2
STEPS = (
    Step("filter", FilterSettings, filter_settings, run_filter,
         lambda cfg: [{"problem": name} for name in cfg.problems.enabled()],
         lambda w: {"table": layout.HIGH_QUALITY.format_map(w), "report": layout.QUALITY_REPORT.format_map(w)},
         resources=resources_of("filter"),
         description="β-filter every α table of a problem → high-quality table + quality report"),
)
