# Shared setup: the validated typed config (CFG), wildcard constraints from the registries, the one command
# every rule runs, and the MLflow hooks of the Snakefile's onstart/onsuccess/onerror.  No rules here.
#
# Each workflow rule runs one step of amorgs.steps, of the same name. Its outputs come from the step
# (step_outputs); so do its threads, memory and wall-clock limit (step_threads, step_resources: the step's
# slice of the config's resources); its settings, the step's typed slice of the config, reach the job as JSON
# with the wildcards and the named inputs and outputs Snakemake resolved (params.job); the same settings alone
# are params.settings, which re-runs a job whose settings changed (step_params); and its command is STEP,
# `python -m amorgs step --job ...`, which tags the job's MLflow run with those wildcards.  A rule itself
# declares only its inputs and its log.
import os
import sys
from pathlib import Path

from snakemake_interface_executor_plugins.settings import DeploymentMethod

from amorgs import layout, lifeline, steps
from amorgs.ablation.arms import SAMPLER_NAMES
from amorgs.solvers.basin_hopping import STRATEGIES
from amorgs.config import load_workflow_config
from amorgs.errors import ConfigError, InputError
from amorgs.data.library import library_files as _library_files
from amorgs.models.names import CR3BP_MODELS
from amorgs.problems import PROBLEMS

try:
    CFG = load_workflow_config(config, [os.path.relpath(f) for f in workflow.configfiles])
    steps.check_settings(CFG)  # whatever a job's settings would reject fails here, before the first job
    steps.check_libraries(CFG)  # so does a library file that differs from its manifest, or an unlisted one
except (ConfigError, InputError) as exc:  # one clear message naming the file (and key), no Python traceback
    sys.exit(f"amorgs: {exc}")


# Jobs run `python -m amorgs ...`: unless a conda environment provides it, that `python` is the interpreter
# running Snakemake (so `.venv/bin/snakemake` works without activating the venv, here and on SLURM nodes).
envvars:
    "PATH",


if DeploymentMethod.CONDA not in workflow.deployment_settings.deployment_method:
    os.environ["PATH"] = os.pathsep.join([str(Path(sys.executable).parent), os.getenv("PATH", "")])

# Jobs die with this Snakemake process, even when it is killed outright (kill -9): each job watches it.
lifeline.mark_workflow()


wildcard_constraints:
    problem="|".join(PROBLEMS),
    alpha=r"\d+\.\d{3}",
    shard=r"\d+",
    model="|".join(CR3BP_MODELS),
    fraction=r"0\.\d+",
    sampler="|".join(SAMPLER_NAMES),
    mseed=r"\d+",
    source=r"\d+\.\d{3}",
    strategy="|".join(STRATEGIES),


# The one command of every rule.
STEP = "python -m amorgs step --job {params.job:q} > {log} 2>&1"


def step_job(name):
    """params.job of the rule called ``name``, the JSON its job reads (wildcards, named inputs, outputs, settings).
    The Snakefile checks that each rule hands over its own name (steps.check_rules)."""

    def job(wildcards, input, output, threads):
        return steps.job_spec(name, CFG, wildcards, input, output, threads)

    job.step = name
    return job


def step_threads(name):
    """threads of the rule called ``name``, from its step's resources for the job's wildcards (steps.job_resources)."""
    return lambda wildcards: steps.job_resources(name, CFG, wildcards).threads


def step_resources(name):
    """resources of the rule called ``name``, mem_mb (MB) and runtime (minutes), from its step as for threads."""
    return {
        "mem_mb": lambda wildcards: steps.job_resources(name, CFG, wildcards).mem_mb,
        "runtime": lambda wildcards: steps.job_resources(name, CFG, wildcards).runtime_min,
    }


def step_params(name):
    """The params of the rule called ``name``, job (step_job) and settings, its job's settings as JSON from
    config and wildcards only (steps.settings_param); Snakemake's params trigger ignores job, which is
    derived from inputs and outputs, so settings is what re-runs the job when they change."""

    def settings(wildcards):
        return steps.settings_param(name, CFG, wildcards)

    return {"job": step_job(name), "settings": settings}


def step_outputs(rule):
    """The named outputs of ``rule`` (its step's templates); figures are marked for `snakemake --report`."""
    outputs = steps.output_templates(rule)
    caption = steps.registry()[rule].report
    if caption is None:
        return outputs

    def mark(path):
        if not path.endswith(".png"):
            return path
        return report(path, caption=f"../report/{caption[0]}.rst", category=caption[1])

    return {k: (mark(v) if isinstance(v, str) else [mark(p) for p in v]) for k, v in outputs.items()}


def library_shards(wildcards):
    """The committed library files of this (problem, α), if the problem's library is enabled."""
    library = getattr(CFG.problems, wildcards.problem).library
    if not library.enabled:
        return []
    return [str(p) for p in _library_files(library.path, wildcards.problem, wildcards.alpha)]


def start_tracking():
    """onstart: open this invocation's MLflow parent run (or switch tracking off)."""
    from amorgs import tracking

    if CFG.mlflow.enabled:
        sources = [str(f) for f in workflow.configfiles]
        tracking.start_invocation(CFG.model_dump(mode="json"), CFG.hash, CFG.mlflow.experiment, sources)
    else:
        tracking.stop_tracking()


def finish_tracking(status):
    """onsuccess/onerror: on success the runtime report (per rule, from the jobs' benchmark files), then close
    the parent run."""
    if status == "FINISHED":
        from amorgs.runtime_report import report_finished_workflow

        report_finished_workflow(CFG.mlflow.enabled)
    if CFG.mlflow.enabled:
        from amorgs import tracking

        tracking.finish_invocation(status)


def global_search_cell_inputs(wildcards):
    """What a global-search cell's {sampler} draws on (as an ablation cell: amorgs.steps.global_search)."""
    from amorgs.steps.global_search import search_cell_inputs

    return search_cell_inputs(wildcards.sampler, wildcards)


def ablation_cell_inputs(wildcards, model_template=layout.CR3BP_MODEL):
    """What the {sampler}'s arm draws on: the checkpoints it loads and, if it needs it, the filtered
    high-quality table (amorgs.steps.ablation.cell_inputs, from the table of arms)."""
    from amorgs.steps.ablation import cell_inputs

    return cell_inputs(wildcards.sampler, model_template, wildcards)
