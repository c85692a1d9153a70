"""The ``amorgs`` command line: one subcommand per workflow step, plus tools around the workflow.

Workflow steps (each called by one Snakemake rule, each mirrored to MLflow as one child run)::

    generate                  multi-start solves of one (problem, α, shard)      → shard table
    merge                     the shards of one (problem, α)                      → α table
    filter                    every α table of a problem, β-filter                → high_quality + report
    train-dejong-cvae         GMM-prior CVAE on the filtered De Jong minima       → model checkpoint
    predict-dejong-cvae       samples at the test α + hit metrics                 → samples + metrics
    fig02-foxholes, fig16-dejong-predictions   one paper figure each          → results/figures/*.png
    analyze-cr3bp             structure analysis, Figs. 3–13                      → metrics, tables, figures
    train-cr3bp               one CR3BP model on the training α (or a fraction)   → model checkpoint
    predict-cr3bp             samples at the test α vs the ground truth, Figs. 17–20 → samples + metrics
    ablation-cell             one (test α, sampler) warm-start cell               → cell table
    ablation-report           Table 6, capped study, coverage, Figs. 21–23        → tables + summary

Tools: ``library-export`` (check finished library-config shards and consolidate them into the versioned
library, ``data/library``), ``library-grow`` (batches of library generation, each exported),
``boundary-conditions`` (recompute or check ``resources/boundary_conditions.json``), ``ui`` (the
MLflow UI on ``results/mlflow``), ``check-outputs`` (every output a config promises exists, is non-empty
and is tracked).  Heavy imports (solvers, torch, mlflow) happen inside the subcommand that needs them.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time

from amorgs.config import SCHEMA_PATH, ConfigError, alpha_label
from amorgs.errors import InputError


def _alpha_key(alpha: float) -> str:
    """Metric-name suffix for one α (MLflow keys allow no ``=``)."""
    return f"alpha_{alpha_label(alpha)}"


# ----------------------------------------------------------------------------------- workflow steps


def cmd_generate(args: argparse.Namespace) -> None:
    from amorgs import tracking
    from amorgs.data.io import write_parquet
    from amorgs.data.tables import validate_solutions
    from amorgs.problems import get_problem
    from amorgs.solvers.multistart import run_multistart

    options = json.loads(args.solver_options)
    wildcards = {"problem": args.problem, "alpha": alpha_label(args.alpha), "shard": str(args.shard)}
    with tracking.job_run("generate", wildcards) as run:
        run.log_params(
            {"alpha": args.alpha, "seed": args.seed, "starts": args.starts, "workers": args.workers, "solver": options}
        )
        t0 = time.perf_counter()
        df = run_multistart(args.problem, args.alpha, args.seed, args.starts, args.workers, options, progress=True)
        df.insert(int(df.columns.get_loc("seed")) + 1, "shard", args.shard)
        validate_solutions(df, get_problem(args.problem).variable_names, where=args.output)
        write_parquet(df, args.output)
        conv = df[df["converged"]]
        run.log_metrics(
            {
                "starts": len(df),
                "converged": len(conv),
                "converged_fraction": len(conv) / len(df),
                "objective_best": conv["objective"].min() if len(conv) else None,
                "iterations_median": conv["iterations"].median() if len(conv) else None,
                "solve_wall_s_total": df["wall_s"].sum(),
                "solve_cpu_s_total": df["cpu_s"].sum(),
                "job_wall_s": time.perf_counter() - t0,
            }
        )
    print(f"{args.output}: {len(df)} solves, {len(conv)} converged")


def cmd_merge(args: argparse.Namespace) -> None:
    import pandas as pd

    from amorgs import tracking
    from amorgs.data.io import write_parquet
    from amorgs.data.library import SOURCE_FRESH, SOURCE_LIBRARY, read_library_file, read_table, tag_source
    from amorgs.data.tables import merge_shards, validate_solutions

    with tracking.job_run("merge", {"problem": args.problem, "alpha": args.alpha}) as run:
        fresh = tag_source(merge_shards(read_table(p) for p in args.inputs), SOURCE_FRESH)
        parts = [fresh]
        if args.library:
            library = merge_shards(read_library_file(p, args.library_dir, args.problem) for p in args.library)
            if args.library_max_rows is not None:
                library = library.head(args.library_max_rows)
            parts.insert(0, tag_source(library, SOURCE_LIBRARY))
        df = pd.concat(parts, ignore_index=True)
        validate_solutions(df, where=args.output)
        wrong = df[(df["problem"] != args.problem) | (df["alpha"].map(alpha_label) != args.alpha)]
        if len(wrong):
            raise ValueError(f"{args.output}: {len(wrong)} row(s) are not {args.problem} at alpha={args.alpha}")
        write_parquet(df, args.output)
        run.log_metrics(
            {
                "shards": len(args.inputs),
                "library_files": len(args.library),
                "rows": len(df),
                "rows_library": len(df) - len(fresh),
                "converged": int(df["converged"].sum()),
            }
        )
    print(f"{args.output}: {len(df)} rows from {len(args.inputs)} fresh shard(s) and {len(args.library)} library file(s)")


def cmd_filter(args: argparse.Namespace) -> None:
    import pandas as pd

    from amorgs import tracking
    from amorgs.data.filter import high_quality, quality_report
    from amorgs.data.io import write_json, write_parquet

    thresholds = {"min_final_mass_kg": args.min_final_mass_kg, "max_objective": args.max_objective}
    with tracking.job_run("filter", {"problem": args.problem}) as run:
        run.log_params(thresholds)
        tables = {path: pd.read_parquet(path) for path in args.inputs}
        for path, table in tables.items():
            run.log_dataset(table, path, "training")
        df = pd.concat(tables.values(), ignore_index=True)
        hq = high_quality(df, **thresholds)
        report = {"problem": args.problem, **quality_report(df, hq, thresholds)}
        write_parquet(hq, args.output)
        write_json(report, args.report)
        run.log_metrics({"rows": report["n"], "converged": report["converged"], "high_quality": report["high_quality"]})
        for entry in report["per_alpha"]:
            key = _alpha_key(entry["alpha"])
            run.log_metrics({f"{k}/{key}": v for k, v in entry.items() if k != "alpha"})
        run.log_artifact(args.report)
    print(f"{args.output}: {len(hq)} high-quality of {len(df)} solves")


def _dejong_cvae_config(preset: str):
    from amorgs.models.cvae import CVAEConfig

    presets = {"dejong_paper": CVAEConfig.dejong_paper, "small": lambda: CVAEConfig.small(x_dim=2, latent_dim=2, n_components=2)}
    return presets[preset]()


def cmd_train_dejong_cvae(args: argparse.Namespace) -> None:
    import numpy as np
    import pandas as pd
    import torch

    from amorgs import tracking
    from amorgs.data.io import atomic_path
    from amorgs.models import cvae
    from amorgs.models.training import TrainConfig, train
    from amorgs.problems import get_problem

    torch.set_num_threads(args.threads)
    names = list(get_problem("dejong").variable_names)
    df = pd.read_parquet(args.data)
    train_labels = {alpha_label(a) for a in args.train_alphas}
    df = df[df["alpha"].map(alpha_label).isin(train_labels)]
    x = df[names].to_numpy(dtype=np.float64, copy=True)
    alpha = df["alpha"].to_numpy(dtype=np.float64, copy=True)
    with tracking.job_run("train_dejong_cvae", {"problem": "dejong", "model": "cvae_gmm"}) as run:
        cfg = TrainConfig(epochs=args.epochs, batch_size=args.batch_size, lr=args.learning_rate, seed=args.seed, device="cpu")
        run.log_params({"preset": args.preset, "rows": len(df), "train_alphas": len(train_labels), **vars(cfg)})
        run.log_dataset(df, args.data, "training")
        run.start_model("cvae_gmm", {"preset": args.preset, **vars(cfg)})
        torch.manual_seed(args.seed)
        model = cvae.GMMPriorCVAE(_dejong_cvae_config(args.preset), cvae.Normalizer.from_data(x))
        history = train(model, x, alpha, cfg, on_epoch=lambda epoch, metrics: run.log_metrics(metrics, step=epoch))
        with atomic_path(args.output) as tmp:
            cvae.save(model, tmp)
        run.log_metrics({f"final_{k}": v[-1] for k, v in history.items() if k != "epoch"})
        run.finish_model(args.output, step=args.epochs)
    print(f"{args.output}: trained {args.epochs} epochs on {len(df)} minima")


def cmd_predict_dejong_cvae(args: argparse.Namespace) -> None:
    import pandas as pd
    import torch

    from amorgs import tracking
    from amorgs.analysis.dejong_eval import prediction_metrics
    from amorgs.data.io import write_json, write_parquet
    from amorgs.models import cvae
    from amorgs.problems import get_problem

    names = list(get_problem("dejong").variable_names)
    with tracking.job_run("predict_dejong_cvae", {"problem": "dejong", "model": "cvae_gmm"}) as run:
        run.log_params({"n_samples": args.n_samples, "seed": args.seed, "radius": args.radius, "test_alphas": args.test_alphas})
        model = cvae.load(args.model)
        generator = torch.Generator().manual_seed(args.seed)
        frames, metrics = [], {}
        for alpha in args.test_alphas:
            samples = model.sample(alpha, args.n_samples, generator=generator).detach().cpu().numpy()
            frame = pd.DataFrame(samples, columns=names)
            frame.insert(0, "alpha", alpha)
            frame.insert(1, "sample", range(len(frame)))
            frames.append(frame)
            scores = prediction_metrics(samples, alpha, radius=args.radius)
            metrics[alpha_label(alpha)] = {"alpha": alpha, **scores}
            run.log_metrics({f"{k}/{_alpha_key(alpha)}": v for k, v in scores.items() if k not in ("n_samples", "radius")})
        write_parquet(pd.concat(frames, ignore_index=True), args.samples)
        write_json({"radius": args.radius, "n_samples": args.n_samples, "per_alpha": metrics}, args.metrics)
        run.log_artifact(args.metrics)
    print(f"{args.samples}: {args.n_samples} samples at each of {len(args.test_alphas)} test α")


def _write_png(fig, output: str, run) -> None:
    """Save ``fig`` as PNG atomically, close it and log it as an artifact of ``run`` under ``figures/``."""
    from matplotlib import pyplot as plt

    from amorgs.data.io import atomic_path

    with atomic_path(output) as tmp:
        fig.savefig(tmp, format="png", dpi=150, bbox_inches="tight")
    plt.close(fig)
    run.log_artifact(output, "figures")


def _write_figures(figures: dict, figures_dir: str, expected: tuple[str, ...], run) -> None:
    """Save every figure of ``figures`` (name → Figure) as ``figures_dir/{name}.png``; the names must be
    exactly ``expected`` (the outputs the workflow declares)."""
    if sorted(figures) != sorted(expected):
        raise ValueError(f"figures {sorted(figures)} differ from the declared outputs {sorted(expected)}")
    for name, fig in figures.items():
        _write_png(fig, os.path.join(figures_dir, f"{name}.png"), run)


def _save_figure(name: str, output: str, draw) -> None:
    """Draw a figure with ``draw()`` inside its job run (a failure is a FAILED run), save it as PNG
    atomically and log it as an artifact."""
    import matplotlib

    matplotlib.use("Agg")
    from amorgs import tracking

    with tracking.job_run(name, {}) as run:
        _write_png(draw(), output, run)
    print(f"{output}: written")


def cmd_fig02_foxholes(args: argparse.Namespace) -> None:
    def draw():
        from amorgs.figures.dejong import fig02_foxholes

        return fig02_foxholes()

    _save_figure("fig02_foxholes", args.output, draw)


def cmd_fig16_dejong_predictions(args: argparse.Namespace) -> None:
    def draw():
        import pandas as pd

        from amorgs.figures.dejong import fig16_dejong_predictions
        from amorgs.problems import get_problem

        names = list(get_problem("dejong").variable_names)
        samples = pd.read_parquet(args.samples)
        by_alpha = {float(a): g[names].to_numpy() for a, g in samples.groupby("alpha", sort=True)}
        return fig16_dejong_predictions(pd.read_parquet(args.data), by_alpha, args.train_alphas)

    _save_figure("fig16_dejong_predictions", args.output, draw)


def _read_tables(paths: list[str]):
    import pandas as pd

    return pd.concat([pd.read_parquet(p) for p in paths], ignore_index=True)


def _finite_metrics(metrics: dict) -> dict[str, float]:
    """The numeric, finite entries of a flat metrics dict (what MLflow can hold)."""
    return {k: float(v) for k, v in metrics.items() if isinstance(v, (int, float)) and math.isfinite(float(v))}


def cmd_analyze_cr3bp(args: argparse.Namespace) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import pandas as pd

    from amorgs import layout, tracking
    from amorgs.analysis.structure_report import StructureParams, analyze
    from amorgs.data.io import write_json, write_parquet

    params_dict = json.loads(args.params)
    try:
        params = StructureParams.from_dict(params_dict)
    except (TypeError, ValueError) as exc:
        raise ConfigError(f"cr3bp_analysis.params: {exc}") from None
    with tracking.job_run("analyze_cr3bp", {"problem": "cr3bp"}) as run:
        run.log_params({"beta_kg": args.beta, "params": params_dict})
        solutions = _read_tables(args.inputs)
        metrics, tables, figures = analyze(solutions, pd.read_parquet(args.high_quality), args.beta, params)
        if sorted(tables) != sorted(layout.ANALYSIS_TABLES):
            raise ValueError(f"analysis tables {sorted(tables)} differ from the declared outputs {sorted(layout.ANALYSIS_TABLES)}")
        for name, table in tables.items():
            write_parquet(table, os.path.join(args.tables_dir, f"{name}.parquet"))
        write_json(metrics, args.metrics)
        run.log_metrics(_finite_metrics(metrics))
        run.log_artifact(args.metrics)
        _write_figures(figures, args.figures_dir, layout.ANALYSIS_FIGURES, run)
    print(f"{args.metrics}: {len(metrics)} metrics, {len(tables)} tables, {len(figures)} figures")


def cmd_train_cr3bp(args: argparse.Namespace) -> None:
    import pandas as pd
    import torch

    from amorgs import tracking
    from amorgs.data.io import atomic_path
    from amorgs.models import cvae, lstm
    from amorgs.models.cr3bp_models import TRAINERS, subsample
    from amorgs.models.training import TrainConfig

    torch.set_num_threads(args.threads)
    hq = pd.read_parquet(args.data)
    train_labels = {alpha_label(a) for a in args.train_alphas}
    hq = hq[hq["alpha"].map(alpha_label).isin(train_labels)].reset_index(drop=True)
    if len(hq) < 2:
        raise SystemExit(f"{args.data}: {len(hq)} high-quality row(s) at the training α {sorted(train_labels)}; need ≥ 2")
    wildcards = {"problem": "cr3bp", "model": args.model}
    if args.fraction is not None:
        wildcards["fraction"] = args.fraction_label
        hq = subsample(hq, args.fraction, args.seed)
    rule = "train_cr3bp" if args.fraction is None else "train_cr3bp_fraction"
    if args.replicate:
        rule, wildcards["mseed"] = "train_cr3bp_replicate", str(args.seed)
    with tracking.job_run(rule, wildcards) as run:
        cfg = TrainConfig(epochs=args.epochs, batch_size=args.batch_size, lr=args.learning_rate, seed=args.seed, device="cpu")
        run.log_params({"preset": args.preset, "rows": len(hq), "train_alphas": sorted(train_labels),
                        "fraction": args.fraction, "threads": args.threads, **vars(cfg)})
        run.log_dataset(hq, args.data, "training")
        run.start_model(args.model, {"preset": args.preset, "fraction": args.fraction, **vars(cfg)})
        torch.manual_seed(args.seed)
        model = TRAINERS[args.model](hq, args.preset, cfg, on_epoch=lambda epoch, m: run.log_metrics(m, step=epoch))
        with atomic_path(args.output) as tmp:
            (lstm.save if args.model == "lstm" else cvae.save)(model, tmp)
        run.finish_model(args.output, step=args.epochs)  # the checkpoint as a logged model and under models/
    print(f"{args.output}: {args.model} trained {args.epochs} epochs on {len(hq)} solutions")


def cmd_predict_cr3bp(args: argparse.Namespace) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import numpy as np
    import pandas as pd

    from amorgs import layout, tracking
    from amorgs.analysis.prediction import at_alpha, prediction_table
    from amorgs.data.io import write_json, write_parquet
    from amorgs.figures.prediction import (
        fig17_time_predictions,
        fig18_data_fraction,
        fig19_final_mass,
        fig20_control_statistics,
    )
    from amorgs.models import cvae
    from amorgs.models.samplers import CVAETimeMassUniformControl, build_sampler
    from amorgs.problems import get_problem

    problem = get_problem("cr3bp")
    names = list(problem.variable_names)
    fractions = {float(f): path for f, path in (item.split("=", 1) for item in args.fraction_models)}
    samplers = {("amorgs", 1.0): build_sampler("amorgs", problem, args.models_dir),
                ("uniform", 1.0): build_sampler("uniform", problem, args.models_dir)}
    for f, path in fractions.items():
        samplers[("cvae_gmm", f)] = CVAETimeMassUniformControl(problem, cvae.load(path))
    with tracking.job_run("predict_cr3bp", {"problem": "cr3bp"}) as run:
        run.log_params({"n_samples": args.n_samples, "seed": args.seed, "test_alphas": args.test_alphas,
                        "data_fractions": sorted(fractions)})
        rng = np.random.default_rng(args.seed)
        frames = []
        for (source, fraction), sampler in samplers.items():
            for alpha in args.test_alphas:
                frame = pd.DataFrame(sampler.sample(alpha, args.n_samples, rng), columns=names)
                frame.insert(0, "alpha", alpha)
                frame.insert(1, "source", source)
                frame.insert(2, "data_fraction", fraction)
                frame.insert(3, "sample", range(len(frame)))
                frames.append(frame)
        samples = pd.concat(frames, ignore_index=True)
        hq = pd.read_parquet(args.high_quality)
        run.log_dataset(hq, args.high_quality, "evaluation")  # the ground truth at the test α
        truth = pd.concat([at_alpha(hq, a) for a in args.test_alphas], ignore_index=True)
        learned = samples[samples["source"] != "uniform"]
        table = prediction_table(learned, truth, by=("alpha", "source", "data_fraction"))
        write_parquet(samples, args.samples)
        write_json({"n_samples": args.n_samples, "rows": table.to_dict(orient="records")}, args.metrics)
        for row in table.to_dict(orient="records"):
            suffix = f"{row['source']}_f{row['data_fraction']:g}/{_alpha_key(row['alpha'])}"
            run.log_metrics(_finite_metrics({f"{k}/{suffix}": v for k, v in row.items() if k not in ("alpha", "source", "data_fraction")}))
        run.log_artifact(args.metrics)
        amorgs = samples[samples["source"] == "amorgs"]
        by_fraction = {1.0: amorgs, **{f: samples[(samples["source"] == "cvae_gmm") & (samples["data_fraction"] == f)] for f in fractions}}
        figures = {
            "fig17_time_predictions": fig17_time_predictions(amorgs, truth, args.test_alphas),
            "fig18_data_fraction": fig18_data_fraction(dict(sorted(by_fraction.items())), truth, args.test_alphas),
            "fig19_final_mass": fig19_final_mass(amorgs, truth, args.test_alphas),
            "fig20_control_statistics": fig20_control_statistics(
                {"LSTM": amorgs, "Ground truth": truth, "Uniform": samples[samples["source"] == "uniform"]}, args.test_alphas
            ),
        }
        _write_figures(figures, args.figures_dir, layout.PREDICTION_FIGURES, run)
    print(f"{args.samples}: {len(samples)} samples at {len(args.test_alphas)} test α")


def cmd_ablation_cell(args: argparse.Namespace) -> None:
    from amorgs import tracking
    from amorgs.ablation.experiment import run_cell
    from amorgs.data.io import write_parquet
    from amorgs.models.samplers import NEEDS_HIGH_QUALITY, NEEDS_MODELS, build_sampler
    from amorgs.problems import get_problem

    options = json.loads(args.solver_options)
    wildcards = {"alpha": alpha_label(args.alpha), "sampler": args.sampler}
    if args.replicate:
        wildcards["mseed"] = str(args.model_seed)
    rule = "ablation_cell_replicate" if args.replicate else "ablation_cell"
    if NEEDS_MODELS[args.sampler] and not args.models_dir:
        raise SystemExit(f"ablation-cell: sampler {args.sampler!r} needs --models-dir")
    if args.sampler in NEEDS_HIGH_QUALITY and not (args.high_quality and args.train_alphas):
        raise SystemExit(f"ablation-cell: sampler {args.sampler!r} needs --high-quality and --train-alphas")
    with tracking.job_run(rule, wildcards) as run:
        run.log_params({"alpha": args.alpha, "seed": args.seed, "starts": args.starts, "workers": args.workers,
                        "solver": options, "model_seed": args.model_seed, "perturbation_scale": args.perturbation_scale,
                        "gmm_components": args.gmm_components})
        problem = get_problem("cr3bp")
        hq = None
        if args.sampler in NEEDS_HIGH_QUALITY:
            import pandas as pd

            hq = pd.read_parquet(args.high_quality)
        sampler = build_sampler(args.sampler, problem, args.models_dir, high_quality=hq, train_alphas=args.train_alphas,
                                perturbation_scale=args.perturbation_scale, gmm_components=args.gmm_components)
        df = run_cell("cr3bp", args.alpha, sampler, args.starts, args.seed, options, args.workers)
        if args.model_seed is not None:
            df.insert(2, "model_seed", int(args.model_seed))
        write_parquet(df, args.output)
        conv = df[df["converged"]]
        run.log_metrics(
            {
                "starts": len(df),
                "converged": len(conv),
                "converged_fraction": len(conv) / len(df),
                "iterations_median": conv["iterations"].median() if len(conv) else None,
                "solve_wall_s_total": df["wall_s"].sum(),
            }
        )
    print(f"{args.output}: {len(df)} solves, {len(conv)} converged")


def cmd_ablation_report(args: argparse.Namespace) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import pandas as pd

    from amorgs import layout, tracking
    from amorgs.ablation.report import MARKDOWN_TITLES, markdown_table, summarize, table6_markdown
    from amorgs.data.io import atomic_path, write_json

    with tracking.job_run("ablation_report", {}) as run:
        run.log_params({"beta_kg": args.beta, "cells": len(args.cells)})
        truth = pd.read_parquet(args.high_quality)
        run.log_dataset(truth, args.high_quality, "evaluation")  # the ground truth at the test α
        run.log_params({"beta_sweep_kg": args.beta_sweep, "iteration_caps": args.iteration_caps,
                        "max_iter": args.max_iter, "n_boot": args.n_boot, "bootstrap_seed": args.seed})
        metrics, tables, figures = summarize(
            _read_tables(args.cells), truth, args.beta, n_boot=args.n_boot, seed=args.seed,
            beta_sweep=tuple(args.beta_sweep), iteration_caps=tuple(args.iteration_caps), max_iter=args.max_iter,
        )
        for key, path in (("table6", args.table6_csv), ("capped", args.capped), ("coverage", args.coverage)):
            with atomic_path(path) as tmp:
                tables[key].to_csv(tmp, index=False)
        with atomic_path(args.table6_md) as tmp:
            tmp.write_text(table6_markdown(tables["table6"]) + "\n")
        tables_dir = args.tables_dir or os.path.dirname(args.table6_csv)
        written = [args.summary, args.table6_csv, args.table6_md, args.capped, args.coverage]
        for key in ("rates", "beta_sweep", "ert", "iteration_capped", "anytime"):
            csv = os.path.join(tables_dir, f"ablation_{key}.csv")
            with atomic_path(csv) as tmp:
                tables[key].to_csv(tmp, index=False)
            written.append(csv)
            if key in MARKDOWN_TITLES:
                md = os.path.join(tables_dir, f"ablation_{key}.md")
                with atomic_path(md) as tmp:
                    tmp.write_text(markdown_table(tables[key], f"**{MARKDOWN_TITLES[key]}**"))
                written.append(md)
        write_json(metrics, args.summary)
        run.log_metrics(_finite_metrics(metrics))
        for path in written:
            run.log_artifact(path, "tables")
        _write_figures(figures, args.figures_dir, layout.ABLATION_FIGURES, run)
    print(f"{args.summary}: {len(metrics)} metrics over {len(args.cells)} cells")


# -------------------------------------------------------------------------------------------- tools


def cmd_library_export(args: argparse.Namespace) -> None:
    from amorgs.data.library import export_library

    summary = export_library(args.solutions_dir, args.library_dir, args.problem, args.config)
    print(
        f"{args.library_dir}/{args.problem}: {summary['files_added']} new file(s), {summary['rows_added']} new rows; "
        f"library now {summary['shards']} shards in {summary['files']} files, {summary['rows']} solves "
        f"({summary['converged']} converged, {summary['cpu_hours']:.2f} CPU-hours, "
        f"{summary['bytes_per_row']:.0f} bytes per solve)"
    )


def cmd_models_export(args: argparse.Namespace) -> None:
    from amorgs.models.shipped import export_models

    manifest = export_models(args.models_dir, args.dest, args.config, args.library_dir)
    size = sum(f["bytes"] for f in manifest["files"])
    print(f"{args.dest}: {len(manifest['files'])} checkpoints ({size / 1e6:.2f} MB), trained on a library of "
          f"{manifest['library_rows']} solves; manifest {args.dest}/provenance.json")


def cmd_library_grow(args: argparse.Namespace) -> None:
    from amorgs.data.library_grow import grow

    grow(args.config, args.library_dir, args.problem, args.workdir, args.cores, args.batches, args.hours, args.nice)


def cmd_boundary_conditions(args: argparse.Namespace) -> None:
    from amorgs.problems.cr3bp import boundary

    if not args.check:
        boundary.write_boundary_conditions(args.output)
        print(f"{args.output or boundary.resource_path()}: written")
        return
    stored = boundary.load_boundary_conditions(args.output)
    bad = _compare(stored, boundary.compute_boundary_conditions(), "", rel_tol=args.rel_tol)
    where = args.output or boundary.resource_path()
    if bad:
        raise SystemExit(f"{where} differs from a fresh computation:\n  " + "\n  ".join(bad))
    print(f"{where}: matches a fresh computation (relative tolerance {args.rel_tol:g})")


def _compare(stored: object, fresh: object, path: str, rel_tol: float) -> list[str]:
    """Differences between two JSON trees: numbers compared to ``rel_tol``, everything else exactly."""
    if isinstance(stored, dict) and isinstance(fresh, dict):
        keys = sorted(set(stored) | set(fresh))
        return [d for k in keys for d in _compare(stored.get(k), fresh.get(k), f"{path}.{k}".lstrip("."), rel_tol)]
    if isinstance(stored, list) and isinstance(fresh, list) and len(stored) == len(fresh):
        return [d for i, (a, b) in enumerate(zip(stored, fresh)) for d in _compare(a, b, f"{path}[{i}]", rel_tol)]
    if isinstance(stored, (int, float)) and isinstance(fresh, (int, float)) and not isinstance(stored, bool):
        return [] if math.isclose(stored, fresh, rel_tol=rel_tol, abs_tol=rel_tol) else [f"{path}: {stored} vs {fresh}"]
    return [] if stored == fresh else [f"{path}: {stored!r} vs {fresh!r}"]


def cmd_design(args: argparse.Namespace) -> None:
    from amorgs.design import DesignRequest, run_design

    request = DesignRequest(
        alpha=args.alpha, n=args.n, sampler=args.sampler, beta_kg=args.beta, eta=args.eta, seed=args.seed,
        workers=args.workers, round_size=args.round_size, max_starts=args.max_starts, max_cpu_s=args.max_cpu_s,
        library_dir=args.library_dir, models_dir=args.models_dir, config=args.config,
    )
    result, paths = run_design(request, args.output, track=not args.no_mlflow, store_dir=args.mlflow_dir,
                               progress=not args.quiet)
    out = paths["reports"][0].parent
    print(f"{out}: {len(result.selected)} of {args.n} solutions (α = {args.alpha:g} N, m_f ≥ {args.beta:g} kg, "
          f"η = {args.eta:g}) from {result.starts} starts, {result.cpu_s:.0f} CPU s, {result.wall_s:.0f} s wall")
    if result.found < args.n:
        print(f"amorgs design: only {result.found} of {args.n} found before the budget ran out "
              f"({result.stop_reason}); raise --max-starts / --max-cpu-s or lower -n", file=sys.stderr)
        raise SystemExit(3)


def cmd_ui(args: argparse.Namespace) -> None:
    from amorgs import tracking

    if not (tracking.STORE_DIR / tracking.DB_NAME).exists():
        raise SystemExit(f"no MLflow store at {tracking.STORE_DIR / tracking.DB_NAME}: run the workflow first")
    cmd = tracking.ui_command(host=args.host, port=args.port)
    print(" ".join(cmd), flush=True)
    os.execv(cmd[0], cmd)


def cmd_check_outputs(args: argparse.Namespace) -> None:
    from amorgs.checks import UNTRACKED, check_outputs
    from amorgs.config import load_config

    problems = check_outputs(load_config(args.config, args.schema), tracked=not args.no_mlflow)
    if problems == [UNTRACKED]:  # every file is fine; only the MLflow history is missing
        print(f"{args.config}: every expected output is present and non-empty, but untracked\n  {UNTRACKED}", file=sys.stderr)
        raise SystemExit(3)
    if problems:
        raise SystemExit("missing or empty outputs:\n  " + "\n  ".join(problems))
    print(f"{args.config}: every expected output is present, non-empty and tracked")


# ------------------------------------------------------------------------------------------- parser


#: One example per subcommand, shown in its ``--help`` epilog (the rules' own command lines, shortened).
_EXAMPLES = {
    "generate": "amorgs generate --problem dejong --alpha 0.2 --shard 0 --seed 7 --starts 40 \\\n"
    "      --output results/dejong/solutions/alpha=0.200/shard-0.parquet",
    "merge": "amorgs merge --problem cr3bp --alpha 0.150 \\\n"
    "      --inputs results/cr3bp/solutions/alpha=0.150/shard-*.parquet \\\n"
    "      --output results/cr3bp/solutions/alpha=0.150.parquet",
    "filter": "amorgs filter --problem cr3bp --inputs results/cr3bp/solutions/alpha=*.parquet \\\n"
    "      --min-final-mass-kg 415 --output results/cr3bp/high_quality.parquet \\\n"
    "      --report results/cr3bp/quality_report.json",
    "train-dejong-cvae": "amorgs train-dejong-cvae --data results/dejong/high_quality.parquet --train-alphas 0 0.5 1 \\\n"
    "      --preset small --learning-rate 1e-3 --epochs 100 --batch-size 256 --seed 0 \\\n"
    "      --output results/dejong/models/cvae_gmm.pt",
    "predict-dejong-cvae": "amorgs predict-dejong-cvae --model results/dejong/models/cvae_gmm.pt --test-alphas 0.349 \\\n"
    "      --n-samples 500 --seed 0 --radius 2 --samples samples.parquet --metrics metrics.json",
    "fig02-foxholes": "amorgs fig02-foxholes --output results/figures/fig02_foxholes.png",
    "fig16-dejong-predictions": "amorgs fig16-dejong-predictions --data results/dejong/high_quality.parquet \\\n"
    "      --samples results/dejong/predictions/samples.parquet --train-alphas 0 0.5 1 \\\n"
    "      --output results/figures/fig16_dejong_predictions.png",
    "analyze-cr3bp": "amorgs analyze-cr3bp --inputs results/cr3bp/solutions/alpha=*.parquet \\\n"
    "      --high-quality results/cr3bp/high_quality.parquet --beta 415 --metrics metrics.json \\\n"
    "      --tables-dir results/cr3bp/analysis --figures-dir results/figures",
    "train-cr3bp": "amorgs train-cr3bp --data results/cr3bp/high_quality.parquet --model lstm --train-alphas 0.1 0.2 \\\n"
    "      --preset small --learning-rate 1e-3 --epochs 500 --batch-size 256 --seed 0 \\\n"
    "      --output results/cr3bp/models/lstm.pt",
    "predict-cr3bp": "amorgs predict-cr3bp --models-dir results/cr3bp/models --high-quality results/cr3bp/high_quality.parquet \\\n"
    "      --test-alphas 0.15 0.85 --n-samples 200 --seed 0 --samples samples.parquet \\\n"
    "      --metrics metrics.json --figures-dir results/figures",
    "ablation-cell": "amorgs ablation-cell --alpha 0.15 --sampler amorgs --models-dir results/cr3bp/models \\\n"
    "      --starts 24 --seed 1 --output results/cr3bp/ablation/alpha=0.150/amorgs.parquet",
    "ablation-report": "amorgs ablation-report --cells results/cr3bp/ablation/alpha=*/*.parquet \\\n"
    "      --high-quality results/cr3bp/high_quality.parquet --beta 415 --summary summary.json \\\n"
    "      --table6-csv table6.csv --table6-md table6.md --capped capped.csv --coverage coverage.csv \\\n"
    "      --figures-dir results/figures",
    "library-export": "amorgs library-export --solutions-dir results/library-grow/results/cr3bp/solutions "
    "--library-dir data/library",
    "models-export": "amorgs models-export --models-dir results/cr3bp/models --dest data/models/cr3bp",
    "boundary-conditions": "amorgs boundary-conditions --check     # recompute and compare with the stored resource",
    "ui": "amorgs ui --port 5000     # then browse http://127.0.0.1:5000",
    "check-outputs": "amorgs check-outputs --config config/smoke.yaml   # exit 0: complete; 1: missing or broken;\n"
    "                                                    # 3: complete but untracked in MLflow",
}


def _add_examples(sub: argparse._SubParsersAction) -> None:
    """Show each subcommand's example (:data:`_EXAMPLES`) in its epilog, unless it has an epilog already."""
    for name, parser in sub.choices.items():
        parser.formatter_class = argparse.RawDescriptionHelpFormatter
        if not parser.epilog and name in _EXAMPLES:
            parser.epilog = "example:\n  " + _EXAMPLES[name]


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="amorgs", description=__doc__.split("\n")[0])
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    p = sub.add_parser("generate", help="multi-start solves of one (problem, α, shard) → parquet")
    p.add_argument("--problem", required=True, choices=("dejong", "cr3bp"), help="problem family: dejong or cr3bp")
    p.add_argument("--alpha", required=True, type=float, help="α (the exact value; the label is derived)")
    p.add_argument("--shard", required=True, type=int, help="shard index k (part of the output path and of the seed)")
    p.add_argument("--seed", required=True, type=int, help="seed of this shard (see amorgs.data.seeds)")
    p.add_argument("--starts", required=True, type=int, help="uniform initial guesses in this shard")
    p.add_argument("--workers", type=int, default=1, help="solver processes")
    p.add_argument("--solver-options", default="{}", help="JSON object of solver options")
    p.add_argument("--output", required=True, help="shard table to write (parquet)")
    p.set_defaults(func=cmd_generate)

    p = sub.add_parser("merge", help="merge the shard tables of one (problem, α)")
    p.add_argument("--problem", required=True, choices=("dejong", "cr3bp"), help="problem family: dejong or cr3bp")
    p.add_argument("--alpha", required=True, help="α label, e.g. 0.150")
    p.add_argument("--inputs", required=True, nargs="+", help="fresh shard tables (source = fresh)")
    p.add_argument("--library", nargs="*", default=[],
                   help="library files of this α (source = library), each checked against the manifest")
    p.add_argument("--library-dir", default="data/library", help="library root holding {problem}/provenance.json")
    p.add_argument("--library-max-rows", type=int, default=None,
                   help="take only the first N library rows in (shard, start) order (default: all)")
    p.add_argument("--output", required=True, help="the merged α table (Parquet)")
    p.set_defaults(func=cmd_merge)

    p = sub.add_parser("filter", help="β-filter every α table of a problem; write a quality report")
    p.add_argument("--problem", required=True, choices=("dejong", "cr3bp"), help="problem family: dejong or cr3bp")
    p.add_argument("--inputs", required=True, nargs="+", help="merged α tables (results/{problem}/solutions/alpha=*.parquet)")
    p.add_argument("--min-final-mass-kg", type=float, help="β on the final mass m_f (kg)")
    p.add_argument("--max-objective", type=float, help="keep objective ≤ this")
    p.add_argument("--output", required=True, help="high-quality table to write (parquet)")
    p.add_argument("--report", required=True, help="quality report JSON to write (rows, converged, high-quality per α)")
    p.set_defaults(func=cmd_filter)

    p = sub.add_parser("train-dejong-cvae", help="train the GMM-prior CVAE on the De Jong minima")
    p.add_argument("--data", required=True, help="high_quality.parquet")
    p.add_argument("--train-alphas", required=True, type=float, nargs="+", help="training α values (rows at other α are left out)")
    p.add_argument("--preset", required=True, choices=("dejong_paper", "small"), help="network size: dejong_paper (Table 3) or small")
    p.add_argument("--learning-rate", required=True, type=float, help="Adam learning rate")
    p.add_argument("--epochs", required=True, type=int, help="passes over the training rows")
    p.add_argument("--batch-size", required=True, type=int, help="rows per mini-batch (the row count or more: full batch)")
    p.add_argument("--seed", required=True, type=int, help="random seed (weights, noise, shuffling or sampling)")
    p.add_argument("--threads", type=int, default=1, help="torch CPU threads")
    p.add_argument("--output", required=True, help="checkpoint to write (.pt)")
    p.set_defaults(func=cmd_train_dejong_cvae)

    p = sub.add_parser("predict-dejong-cvae", help="sample the CVAE at the test α and score the samples")
    p.add_argument("--model", required=True, help="trained CVAE checkpoint (cvae_gmm.pt)")
    p.add_argument("--test-alphas", required=True, type=float, nargs="+", help="held-out α values to sample at")
    p.add_argument("--n-samples", required=True, type=int, help="samples per test α")
    p.add_argument("--seed", required=True, type=int, help="random seed (weights, noise, shuffling or sampling)")
    p.add_argument("--radius", required=True, type=float, help="a sample within this distance of a true minimum counts as a hit")
    p.add_argument("--samples", required=True, help="samples parquet to write")
    p.add_argument("--metrics", required=True, help="metrics JSON to write")
    p.set_defaults(func=cmd_predict_dejong_cvae)

    p = sub.add_parser("fig02-foxholes", help="Fig. 2: the classic 25-foxhole De Jong function")
    p.add_argument("--output", required=True, help="PNG to write")
    p.set_defaults(func=cmd_fig02_foxholes)

    p = sub.add_parser("fig16-dejong-predictions", help="Fig. 16: De Jong training minima and CVAE samples")
    p.add_argument("--data", required=True, help="high_quality.parquet (training minima)")
    p.add_argument("--samples", required=True, help="predicted samples parquet")
    p.add_argument("--train-alphas", required=True, type=float, nargs="+", help="training α values (rows at other α are left out)")
    p.add_argument("--output", required=True, help="PNG to write")
    p.set_defaults(func=cmd_fig16_dejong_predictions)

    p = sub.add_parser("analyze-cr3bp", help="structure analysis of the CR3BP solutions, Figs. 3-13")
    p.add_argument("--inputs", required=True, nargs="+", help="merged α tables (every solve)")
    p.add_argument("--high-quality", required=True, help="high_quality.parquet of the problem")
    p.add_argument("--beta", required=True, type=float, help="β, the final-mass threshold (kg)")
    p.add_argument("--params", default="{}", help="JSON object of StructureParams fields")
    p.add_argument("--metrics", required=True, help="metrics JSON to write")
    p.add_argument("--tables-dir", required=True, help="folder for the analysis tables (parquet)")
    p.add_argument("--figures-dir", required=True, help="folder for the figures (PNG)")
    p.set_defaults(func=cmd_analyze_cr3bp)

    p = sub.add_parser("train-cr3bp", help="train one CR3BP model on the high-quality rows at the training α")
    p.add_argument("--data", required=True, help="high_quality.parquet")
    p.add_argument("--train-alphas", required=True, type=float, nargs="+", help="training α values (rows at other α are left out)")
    p.add_argument("--model", required=True, choices=("cvae_gmm", "vanilla_cvae", "lstm"), help="which model: cvae_gmm, vanilla_cvae or lstm")
    p.add_argument("--fraction", type=float, help="train on this fraction of the rows of every α (Fig. 18)")
    p.add_argument("--fraction-label", help="the fraction as in the output path (with --fraction)")
    p.add_argument("--preset", required=True, choices=("paper", "small"), help="network size: paper (Tables 4-5) or small")
    p.add_argument("--learning-rate", required=True, type=float, help="Adam learning rate")
    p.add_argument("--epochs", required=True, type=int, help="passes over the training rows")
    p.add_argument("--batch-size", required=True, type=int, help="rows per mini-batch (the row count or more: full batch)")
    p.add_argument("--seed", required=True, type=int, help="random seed (weights, noise, shuffling or sampling)")
    p.add_argument("--replicate", action="store_true",
                   help="a replicate of an extra training seed (tracked as train_cr3bp_replicate, wildcard mseed = --seed)")
    p.add_argument("--threads", type=int, default=1, help="torch CPU threads")
    p.add_argument("--output", required=True, help="checkpoint to write (.pt)")
    p.set_defaults(func=cmd_train_cr3bp)

    p = sub.add_parser("predict-cr3bp", help="sample the CR3BP models at the test α; Figs. 17-20")
    p.add_argument("--models-dir", required=True, help="folder of cvae_gmm.pt, vanilla_cvae.pt, lstm.pt")
    p.add_argument("--fraction-models", nargs="*", default=[], help="FRACTION=PATH of the reduced-data GMM-CVAEs")
    p.add_argument("--high-quality", required=True, help="ground truth: its rows at the test α")
    p.add_argument("--test-alphas", required=True, type=float, nargs="+", help="held-out α values to sample at")
    p.add_argument("--n-samples", required=True, type=int, help="samples per test α")
    p.add_argument("--seed", required=True, type=int, help="random seed (weights, noise, shuffling or sampling)")
    p.add_argument("--samples", required=True, help="samples parquet to write")
    p.add_argument("--metrics", required=True, help="metrics JSON to write")
    p.add_argument("--figures-dir", required=True, help="folder for the figures (PNG)")
    p.set_defaults(func=cmd_predict_cr3bp)

    from amorgs.ablation.arms import SAMPLER_NAMES

    p = sub.add_parser("ablation-cell", help="solve the guesses of one sampler at one test α")
    p.add_argument("--alpha", required=True, type=float, help="test α of this cell")
    p.add_argument("--sampler", required=True, choices=SAMPLER_NAMES, help="warm-start sampler of the cell")
    p.add_argument("--models-dir", help="folder of the checkpoints (the arms that load a model)")
    p.add_argument("--high-quality", help="filtered high-quality table (nearest_alpha, nearest_alpha_perturbed, gmm_lstm)")
    p.add_argument("--train-alphas", type=float, nargs="+", help="the training α: the only rows those arms may use")
    p.add_argument("--perturbation-scale", type=float, default=0.02, help="σ of nearest_alpha_perturbed (box-normalised)")
    p.add_argument("--gmm-components", type=int, default=5, help="mixture components per training α of gmm_lstm")
    p.add_argument("--model-seed", type=int, help="training seed of the models (written to the model_seed column)")
    p.add_argument("--replicate", action="store_true", help="a replicate cell of an extra model seed (MLflow rule name)")
    p.add_argument("--starts", required=True, type=int, help="initial guesses (solves) in this cell")
    p.add_argument("--seed", required=True, type=int, help="random seed (weights, noise, shuffling or sampling)")
    p.add_argument("--workers", type=int, default=1, help="solver processes")
    p.add_argument("--solver-options", default="{}", help="JSON object of solver options")
    p.add_argument("--output", required=True, help="cell table to write (parquet)")
    p.set_defaults(func=cmd_ablation_cell)

    p = sub.add_parser("ablation-report", help="Table 6, capped study, coverage and Figs. 21-23")
    p.add_argument("--cells", required=True, nargs="+", help="ablation cell tables (results/cr3bp/ablation/alpha=*/*.parquet)")
    p.add_argument("--high-quality", required=True, help="high_quality.parquet of the problem")
    p.add_argument("--beta", required=True, type=float, help="β, the final-mass threshold of a high-quality solution (kg)")
    p.add_argument("--summary", required=True, help="summary JSON to write (every metric of the report)")
    p.add_argument("--table6-csv", required=True, help="Table 6 as CSV to write")
    p.add_argument("--table6-md", required=True, help="Table 6 as Markdown to write")
    p.add_argument("--capped", required=True, help="capped-budget study CSV to write")
    p.add_argument("--coverage", required=True, help="coverage-of-the-true-solutions CSV to write")
    p.add_argument("--tables-dir", help="folder of the issue-11 tables (default: the folder of --table6-csv)")
    p.add_argument("--beta-sweep", type=float, nargs="*", default=[], help="extra β (kg) of the rate sweep")
    p.add_argument("--iteration-caps", type=int, nargs="*", default=[], help="iteration caps fixed before the solves")
    p.add_argument("--max-iter", type=int, help="the solver's max_iter (caps may not exceed it)")
    p.add_argument("--n-boot", type=int, default=2000, help="bootstrap resamples")
    p.add_argument("--seed", type=int, default=0, help="bootstrap seed")
    p.add_argument("--figures-dir", required=True, help="folder for the figures (PNG)")
    p.set_defaults(func=cmd_ablation_report)

    p = sub.add_parser("library-export", help="check finished library-config shards and add them to the library")
    p.add_argument("--problem", default="cr3bp", choices=("dejong", "cr3bp"), help="problem whose shards are exported")
    p.add_argument("--solutions-dir", default="results/cr3bp/solutions", help="where the generate rule wrote the shards")
    p.add_argument("--library-dir", default="data/library", help="library root (data/library)")
    p.add_argument("--config", default="config/library.yaml", help="the config that generated them (provenance)")
    p.set_defaults(func=cmd_library_export)

    p = sub.add_parser("models-export", help="ship a workflow run's CR3BP checkpoints in the repository (for design)")
    p.add_argument("--models-dir", default="results/cr3bp/models", help="the train step's checkpoints")
    p.add_argument("--dest", default="data/models/cr3bp", help="where the shipped checkpoints live")
    p.add_argument("--config", default="config/default.yaml", help="the config of the run that trained them")
    p.add_argument("--library-dir", default="data/library", help="the library they were trained on (its hash is recorded)")
    p.set_defaults(func=cmd_models_export)

    p = sub.add_parser(
        "library-grow",
        help="grow the library: generate the next batch of library-config shards, export, repeat",
        epilog="example: nice -n 19 amorgs library-grow --batches 20 --hours 3   # then commit data/library",
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("--config", default="config/library.yaml", help="the library config (seed, α, starts per shard)")
    p.add_argument("--problem", default="cr3bp", choices=("cr3bp",), help="problem whose library grows")
    p.add_argument("--library-dir", default="data/library", help="library root")
    p.add_argument("--workdir", default="results/library-grow", help="Snakemake working directory of the batches")
    p.add_argument("--cores", type=int, default=2, help="cores Snakemake may use")
    p.add_argument("--batches", type=int, default=1, help="batches to run (each: every α × generate.shards shards)")
    p.add_argument("--hours", type=float, default=None, help="start no new batch after this many hours")
    p.add_argument("--nice", type=int, default=19, help="niceness added before starting (0: none)")
    p.set_defaults(func=cmd_library_grow)

    p = sub.add_parser("boundary-conditions", help="recompute (or --check) the CR3BP boundary conditions")
    p.add_argument("--output", help="the resource file (default: resources/boundary_conditions.json)")
    p.add_argument("--check", action="store_true", help="compare the stored file with a fresh computation")
    p.add_argument("--rel-tol", type=float, default=1e-9, help="--check: relative tolerance on numbers")
    p.set_defaults(func=cmd_boundary_conditions)

    p = sub.add_parser(
        "design",
        help="N good, verified, η-diverse CR3BP transfers at one α, exported (tables, CSV, CCSDS OEM, plot)",
        description="Solve warm starts at one α in rounds until N high-quality (converged and verified by\n"
                    "independent re-propagation, m_f ≥ β) and η-diverse (paper Eq. 12) solutions are found or a\n"
                    "budget runs out; write them with dense trajectories in the rotating frame and an Earth-centred\n"
                    "inertial frame (epoch 2030-01-01T00:00:00 TDB at departure) as CSV, CCSDS OEM and a 3-D plot.",
        epilog="example:\n  amorgs design --alpha 0.42 -n 20            # → results/design/alpha=0.420/\n"
               "  amorgs design --alpha 0.42 -n 5 --seed 7 --max-starts 64 --output my-design\n"
               "exit status: 0 all N found, 3 fewer found before the budget ran out (files still written)",
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("--alpha", required=True, type=float, help="maximum thrust α in N, within [0.1, 1.0]")
    p.add_argument("-n", "--n", dest="n", required=True, type=int, help="number of solutions wanted (≥ 1)")
    p.add_argument("--sampler", default="nearest_alpha",
                   help="warm-start sampler (default nearest_alpha: library solutions of the nearest training α); "
                        "also uniform, nearest_alpha_perturbed, and the learned amorgs, cvae_uniform_control, "
                        "uniform_lstm_control, vanilla_cvae, gmm_lstm (need --models-dir)")
    p.add_argument("--beta", type=float, default=415.0, help="β: minimum final fuel mass m_f in kg (default 415)")
    p.add_argument("--eta", type=float, default=0.02,
                   help="η of Eq. 12, dimensionless: solutions must differ by more than η in (τ_s/40, τ_i/15, τ_f/15) "
                        "(default 0.02 ≈ 0.8 TU of τ_s or 0.3 TU of τ_i, τ_f)")
    p.add_argument("--seed", type=int, default=0, help="seed of the warm starts; same seed, same result (default 0)")
    p.add_argument("--workers", type=int, default=2, help="solver processes (default 2)")
    p.add_argument("--round-size", type=int, default=16,
                   help="starts solved per round; the stop criteria are checked between rounds (default 16)")
    p.add_argument("--max-starts", type=int, default=400, help="budget: at most this many solves (default 400)")
    p.add_argument("--max-cpu-s", type=float, default=3600.0,
                   help="budget: start no new round after this many CPU seconds, workers included (default 3600)")
    p.add_argument("--output", default=None, help="output folder (default results/design/alpha=<label>/)")
    p.add_argument("--library-dir", default="data/library", help="the solution library shipped in the repository")
    p.add_argument("--models-dir", default="data/models/cr3bp", help="checkpoints of the learned samplers")
    p.add_argument("--config", default="config/default.yaml",
                   help="config giving the solver options (problems.cr3bp.solver), training α and filter β")
    p.add_argument("--mlflow-dir", default="results/mlflow",
                   help="MLflow store of the design run (default: the workflow's store, so `amorgs ui` shows it)")
    p.add_argument("--no-mlflow", action="store_true", help="do not mirror the call to MLflow")
    p.add_argument("--quiet", action="store_true", help="no progress bar on stderr")
    p.set_defaults(func=cmd_design)

    p = sub.add_parser("ui", help="open the MLflow UI on results/mlflow")
    p.add_argument("--host", default="127.0.0.1", help="address the UI listens on")
    p.add_argument("--port", type=int, default=5000, help="port the UI listens on")
    p.set_defaults(func=cmd_ui)

    p = sub.add_parser("check-outputs", help="check that every output of a config exists, is non-empty and tracked")
    p.add_argument("--config", required=True, help="config file, e.g. config/smoke.yaml")
    p.add_argument("--schema", default=str(SCHEMA_PATH), help="JSON Schema of the config (default: the workflow's)")
    p.add_argument("--no-mlflow", action="store_true", help="skip the MLflow checks")
    p.set_defaults(func=cmd_check_outputs)
    _add_examples(sub)
    return parser


def main(argv: list[str] | None = None) -> None:
    args = build_parser().parse_args(argv)
    try:
        args.func(args)
    except (ConfigError, InputError) as exc:
        sys.exit(f"amorgs {args.command}: {exc}")
