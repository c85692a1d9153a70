"""The frontier study around the workflow (issue 21 §1): ``amorgs frontier-plan`` writes one config per design
fold and the command that runs it; ``amorgs frontier`` aggregates the finished fold runs.

A *fold* is one ordinary run of the workflow (the same Snakefile, the same DAG) in its own directory
``<runs>/<fold>/`` with its own ``config.yaml``: the base config (``config/frontier.yaml``) with
``problems.cr3bp.alphas`` replaced by the fold's training and test α (:mod:`amorgs.ablation.frontier`), the
library path made absolute (the run's working directory is the fold's directory) and any ``--set`` overrides
applied; the config is validated before it is written.  A finished fold directory therefore holds everything
the aggregation reads: its config (training α, β, η, which cells exist) and its ``results/`` tree.

The aggregation writes ``frontier.csv`` / ``frontier.md`` (:func:`amorgs.ablation.frontier.frontier_table`)
and ``fig_frontier.png`` (:func:`amorgs.figures.frontier.fig_frontier`) under ``--dest`` and mirrors them to
MLflow: one standalone run in experiment :data:`EXPERIMENT`, its metrics the ratios learned ÷ reuse.
"""

from __future__ import annotations

import copy
import shlex
from pathlib import Path

import pandas as pd
import yaml

from amorgs import steps
from amorgs.ablation.arms import REUSE_ARM
from amorgs.ablation.frontier import Fold, FrontierRun, frontier_metrics, frontier_table, leave_one_out, sparse_grid
from amorgs.config import effective_mapping, from_mapping, load_config, read_yaml
from amorgs.errors import ConfigError, InputError

#: MLflow experiment of the aggregation's standalone runs.
EXPERIMENT = "amorgs-frontier"
#: The config file of a fold inside its run directory.
RUN_CONFIG = "config.yaml"
#: What the aggregation writes under its destination.
OUTPUTS = ("frontier.csv", "frontier.md", "fig_frontier.png")
#: Fewest bootstrap resamples the frontier accepts for its 95 % intervals (the 2.5 and 97.5 percentiles).
MIN_BOOTSTRAP = 100


def library_alphas(library_dir: str | Path, problem: str = "cr3bp") -> list[float]:
    """The α of the library's manifest (N), ascending."""
    from amorgs.data.library import read_manifest

    manifest = read_manifest(library_dir, problem)
    if manifest is None:
        raise InputError(f"{library_dir}/{problem}: no library manifest (provenance.json)")
    return sorted(float(e["alpha"]) for e in manifest["per_alpha"])


def _set(mapping: dict, assignment: str) -> None:
    """Apply one ``dotted.key=YAML`` override to ``mapping`` in place (the key must exist)."""
    key, sep, text = assignment.partition("=")
    if not sep:
        raise ConfigError(f"--set {assignment!r}: expected dotted.key=value")
    *path, last = key.split(".")
    node = mapping
    for part in path:
        node = node.get(part) if isinstance(node, dict) else None
    if not isinstance(node, dict) or last not in node:
        raise ConfigError(f"--set {assignment!r}: the base config has no key {key}")
    node[last] = yaml.safe_load(text)


def fold_config(base: dict, fold: Fold, library_dir: Path, sets: tuple[str, ...] = ()) -> dict:
    """The full config of ``fold``: ``base`` with the CR3BP training and test α of the fold, the CR3BP library
    at ``library_dir`` (absolute) and the ``sets`` overrides; validated (``ConfigError`` otherwise)."""
    cfg = copy.deepcopy(base)
    cr3bp = cfg["problems"]["cr3bp"]
    cr3bp["alphas"] = {"train": list(fold.train), "test": list(fold.test)}
    cr3bp["library"]["path"] = str(library_dir)
    for s in sets:
        _set(cfg, s)
    from_mapping(cfg, f"fold {fold.name}")
    return cfg


def plan(base_config: str | Path, runs_dir: str | Path, loo: tuple[float, ...] = (), sparse: tuple[int, ...] = (),
         sets: tuple[str, ...] = ()) -> list[tuple[Fold, Path]]:
    """Write ``<runs_dir>/<fold>/config.yaml`` for every leave-one-out α of ``loo`` and every sparse grid size of
    ``sparse`` (folds of the library the base config reads); return (fold, run directory) in that order."""
    load_config(base_config)
    base = effective_mapping(read_yaml(base_config))
    library = Path(base["problems"]["cr3bp"]["library"]["path"]).resolve()
    alphas = library_alphas(library)
    try:
        folds = [leave_one_out(alphas, a) for a in loo] + [sparse_grid(alphas, k) for k in sparse]
    except ValueError as exc:
        raise ConfigError(str(exc)) from None
    if not folds:
        raise ConfigError("no fold: give --loo α … and/or --sparse k …")
    out = []
    for fold in folds:
        run = Path(runs_dir) / fold.name
        run.mkdir(parents=True, exist_ok=True)
        text = (f"# fold {fold.name} of the frontier ({fold.design}), written by `amorgs frontier-plan` from "
                f"{base_config}\n" + yaml.safe_dump(fold_config(base, fold, library, sets), sort_keys=False))
        (run / RUN_CONFIG).write_text(text)
        out.append((fold, run))
    return out


def run_command(run: Path, snakemake: str = "snakemake") -> str:
    """The command that runs one fold: Snakemake in the fold's directory with the fold's config (the
    repository's workflow profile, by the Snakefile's path)."""
    root = Path(__file__).resolve().parents[2]
    run = run.resolve()
    return (f"{snakemake} --snakefile {shlex.quote(str(root / 'workflow' / 'Snakefile'))} "
            f"--workflow-profile {shlex.quote(str(root / 'workflow' / 'profiles' / 'default'))} "
            f"--directory {shlex.quote(str(run))} --configfile {shlex.quote(str(run / RUN_CONFIG))}")


# ------------------------------------------------------------------------------------------- aggregation


def read_run(run_dir: str | Path, design: str | None = None) -> FrontierRun:
    """One finished fold: its config and every cell table its ablation wrote (the main model seed's and the
    replicates'; ``InputError`` naming the first missing one) — from the fold's run directory, or from its
    committed reference (``amorgs reference-export --starts-only``: ``starts.parquet`` holds every cell's starts
    with the columns the statistics read; its files are checked against the manifest first).  ``design``: the design's name (default: the
    run directory's name up to its last ``-``, ``loo`` for ``loo-0.500``; the whole name when it has none)."""
    from amorgs.reference import STARTS_FILE, verify_reference

    run = Path(run_dir)
    config = run / RUN_CONFIG
    if not config.is_file():
        raise InputError(f"{run}: no {RUN_CONFIG} (a fold directory written by `amorgs frontier-plan`, or its "
                         "committed reference)")
    cfg = load_config(config)
    rules = ("ablation_cell", "ablation_cell_replicate")
    cells_of_run = [p for rule in rules for p in steps.outputs_of(rule, cfg, "table")]
    if (run / STARTS_FILE).is_file():  # a committed reference of the fold: its starts, checked against the manifest
        verify_reference(run)
        if cfg.cr3bp_analysis.params.diversity.features != "times":
            raise InputError(f"{config}: the starts keep the solution's times only; η-distinctness with features "
                             f"{cfg.cr3bp_analysis.params.diversity.features!r} needs the fold's run directory")
        starts = pd.read_parquet(run / STARTS_FILE)
        wanted = {p.removeprefix("results/") for p in cells_of_run}
        if set(starts["cell"]) < wanted:
            raise InputError(f"{run / STARTS_FILE}: no starts of {sorted(wanted - set(starts['cell']))[0]}")
        cells = starts[starts["cell"].isin(wanted)].drop(columns="cell").reset_index(drop=True)
    else:
        paths = [run / p for p in cells_of_run]
        missing = [p for p in paths if not p.is_file()]
        if missing or not paths:
            raise InputError(f"{run}: the run is not finished: {missing[0] if missing else 'no ablation cells'} is "
                             "missing")
        cells = pd.concat([pd.read_parquet(p) for p in paths], ignore_index=True)
    name = run.resolve().name
    if design is None:
        design = name.rpartition("-")[0] if name.startswith("loo-") else name
    return FrontierRun(design=design, run=name, train=cfg.problems.cr3bp.alphas.train_values(),
                       beta_kg=cfg.problems.cr3bp.filter.min_final_mass_kg,
                       eta=cfg.cr3bp_analysis.params.diversity.eta, cells=cells)


def aggregate(run_dirs, dest: str | Path, learned: tuple[str, ...] | None = None, reuse: str = REUSE_ARM,
              n_boot: int = 2000, seed: int = 0, track: bool = True, store_dir: str | Path = "results/mlflow"
              ) -> pd.DataFrame:
    """The frontier of the finished fold directories ``run_dirs``: table, Markdown and figure under ``dest``
    (:data:`OUTPUTS`), mirrored to MLflow (unless ``track`` is false) in the store ``store_dir``."""
    from amorgs.ablation.report import markdown_table
    from amorgs.data.io import atomic_path
    from amorgs.figures.frontier import fig_frontier

    from amorgs.ablation.arms import ARMS
    from amorgs.data.io import check_writable_folder

    if n_boot < MIN_BOOTSTRAP:
        raise InputError(f"--n-boot {n_boot}: a 95 % interval needs at least {MIN_BOOTSTRAP} bootstrap resamples")
    arms = [a.name for a in ARMS]
    for option, names in (("--reuse", (reuse,)), ("--learned", learned or ())):
        unknown = [n for n in names if n not in arms]
        if unknown:
            raise InputError(f"{option} {unknown[0]}: not an arm (arms: {', '.join(arms)})")
    check_writable_folder(dest, "--dest")
    runs = [read_run(d) for d in run_dirs]
    table = frontier_table(runs, learned=learned, reuse=reuse, n_boot=n_boot, seed=seed)
    dest = Path(dest)
    dest.mkdir(parents=True, exist_ok=True)
    csv, md, png = (dest / name for name in OUTPUTS)
    with atomic_path(csv) as tmp:
        table.to_csv(tmp, index=False)
    shown = table[(table["unit"] == "iterations")].drop(columns=["run", "nearest_train_alpha"])
    with atomic_path(md) as tmp:
        tmp.write_text(markdown_table(shown, "**The frontier: aRT in IPOPT iterations per high-quality solution "
                                             "(target high_quality) and per new η-distinct optimum (distinct); "
                                             "ratio_to_reuse = aRT(learned) ÷ aRT(reuse), < 1: learning wins; "
                                             "bootstrap 95 %; aRT_oracle: the arm's aRT had it solved only "
                                             "the starts that found something, oracle_to_reuse = aRT_oracle "
                                             "÷ aRT(reuse) (reuse row: the limit of any selector over reuse's "
                                             "candidates)**"))
    figure = fig_frontier(table)
    with atomic_path(png) as tmp:
        figure.savefig(tmp, format="png", dpi=120)
    if track:
        _track(runs, table, (csv, md, png), store_dir, n_boot, seed)
    return table


def _track(runs, table: pd.DataFrame, files, store_dir, n_boot: int, seed: int) -> None:
    from amorgs import tracking

    with tracking.standalone_run("frontier", EXPERIMENT, store_dir) as run:
        run.log_params({"runs": ",".join(r.run for r in runs), "designs": ",".join(sorted({r.design for r in runs})),
                        "n_boot": n_boot, "seed": seed})
        run.log_metrics(frontier_metrics(table))
        for path in files:
            run.log_artifact(path, "frontier")
