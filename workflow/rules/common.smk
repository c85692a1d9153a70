# Shared setup: the validated typed config (CFG), wildcard constraints, parameter helpers and the MLflow
# hooks of the Snakefile's onstart/onsuccess/onerror.  No rules here.
import json
import os
import sys
from pathlib import Path

from snakemake_interface_executor_plugins.settings import DeploymentMethod

from amorgs import layout
from amorgs.config import load_workflow_config
from amorgs.data.seeds import shard_seed


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


def problem_cfg(wildcards):
    """The config section of the {problem} wildcard."""
    return getattr(CFG.problems, wildcards.problem)


def alpha_value(wildcards):
    """The exact α behind the {alpha} label."""
    return problem_cfg(wildcards).alpha_values()[wildcards.alpha]


def seed_of_shard(wildcards):
    """The seed of one generate job, derived from (base seed, problem, α, shard)."""
    return shard_seed(CFG.seed, wildcards.problem, alpha_value(wildcards), int(wildcards.shard))


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
