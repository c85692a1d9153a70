"""Stage 2: the problem's quality filter (the β-filter of the CR3BP) over every α table of a problem, with a
per-α quality report."""

from __future__ import annotations

import dataclasses
from typing import Literal

from pydantic import model_validator

from amorgs import layout
from amorgs.alphas import metric_key
from amorgs.config import Config, Section
from amorgs.problems import PROBLEMS, QualityFilter, get_family
from amorgs.steps import Job, Step, Wildcards, resources_of


class FilterSettings(Section):
    """The quality filter of ``problem`` (its family's ``quality_type``, :meth:`quality`): its thresholds sit
    flat beside the problem, one field per threshold of every family — m_f ≥ ``min_final_mass_kg`` (kg, CR3BP),
    objective ≤ ``max_objective`` (De Jong) —, the other families' null.  Flat, so that the settings of the
    filter jobs of earlier runs keep their JSON and those jobs do not rerun; a family whose filter has a
    threshold of a new name adds a field here."""

    problem: Literal[PROBLEMS]  # type: ignore[valid-type]
    min_final_mass_kg: float | None = None
    max_objective: float | None = None

    def quality(self) -> QualityFilter:
        """The problem's quality filter with these thresholds."""
        quality_type = get_family(self.problem).quality_type
        own = {f.name for f in dataclasses.fields(quality_type)}  # type: ignore[arg-type]
        return quality_type.from_mapping({k: v for k, v in self if k in own})

    @model_validator(mode="after")
    def _thresholds_of_the_problem(self) -> FilterSettings:
        own = {f.name for f in dataclasses.fields(get_family(self.problem).quality_type)}  # type: ignore[arg-type]
        foreign = [k for k, v in self if k != "problem" and k not in own and v is not None]
        if foreign:
            raise ValueError(f"filter of {self.problem}: {foreign} are thresholds of another problem's filter")
        self.quality()
        return self


def filter_settings(cfg: Config, w: Wildcards) -> FilterSettings:
    return FilterSettings(problem=w["problem"], **getattr(cfg.problems, w["problem"]).filter.to_dict())


def run_filter(job: Job, run) -> None:
    import pandas as pd

    from amorgs.data.filter import quality_report
    from amorgs.data.io import write_json, write_parquet

    s: FilterSettings = job.settings
    quality = s.quality()
    tables = {path: pd.read_parquet(path) for path in job.input["tables"]}
    for path, table in tables.items():
        run.log_dataset(table, path, "training")
    df = pd.concat(tables.values(), ignore_index=True)
    hq = quality.select(df)
    report = {"problem": s.problem, **quality_report(df, hq, quality.to_dict())}
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
         description="the problem's quality filter (β) over every α table → high-quality table + quality report"),
)
