# Shared setup: the validated typed config (CFG), wildcard constraints, parameter helpers and the MLflow
# hooks of the Snakefile's onstart/onsuccess/onerror.  No rules here.
import json
import os
import sys
from pathlib import Path

from snakemake_interface_executor_plugins.settings import DeploymentMethod

from amorgs import layout
from amorgs.ablation.arms import NEEDS_HIGH_QUALITY, NEEDS_MODELS
from amorgs.config import load_workflow_config
from amorgs.data.library import library_files as _library_files
from amorgs.data.seeds import cell_seed, shard_seed

CFG = load_workflow_config(config, workflow.configfiles, workflow.source_path("../schemas/config.schema.yaml"))


# Jobs run `python -m amorgs ...`: unless a conda environment provides it, that `python` is the interpreter
# running Snakemake (so `.venv/bin/snakemake` works without activating the venv, here and on SLURM nodes).
envvars:
    "PATH",


if DeploymentMethod.CONDA not in workflow.deployment_settings.deployment_method:
    os.environ["PATH"] = os.pathsep.join([str(Path(sys.executable).parent), os.getenv("PATH", "")])


wildcard_constraints:
    problem="dejong|cr3bp",
    alpha=r"\d+\.\d{3}",
    shard=r"\d+",
    model="cvae_gmm|vanilla_cvae|lstm",
    fraction=r"0\.\d+",
    sampler="|".join(CFG.ablation.samplers),


def problem_cfg(wildcards):
    """The config section of the {problem} wildcard."""
    return getattr(CFG.problems, wildcards.problem)


def floats(values):
    """A list of numbers as one shell argument list."""
    return " ".join(map(repr, values))


def alpha_value(wildcards):
    """The exact α behind the {alpha} label."""
    return problem_cfg(wildcards).alpha_values()[wildcards.alpha]


def seed_of_shard(wildcards):
    """The seed of one generate job, derived from (base seed, problem, α, shard)."""
    return shard_seed(CFG.seed, wildcards.problem, alpha_value(wildcards), int(wildcards.shard))


def library_shards(wildcards):
    """The committed library files of this (problem, α), if the problem's library is enabled."""
    library = problem_cfg(wildcards).library
    if not library.enabled:
        return []
    return [str(p) for p in _library_files(library.path, wildcards.problem, wildcards.alpha)]


def library_arguments(wildcards):
    """The merge's library options: the library root and the optional fixed slice."""
    library = problem_cfg(wildcards).library
    slice_ = "" if library.max_rows_per_alpha is None else f" --library-max-rows {library.max_rows_per_alpha}"
    return f"--library-dir {library.path}{slice_}"


def seed_of_cell(wildcards):
    """The seed of one ablation cell, derived from (ablation seed, α, sampler)."""
    return cell_seed(CFG.ablation.seed, "cr3bp", CFG.problems.cr3bp.alpha_values()[wildcards.alpha], wildcards.sampler)


def train_cr3bp_params(seed=None):
    """The training settings shared by train_cr3bp, train_cr3bp_fraction and (with its own seed and
    --replicate) train_cr3bp_replicate."""
    m = CFG.cr3bp_models
    replicate = "" if seed is None else " --replicate"
    return (
        f"--train-alphas {floats(CFG.problems.cr3bp.alphas.train_values())} --preset {m.preset} "
        f"--learning-rate {m.learning_rate!r} --epochs {m.epochs} --batch-size {m.batch_size} "
        f"--seed {m.seed if seed is None else seed}{replicate}"
    )


def solver_options(wildcards):
    """The problem's solver options as one JSON argument."""
    return json.dumps(problem_cfg(wildcards).solver_options(), sort_keys=True)


def filter_arguments(wildcards):
    """The problem's β-filter thresholds as command-line options (thresholds set to null are omitted)."""
    thresholds = problem_cfg(wildcards).filter_thresholds()
    return " ".join(f"--{k.replace('_', '-')} {v!r}" for k, v in thresholds.items() if v is not None)


def start_tracking():
    """onstart: open this invocation's MLflow parent run (or switch tracking off)."""
    from amorgs import tracking

    if CFG.mlflow.enabled:
        sources = [str(f) for f in workflow.configfiles]
        tracking.start_invocation(config, CFG.hash, CFG.mlflow.experiment, sources)
    else:
        tracking.stop_tracking()


def finish_tracking(status):
    """onsuccess/onerror: close the parent run."""
    if CFG.mlflow.enabled:
        from amorgs import tracking

        tracking.finish_invocation(status)


# ---- ablation (rules in ablation.smk)
def ablation_cell_inputs(wildcards, model_template=layout.CR3BP_MODEL):
    """The checkpoints the {sampler} loads (none for uniform / nearest_alpha*) and, for the reuse baselines,
    the filtered high-quality table (they draw from its training-α rows)."""
    fmt = dict(wildcards.items())
    inputs = {"models": [model_template.format(**{**fmt, "model": m}) for m in NEEDS_MODELS[wildcards.sampler]]}
    if wildcards.sampler in NEEDS_HIGH_QUALITY:
        inputs["high_quality"] = layout.HIGH_QUALITY.format(problem="cr3bp")
    return inputs


def ablation_cell_args(wildcards, input):
    """The sampler-specific arguments of `amorgs ablation-cell`."""
    args = []
    if len(input.get("models", [])):
        args.append(f"--models-dir {os.path.dirname(input.models[0])}")
    if "high_quality" in input.keys():
        a = CFG.ablation
        args.append(
            f"--high-quality {input.high_quality} --train-alphas {floats(CFG.problems.cr3bp.alphas.train_values())} "
            f"--perturbation-scale {a.perturbation_scale!r} --gmm-components {a.gmm_components}"
        )
    return " ".join(args)


def seed_of_replicate_cell(wildcards):
    """The seed of one replicate cell: as seed_of_cell, with the model seed mixed into the sampler's name."""
    alpha = CFG.problems.cr3bp.alpha_values()[wildcards.alpha]
    return cell_seed(CFG.ablation.seed, "cr3bp", alpha, f"{wildcards.sampler}@seed={wildcards.mseed}")
