"""Where the workflow's time goes (issue 40 §1): a table and a figure per rule and per job, from the
``benchmark:`` file Snakemake writes for every job (``results/benchmarks/<rule>/<wildcards>.tsv``: wall seconds
``s``, CPU seconds ``cpu_time``, peak resident memory ``max_rss`` in MB, ``mean_load`` in % of one core).

Written when the workflow finishes (Snakemake's ``onsuccess``, :func:`write_runtime_report`) and logged to the
invocation's MLflow parent run; every job whose benchmark file is present counts, so a resumed run reports the
whole workflow, each job at its latest execution.  Pure functions but the last.
"""

from __future__ import annotations

from pathlib import Path

import pandas as pd

from amorgs import layout

#: The columns of Snakemake's benchmark files that the report reads.
BENCHMARK_COLUMNS = ("s", "cpu_time", "max_rss", "mean_load")


def read_benchmarks(root: str | Path = layout.BENCHMARK_DIR) -> pd.DataFrame:
    """One row per job: ``rule`` (the first folder under ``root``), ``job`` (the rest of the path, its
    wildcards), ``wall_s``, ``cpu_s``, ``max_rss_mb``, ``mean_load_pct`` (the last line of the file: a job's
    latest execution).  Empty (with those columns) when there is none."""
    rows = []
    for path in sorted(Path(root).glob("*/**/*.tsv")):
        table = pd.read_csv(path, sep="\t")
        if table.empty or not set(BENCHMARK_COLUMNS) <= set(table.columns):
            continue
        last = table.iloc[-1]
        rel = path.relative_to(root)
        rows.append({"rule": rel.parts[0], "job": str(Path(*rel.parts[1:]).with_suffix("")),
                     "wall_s": float(last["s"]), "cpu_s": float(last["cpu_time"]),
                     "max_rss_mb": float(last["max_rss"]) if last["max_rss"] != "NA" else float("nan"),
                     "mean_load_pct": float(last["mean_load"])})
    return pd.DataFrame(rows, columns=["rule", "job", "wall_s", "cpu_s", "max_rss_mb", "mean_load_pct"])


def runtime_by_rule(jobs: pd.DataFrame) -> pd.DataFrame:
    """Per rule, the most expensive first: ``jobs``, ``wall_min`` (summed over its jobs: job-minutes),
    ``cpu_min``, ``median_wall_s`` and ``max_wall_s`` per job, ``max_rss_mb``, and its share of all CPU."""
    if jobs.empty:
        return pd.DataFrame(columns=["rule", "jobs", "wall_min", "cpu_min", "median_wall_s", "max_wall_s",
                                     "max_rss_mb", "cpu_share"])
    g = jobs.groupby("rule")
    out = pd.DataFrame({"jobs": g.size(), "wall_min": g["wall_s"].sum() / 60, "cpu_min": g["cpu_s"].sum() / 60,
                        "median_wall_s": g["wall_s"].median(), "max_wall_s": g["wall_s"].max(),
                        "max_rss_mb": g["max_rss_mb"].max()}).reset_index()
    out["cpu_share"] = out["cpu_min"] / out["cpu_min"].sum() if out["cpu_min"].sum() > 0 else 0.0
    return out.sort_values(["cpu_min", "rule"], ascending=[False, True], ignore_index=True)


def write_runtime_report(root: str | Path = layout.BENCHMARK_DIR, run=None) -> list[Path]:
    """Write the per-rule table (CSV, Markdown), the per-job table and the figure (:data:`amorgs.layout`
    ``RUNTIME_*``), log them to ``run`` (a :class:`amorgs.tracking.JobRun`, optional) with the totals as metrics;
    return the paths written (none without benchmark files)."""
    from amorgs.ablation.report import markdown_table
    from amorgs.data.io import atomic_path
    from amorgs.figures.runtime import fig_runtime_by_rule

    jobs = read_benchmarks(root)
    if jobs.empty:
        return []
    rules = runtime_by_rule(jobs)
    paths = [Path(p) for p in (layout.RUNTIME_TABLE, layout.RUNTIME_JOBS, layout.RUNTIME_MARKDOWN,
                               layout.RUNTIME_FIGURE)]
    for path, write in ((paths[0], lambda t: rules.to_csv(t, index=False)),
                        (paths[1], lambda t: jobs.to_csv(t, index=False)),
                        (paths[2], lambda t: t.write_text(markdown_table(
                            rules, f"**Runtime per rule: {len(jobs)} jobs, {jobs['wall_s'].sum() / 60:.1f} job-minutes "
                                   f"wall, {jobs['cpu_s'].sum() / 60:.1f} CPU-minutes**"))),
                        (paths[3], lambda t: fig_runtime_by_rule(rules).savefig(t, format="png", dpi=110))):
        with atomic_path(path) as tmp:
            write(tmp)
    if run is not None:
        run.log_metrics({"runtime/jobs": len(jobs), "runtime/job_wall_min": jobs["wall_s"].sum() / 60,
                         "runtime/cpu_min": jobs["cpu_s"].sum() / 60,
                         **{f"runtime/cpu_min/{r.rule}": r.cpu_min for r in rules.itertuples()}})
        for path in paths:
            run.log_artifact(path, "runtime")
    return paths


def report_finished_workflow(tracked: bool) -> None:
    """Snakemake's ``onsuccess``: write the runtime report and, when ``tracked``, log it to the invocation's
    parent run.  A failure here is a warning: the workflow's own outputs are complete."""
    import sys

    from amorgs import tracking

    try:
        run = tracking.invocation_run() if tracked else None
        paths = write_runtime_report(run=run)
        if run is not None:
            run.flush()
        if paths:
            print(f"amorgs: runtime per rule in {paths[2]} and {paths[3]}", file=sys.stderr)
    except Exception as exc:  # noqa: BLE001 — a report of the run never fails the run
        print(f"amorgs: the runtime report failed: {type(exc).__name__}: {exc}", file=sys.stderr)
