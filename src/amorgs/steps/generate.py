"""Stage 1: multi-start local solves of one (problem, α, shard), and the merge of one (problem, α)."""

from __future__ import annotations

import time
from typing import Annotated, Any, Literal, Union

from pydantic import Field, model_validator

from amorgs import layout
from amorgs.alphas import alpha_label
from amorgs.config import Config, Section
from amorgs.data.seeds import shard_seed
from amorgs.problems import FAMILIES, PROBLEMS
from amorgs.solvers.options import as_options
from amorgs.steps import Job, Step, Wildcards, resources_of

#: Any family's solver options: the union of the families' ``options_type``.
SolverOptions = Union[tuple(dict.fromkeys(f.options_type for f in FAMILIES.values()))]  # noqa: UP007


#: A shard of a family with quick solves (``Family.quick_solves``) and at most this many starts does seconds of
#: work (De Jong: ≈ 1.6 s of solving per 300 starts), so its MLflow run is deferred (:attr:`Step.deferred_tracking`);
#: a larger shard opens its run while it works, so that it is seen RUNNING.
QUICK_SHARD_STARTS = 500


class GenerateSettings(Section):
    """One shard: ``starts`` uniform starts at the exact ``alpha`` with ``seed`` (derived from the config's
    base seed, the problem, α and the shard index) and the problem's solver options (validated as its family's
    ``options_type``)."""

    problem: Literal[PROBLEMS]  # type: ignore[valid-type]
    alpha: float
    seed: Annotated[int, Field(ge=0)]
    starts: Annotated[int, Field(ge=1)]
    solver: SolverOptions = Field(description="the options of the problem's solver, an instance of its family's "
                                              "options_type (converted from a mapping by the problem it names)")

    @model_validator(mode="before")
    @classmethod
    def _solver_of_the_problem(cls, data: Any) -> Any:
        if isinstance(data, dict) and data.get("problem") in FAMILIES and "solver" in data:
            data = {**data, "solver": as_options(FAMILIES[data["problem"]].options_type, data["solver"])}
        return data


def generate_settings(cfg: Config, w: Wildcards) -> GenerateSettings:
    problem = getattr(cfg.problems, w["problem"])
    alpha = problem.alpha_values()[w["alpha"]]
    return GenerateSettings(problem=w["problem"], alpha=alpha, seed=shard_seed(cfg.seed, w["problem"], alpha, int(w["shard"])),
                            starts=problem.generate.starts_per_shard, solver=problem.solver)


def generate_jobs(cfg: Config) -> list[dict[str, str]]:
    return [{"problem": name, "alpha": label, "shard": str(k)}
            for name, problem in cfg.problems.enabled().items()
            for label in problem.alpha_values()
            for k in range(problem.generate.shards)]


def run_generate(job: Job, run) -> None:
    from amorgs.data.io import write_parquet
    from amorgs.data.tables import validate_solutions
    from amorgs.problems import get_problem
    from amorgs.solvers.multistart import run_multistart

    s: GenerateSettings = job.settings
    output = job.output["table"]
    t0 = time.perf_counter()
    problem = get_problem(s.problem)
    df = run_multistart(problem, s.alpha, s.seed, s.starts, job.threads, s.solver, progress=True)
    df.insert(int(df.columns.get_loc("seed")) + 1, "shard", int(job.wildcards["shard"]))
    validate_solutions(df, problem.variable_names, where=output)
    write_parquet(df, output)
    conv = df[df["converged"]]
    run.log_metrics({
        "starts": len(df),
        "converged": len(conv),
        "converged_fraction": len(conv) / len(df),
        "objective_best": conv["objective"].min() if len(conv) else None,
        "iterations_median": conv["iterations"].median() if len(conv) else None,
        "solve_wall_s_total": df["wall_s"].sum(),
        "solve_cpu_s_total": df["cpu_s"].sum(),
        "job_wall_s": time.perf_counter() - t0,
    })
    print(f"{output}: {len(df)} solves, {len(conv)} converged")


class MergeSettings(Section):
    """The merge of one (problem, α): the fresh shards, plus (with ``library_enabled``) the library files of
    that α under ``library_path`` — all rows, or the first ``library_max_rows``."""

    problem: Literal[PROBLEMS]  # type: ignore[valid-type]
    library_enabled: bool
    library_path: str
    library_max_rows: Annotated[int, Field(ge=1)] | None


def merge_settings(cfg: Config, w: Wildcards) -> MergeSettings:
    library = getattr(cfg.problems, w["problem"]).library
    return MergeSettings(problem=w["problem"], library_enabled=library.enabled, library_path=library.path,
                         library_max_rows=library.max_rows_per_alpha)


def merge_jobs(cfg: Config) -> list[dict[str, str]]:
    return [{"problem": name, "alpha": label} for name, problem in cfg.problems.enabled().items()
            for label in problem.alpha_values()]


def run_merge(job: Job, run) -> None:
    import pandas as pd

    from amorgs.data.io import write_parquet
    from amorgs.data.library import SOURCE_FRESH, SOURCE_LIBRARY, read_library_file, read_table, tag_source
    from amorgs.data.tables import merge_shards, validate_solutions

    s: MergeSettings = job.settings
    output, label = job.output["table"], job.wildcards["alpha"]
    fresh_paths, library_paths = job.input["fresh"], job.input.get("library", [])
    fresh = tag_source(merge_shards(read_table(p) for p in fresh_paths), SOURCE_FRESH)
    parts = [fresh]
    if library_paths:
        library = merge_shards(read_library_file(p, s.library_path, s.problem) for p in library_paths)
        if s.library_max_rows is not None:
            library = library.head(s.library_max_rows)
        parts.insert(0, tag_source(library, SOURCE_LIBRARY))
    df = pd.concat(parts, ignore_index=True)
    validate_solutions(df, where=output)
    wrong = df[(df["problem"] != s.problem) | (df["alpha"].map(alpha_label) != label)]
    if len(wrong):
        raise ValueError(f"{output}: {len(wrong)} row(s) are not {s.problem} at alpha={label}")
    write_parquet(df, output)
    run.log_metrics({"shards": len(fresh_paths), "library_files": len(library_paths), "rows": len(df),
                     "rows_library": len(df) - len(fresh), "converged": int(df["converged"].sum())})
    print(f"{output}: {len(df)} rows from {len(fresh_paths)} fresh shard(s) and {len(library_paths)} library file(s)")


STAGE = 1
STEPS = (
    Step("generate", GenerateSettings, generate_settings, run_generate, generate_jobs,
         lambda w: {"table": layout.SHARD.format_map(w)},
         resources=lambda cfg, w: getattr(cfg.problems, w["problem"]).generate.job(),
         description="multi-start solves of one (problem, α, shard) → shard table",
         deferred_tracking=lambda s: FAMILIES[s.problem].quick_solves and s.starts <= QUICK_SHARD_STARTS),
    Step("merge", MergeSettings, merge_settings, run_merge, merge_jobs,
         lambda w: {"table": layout.ALPHA_TABLE.format_map(w)},
         resources=resources_of("merge"),
         description="the shards of one (problem, α) and its library files → α table",
         deferred_tracking=lambda s: True),
)
