"""The ``amorgs`` command line: one subcommand per workflow step, plus tools around the workflow.

Workflow steps (each called by one Snakemake rule, each mirrored to MLflow as one child run)::

    generate                  multi-start solves of one (problem, α, shard)      → shard table
    merge                     the shards of one (problem, α)                      → α table
    filter                    every α table of a problem, β-filter                → high_quality + report
    train-dejong-cvae         GMM-prior CVAE on the filtered De Jong minima       → model checkpoint
    predict-dejong-cvae       samples at the test α + hit metrics                 → samples + metrics
    fig02-foxholes, fig16-dejong-predictions   one paper figure each          → results/figures/*.png

Tools: ``boundary-conditions`` (recompute or check ``resources/boundary_conditions.json``), ``ui`` (the
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
    from amorgs.data.tables import merge_shards

    with tracking.job_run("merge", {"problem": args.problem, "alpha": args.alpha}) as run:
        df = merge_shards(pd.read_parquet(p) for p in args.inputs)
        wrong = df[(df["problem"] != args.problem) | (df["alpha"].map(alpha_label) != args.alpha)]
        if len(wrong):
            raise ValueError(f"{args.output}: {len(wrong)} row(s) are not {args.problem} at alpha={args.alpha}")
        write_parquet(df, args.output)
        run.log_metrics({"shards": len(args.inputs), "rows": len(df), "converged": int(df["converged"].sum())})
    print(f"{args.output}: {len(df)} rows from {len(args.inputs)} shard(s)")


def cmd_filter(args: argparse.Namespace) -> None:
    import pandas as pd

    from amorgs import tracking
    from amorgs.data.filter import high_quality, quality_report
    from amorgs.data.io import write_json, write_parquet

    thresholds = {"min_final_mass_kg": args.min_final_mass_kg, "max_objective": args.max_objective}
    with tracking.job_run("filter", {"problem": args.problem}) as run:
        run.log_params(thresholds)
        df = pd.concat([pd.read_parquet(p) for p in args.inputs], ignore_index=True)
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
        torch.manual_seed(args.seed)
        model = cvae.GMMPriorCVAE(_dejong_cvae_config(args.preset), cvae.Normalizer.from_data(x))
        history = train(model, x, alpha, cfg, on_epoch=lambda epoch, metrics: run.log_metrics(metrics, step=epoch))
        with atomic_path(args.output) as tmp:
            cvae.save(model, tmp)
        run.log_metrics({f"final_{k}": v[-1] for k, v in history.items() if k != "epoch"})
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


def _save_figure(name: str, output: str, draw) -> None:
    """Draw a figure with ``draw()`` inside its job run (a failure is a FAILED run), save it as PNG
    atomically and log it as an artifact."""
    import matplotlib

    matplotlib.use("Agg")
    from matplotlib import pyplot as plt

    from amorgs import tracking
    from amorgs.data.io import atomic_path

    with tracking.job_run(name, {}) as run:
        fig = draw()
        with atomic_path(output) as tmp:
            fig.savefig(tmp, format="png", dpi=150, bbox_inches="tight")
        plt.close(fig)
        run.log_artifact(output, "figures")
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


# -------------------------------------------------------------------------------------------- tools


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


def cmd_ui(args: argparse.Namespace) -> None:
    from amorgs import tracking

    if not (tracking.STORE_DIR / tracking.DB_NAME).exists():
        raise SystemExit(f"no MLflow store at {tracking.STORE_DIR / tracking.DB_NAME}: run the workflow first")
    cmd = tracking.ui_command(host=args.host, port=args.port)
    print(" ".join(cmd), flush=True)
    os.execv(cmd[0], cmd)


def cmd_check_outputs(args: argparse.Namespace) -> None:
    from amorgs.checks import check_outputs
    from amorgs.config import load_config

    problems = check_outputs(load_config(args.config, args.schema), tracked=not args.no_mlflow)
    if problems:
        raise SystemExit("missing or empty outputs:\n  " + "\n  ".join(problems))
    print(f"{args.config}: every expected output is present, non-empty and tracked")


# ------------------------------------------------------------------------------------------- parser


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="amorgs", description=__doc__.split("\n")[0])
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    p = sub.add_parser("generate", help="multi-start solves of one (problem, α, shard) → parquet")
    p.add_argument("--problem", required=True, choices=("dejong", "cr3bp"))
    p.add_argument("--alpha", required=True, type=float, help="α (the exact value; the label is derived)")
    p.add_argument("--shard", required=True, type=int)
    p.add_argument("--seed", required=True, type=int, help="seed of this shard (see amorgs.data.seeds)")
    p.add_argument("--starts", required=True, type=int, help="uniform initial guesses in this shard")
    p.add_argument("--workers", type=int, default=1, help="solver processes")
    p.add_argument("--solver-options", default="{}", help="JSON object of solver options")
    p.add_argument("--output", required=True)
    p.set_defaults(func=cmd_generate)

    p = sub.add_parser("merge", help="merge the shard tables of one (problem, α)")
    p.add_argument("--problem", required=True, choices=("dejong", "cr3bp"))
    p.add_argument("--alpha", required=True, help="α label, e.g. 0.150")
    p.add_argument("--inputs", required=True, nargs="+")
    p.add_argument("--output", required=True)
    p.set_defaults(func=cmd_merge)

    p = sub.add_parser("filter", help="β-filter every α table of a problem; write a quality report")
    p.add_argument("--problem", required=True, choices=("dejong", "cr3bp"))
    p.add_argument("--inputs", required=True, nargs="+")
    p.add_argument("--min-final-mass-kg", type=float, help="β on the final mass m_f (kg)")
    p.add_argument("--max-objective", type=float, help="keep objective ≤ this")
    p.add_argument("--output", required=True)
    p.add_argument("--report", required=True)
    p.set_defaults(func=cmd_filter)

    p = sub.add_parser("train-dejong-cvae", help="train the GMM-prior CVAE on the De Jong minima")
    p.add_argument("--data", required=True, help="high_quality.parquet")
    p.add_argument("--train-alphas", required=True, type=float, nargs="+")
    p.add_argument("--preset", required=True, choices=("dejong_paper", "small"))
    p.add_argument("--learning-rate", required=True, type=float)
    p.add_argument("--epochs", required=True, type=int)
    p.add_argument("--batch-size", required=True, type=int)
    p.add_argument("--seed", required=True, type=int)
    p.add_argument("--threads", type=int, default=1, help="torch CPU threads")
    p.add_argument("--output", required=True)
    p.set_defaults(func=cmd_train_dejong_cvae)

    p = sub.add_parser("predict-dejong-cvae", help="sample the CVAE at the test α and score the samples")
    p.add_argument("--model", required=True)
    p.add_argument("--test-alphas", required=True, type=float, nargs="+")
    p.add_argument("--n-samples", required=True, type=int)
    p.add_argument("--seed", required=True, type=int)
    p.add_argument("--radius", required=True, type=float)
    p.add_argument("--samples", required=True)
    p.add_argument("--metrics", required=True)
    p.set_defaults(func=cmd_predict_dejong_cvae)

    p = sub.add_parser("fig02-foxholes", help="Fig. 2: the classic 25-foxhole De Jong function")
    p.add_argument("--output", required=True)
    p.set_defaults(func=cmd_fig02_foxholes)

    p = sub.add_parser("fig16-dejong-predictions", help="Fig. 16: De Jong training minima and CVAE samples")
    p.add_argument("--data", required=True, help="high_quality.parquet (training minima)")
    p.add_argument("--samples", required=True, help="predicted samples parquet")
    p.add_argument("--train-alphas", required=True, type=float, nargs="+")
    p.add_argument("--output", required=True)
    p.set_defaults(func=cmd_fig16_dejong_predictions)

    p = sub.add_parser("boundary-conditions", help="recompute (or --check) the CR3BP boundary conditions")
    p.add_argument("--output", help="the resource file (default: resources/boundary_conditions.json)")
    p.add_argument("--check", action="store_true", help="compare the stored file with a fresh computation")
    p.add_argument("--rel-tol", type=float, default=1e-9, help="--check: relative tolerance on numbers")
    p.set_defaults(func=cmd_boundary_conditions)

    p = sub.add_parser("ui", help="open the MLflow UI on results/mlflow")
    p.add_argument("--host", default="127.0.0.1")
    p.add_argument("--port", type=int, default=5000)
    p.set_defaults(func=cmd_ui)

    p = sub.add_parser("check-outputs", help="check that every output of a config exists, is non-empty and tracked")
    p.add_argument("--config", required=True, help="config file, e.g. config/smoke.yaml")
    p.add_argument("--schema", default=str(SCHEMA_PATH))
    p.add_argument("--no-mlflow", action="store_true", help="skip the MLflow checks")
    p.set_defaults(func=cmd_check_outputs)
    return parser


def main(argv: list[str] | None = None) -> None:
    args = build_parser().parse_args(argv)
    try:
        args.func(args)
    except ConfigError as exc:
        sys.exit(f"amorgs {args.command}: {exc}")
