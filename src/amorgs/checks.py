"""``amorgs check-outputs``: does the results tree hold everything a config promises?

Every output must exist and be non-empty; solution tables must pass the table schema and hold rows (ablation
cells: the key columns, ``sampler``, ``converged``, ``wall_s``); the ablation's statistics tables must have
``alpha`` and ``sampler`` columns and rows, and its summary the expected-running-time metrics;
figures must be PNG files; JSON must parse; and, with MLflow enabled, every job of the config must have a
FINISHED run in the store (from this or an earlier invocation; the jobs and their outputs are those of
:func:`amorgs.steps.expected_jobs` and :func:`amorgs.steps.targets`), every figure must be logged as an
artifact, and the latest workflow run must have FINISHED.
"""

from __future__ import annotations

import json
from pathlib import Path

import pandas as pd

from amorgs import layout, steps
from amorgs.ablation.studies import OPTIONAL_STEMS
from amorgs.config import Config
from amorgs.data.tables import validate_solutions

_PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"



def _check_file(path: str) -> str | None:
    p = Path(path)
    if not p.is_file():
        return f"{path}: missing"
    if p.stat().st_size == 0:
        return f"{path}: empty file"
    try:
        if p.suffix == ".png" and not p.read_bytes().startswith(_PNG_SIGNATURE):
            return f"{path}: not a PNG image"
        if p.suffix == ".json":
            data = json.loads(p.read_text())
            if path == layout.ABLATION_SUMMARY and not any(k.startswith("aRT_iterations/") for k in data):
                return f"{path}: no expected-running-time metrics (aRT_iterations/*)"
        if p.suffix == ".csv" and Path(path).stem in OPTIONAL_STEMS:
            pass  # empty when the config asks for none of it (no caps, no break-even, no learning curve)
        elif p.suffix == ".csv" and Path(path).name.startswith("ablation_"):
            df = pd.read_csv(p)
            missing = [c for c in ("alpha", "sampler") if c not in df.columns]
            if missing or df.empty:
                return f"{path}: ablation table lacks column(s) {missing} or rows"
        if p.suffix == ".parquet" and "/ablation/" in path:
            df = pd.read_parquet(p)
            missing = [c for c in ("problem", "alpha", "seed", "start", "sampler", "converged", "wall_s") if c not in df.columns]
            if missing:
                return f"{path}: ablation cell lacks column(s) {missing}"
            if df.empty:
                return f"{path}: no rows"
        if p.suffix == ".parquet" and "/solutions/" in path:
            df = pd.read_parquet(p)
            validate_solutions(df, where=path)
            if df.empty:
                return f"{path}: no rows"
    except (ValueError, pd.errors.EmptyDataError) as exc:
        return f"{path}: {exc}"
    return None


#: The one problem reported when the outputs are complete but the MLflow store is gone (exit status 3).
UNTRACKED = (
    "MLflow: no tracking store (results/mlflow/ was deleted or never written): the outputs are untracked. "
    "The files are the source of truth, only the MLflow history is lost; rerun the jobs to track them "
    "(snakemake --forceall), or check the files alone with --no-mlflow"
)


def check_outputs(cfg: Config, tracked: bool = True) -> list[str]:
    """Every problem found with the outputs of ``cfg`` (an empty list when all is well)."""
    files = steps.targets(cfg)
    problems = [msg for msg in map(_check_file, files) if msg]
    for name in cfg.problems.enabled():
        path = layout.HIGH_QUALITY.format(problem=name)
        if Path(path).is_file():
            try:
                validate_solutions(pd.read_parquet(path), where=path)
            except ValueError as exc:
                problems.append(str(exc))
    if tracked and cfg.mlflow.enabled:
        problems += _check_tracking(cfg)
    return problems


def _check_tracking(cfg: Config) -> list[str]:
    from amorgs import tracking

    try:
        store = tracking.tracked_jobs()
    except FileNotFoundError:
        return [UNTRACKED]
    problems = []
    if store["parent_status"] != "FINISHED":
        problems.append(f"MLflow: the latest workflow run is {store['parent_status']}, not FINISHED")
    finished = {(j["rule"], json.dumps(j["wildcards"], sort_keys=True)) for j in store["jobs"] if j["status"] == "FINISHED"}
    for rule, wildcards in steps.expected_jobs(cfg):
        if (rule, json.dumps(wildcards, sort_keys=True)) not in finished:
            problems.append(f"MLflow: no FINISHED run of {rule} {wildcards}")
    logged = {Path(a).name for j in store["jobs"] for a in j["artifacts"]}
    for figure in (Path(p).name for p in steps.targets(cfg) if p.endswith(".png")):
        if figure not in logged:
            problems.append(f"MLflow: figure {figure} is not logged")
    return problems
