"""``amorgs check-outputs``: does the results tree hold everything a config promises?

Every output must exist and be non-empty; solution tables must pass the table schema and hold rows (ablation
cells: the key columns, ``sampler``, ``converged``, ``wall_s``); the ablation's statistics tables must have
``alpha`` and ``sampler`` columns and rows, and its summary the expected-running-time metrics;
figures must be PNG files; JSON must parse; and, with MLflow enabled, every job of the config must have a
FINISHED run in the store (from this or an earlier invocation), every figure must be logged as an
artifact, and the latest workflow run must have FINISHED.
"""

from __future__ import annotations

import json
from pathlib import Path

import pandas as pd

from amorgs import layout
from amorgs.config import Config, alpha_label
from amorgs.data.tables import validate_solutions

_PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
#: Figures drawn by a rule of their own (the others come out of analyze_cr3bp, predict_cr3bp, ablation_report).
_FIGURE_RULES = ("fig02_foxholes", "fig16_dejong_predictions")


def expected_jobs(cfg: Config) -> list[tuple[str, dict[str, str]]]:
    """(rule, wildcards) of every job a complete run of ``cfg`` executes."""
    jobs: list[tuple[str, dict[str, str]]] = []
    for name, problem in cfg.problems.enabled().items():
        for label in problem.alpha_values():
            jobs += [("generate", {"problem": name, "alpha": label, "shard": str(k)}) for k in range(problem.generate.shards)]
            jobs.append(("merge", {"problem": name, "alpha": label}))
        jobs.append(("filter", {"problem": name}))
    if cfg.dejong_cvae.enabled:
        jobs += [(rule, {"problem": "dejong", "model": "cvae_gmm"}) for rule in ("train_dejong_cvae", "predict_dejong_cvae")]
    if cfg.cr3bp_analysis.enabled:
        jobs.append(("analyze_cr3bp", {"problem": "cr3bp"}))
    if cfg.cr3bp_models.enabled:
        jobs += [("train_cr3bp", {"problem": "cr3bp", "model": m}) for m in layout.CR3BP_MODELS]
        jobs += [
            ("train_cr3bp_fraction", {"problem": "cr3bp", "model": "cvae_gmm", "fraction": layout.fraction_label(f)})
            for f in cfg.cr3bp_models.data_fractions
        ]
        jobs.append(("predict_cr3bp", {"problem": "cr3bp"}))
    if cfg.ablation.enabled:
        jobs += [
            ("ablation_cell", {"alpha": alpha_label(a), "sampler": s})
            for a in cfg.problems.cr3bp.alphas.test
            for s in cfg.ablation.samplers
        ]
        from amorgs.ablation.arms import NEEDS_MODELS

        needed = sorted({m for s in cfg.ablation.samplers for m in NEEDS_MODELS[s]})
        jobs += [
            ("train_cr3bp_replicate", {"problem": "cr3bp", "model": name, "mseed": str(m)})
            for m in cfg.cr3bp_models.extra_seeds
            for name in needed
        ]
        jobs += [
            ("ablation_cell_replicate", {"alpha": alpha_label(a), "sampler": s, "mseed": str(m)})
            for m in cfg.cr3bp_models.extra_seeds
            for a in cfg.problems.cr3bp.alphas.test
            for s in cfg.ablation.samplers
        ]
        jobs.append(("ablation_report", {}))
    jobs += [(name, {}) for name in layout.figure_names(cfg) if name in _FIGURE_RULES]
    return jobs


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
            if path == layout.ABLATION_SUMMARY and not any(k.startswith("aRT_iterations_") for k in data):
                return f"{path}: no expected-running-time metrics (aRT_iterations_*)"
        if p.suffix == ".csv" and Path(path).name.startswith("ablation_") and "iteration_capped" not in path:
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
    files = list(layout.targets(cfg))
    for name in cfg.problems.enabled():
        files += layout.alpha_tables(cfg, name)
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
    for rule, wildcards in expected_jobs(cfg):
        if (rule, json.dumps(wildcards, sort_keys=True)) not in finished:
            problems.append(f"MLflow: no FINISHED run of {rule} {wildcards}")
    logged = {Path(a).name for j in store["jobs"] for a in j["artifacts"]}
    for name in layout.figure_names(cfg):
        if f"{name}.png" not in logged:
            problems.append(f"MLflow: figure {name}.png is not logged")
    return problems
