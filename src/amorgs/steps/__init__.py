"""The workflow's steps: one :class:`Step` per Snakemake rule, the single source of each job's settings,
outputs and expected jobs.

A step says, for one rule:

- ``resources(cfg, wildcards)``: the threads, memory (MB) and wall-clock limit (minutes) of one job, from the
  config (a :class:`~amorgs.config.Job`; :func:`resources_of` for the ``resources`` section), which the rule
  takes through ``step_threads``/``step_resources`` (``workflow/rules/common.smk``);
- ``settings(cfg, wildcards)``: the part of the validated :class:`~amorgs.config.Config` the job needs, as
  one typed object (a :class:`~amorgs.config.Section` subclass, :attr:`Step.settings_type`).  The rule passes
  it to the job as JSON (so a changed setting re-runs the job: Snakemake's params trigger), and the job
  validates it again before doing anything;
- ``run(job, run)``: the work, given a :class:`Job` (wildcards, named inputs and outputs, threads, settings)
  and its MLflow child run (:class:`amorgs.tracking.JobRun`);
- ``deferred_tracking(settings)``: whether a job is so short (a merge, a small De Jong shard) that its MLflow run is
  written when the invocation ends, from what the job logged (:mod:`amorgs.tracking`), not opened by the job;
- ``jobs(cfg)``: the wildcards of every job of this rule that a complete run of ``cfg`` executes, and
  ``outputs(wildcards)``: the named outputs of one job (path templates of :mod:`amorgs.layout`).  From these
  two come the targets of ``rule all`` (:func:`targets`) and the MLflow jobs ``amorgs check-outputs`` expects
  (:func:`expected_jobs`) — the job graph is written once, here and in the rule's inputs.

Every rule runs the same command, ``python -m amorgs step --job <JSON>``: the wildcards and the named inputs
and outputs in the JSON are those Snakemake resolved, and they tag the job's MLflow run (:func:`run_job`).
The rule's name is the one thing a rule writes itself (``params: job=step_job("<rule>")``: Snakemake gives a
params function no rule name); :func:`check_rules` checks it against Snakemake's own name at parse time.

Adding a step: add it to the ``STEPS`` of its stage's module under ``amorgs/steps/`` (a new module needs
``STEPS`` and ``STAGE``, its place in the workflow's order; it is found by itself), and add one rule of the
same name (its inputs and log; ``output: **step_outputs(...)``, ``threads: step_threads(...)``,
``resources: **step_resources(...)``, ``params: **step_params(...)``, ``shell: STEP``).
"""

from __future__ import annotations

import importlib
import json
import pkgutil
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

from amorgs.config import Config, Section
from amorgs.config import Job as JobResources
from amorgs.errors import ConfigError, InputError

Wildcards = Mapping[str, str]
Outputs = dict[str, "str | list[str]"]



@dataclass(frozen=True)
class Job:
    """One job as Snakemake scheduled it: its rule, wildcards, named inputs and outputs (a path or a list of
    paths each), cores, and the step's validated settings."""

    rule: str
    wildcards: dict[str, str]
    input: dict[str, Any]
    output: dict[str, Any]
    threads: int
    settings: Any


@dataclass(frozen=True)
class Step:
    """One workflow step (one Snakemake rule); see the module docstring."""

    rule: str
    settings_type: type[Section]
    settings: Callable[[Config, Wildcards], Section]
    run: Callable[[Job, Any], None]
    jobs: Callable[[Config], list[dict[str, str]]]
    outputs: Callable[[Wildcards], Outputs]
    resources: Callable[[Config, Wildcards], JobResources]
    #: (caption file under workflow/report/ without .rst, category) of the figures in ``snakemake --report``.
    report: tuple[str, str] | None = None
    description: str = field(default="")
    #: Whether a job (of these settings) does seconds of work, so that its MLflow run is written from its journal
    #: when the invocation ends instead of by the job (``tracking.job_run(deferred=True)``: ≈ 4.5 s less a job).
    deferred_tracking: Callable[[Any], bool] = field(default=lambda settings: False)


def resources_of(key: str) -> Callable[[Config, Wildcards], JobResources]:
    """``resources`` of a step whose every job takes the config's ``resources.<key>`` (e.g. ``"merge"``)."""
    return lambda cfg, wildcards: getattr(cfg.resources, key)


def once_if(section: str) -> Callable[[Config], list[dict[str, str]]]:
    """``jobs`` of a step without wildcards: one job when the config section at the dotted path ``section``
    (e.g. ``"dejong_cvae"``, ``"problems.dejong"``) is enabled, none otherwise."""

    def jobs(cfg: Config) -> list[dict[str, str]]:
        obj = cfg
        for part in section.split("."):
            obj = getattr(obj, part)
        return [{}] if obj.enabled else []

    return jobs


def _load() -> dict[str, Step]:
    """Every ``STEPS`` of the modules of this package, ordered by their ``STAGE`` (the workflow's order)."""
    modules = [importlib.import_module(f"{__name__}.{m.name}") for m in pkgutil.iter_modules(__path__)]
    steps: dict[str, Step] = {}
    for module in sorted((m for m in modules if hasattr(m, "STEPS")), key=lambda m: m.STAGE):
        for step in module.STEPS:
            if step.rule in steps:
                raise RuntimeError(f"step {step.rule!r} is defined twice")
            steps[step.rule] = step
    return steps


_REGISTRY: dict[str, Step] | None = None


def registry() -> dict[str, Step]:
    """Rule name → :class:`Step`, every step of the workflow (loaded once; the stage modules import their
    heavy dependencies — solvers, torch, matplotlib — only inside ``run``)."""
    global _REGISTRY
    if _REGISTRY is None:
        _REGISTRY = _load()
    return _REGISTRY


def get_step(rule: str) -> Step:
    steps = registry()
    if rule not in steps:
        raise InputError(f"no workflow step {rule!r}; steps: {', '.join(steps)}")
    return steps[rule]


# ------------------------------------------------------------------------------------ the job graph


def _paths(value: str | list[str]) -> list[str]:
    """A named output's paths (one path or a list of them)."""
    return [value] if isinstance(value, str) else list(value)


def _flat(outputs: Outputs) -> list[str]:
    return [p for v in outputs.values() for p in _paths(v)]


def expected_jobs(cfg: Config) -> list[tuple[str, dict[str, str]]]:
    """(rule, wildcards) of every job a complete run of ``cfg`` executes."""
    return [(rule, w) for rule, step in registry().items() for w in step.jobs(cfg)]


def targets(cfg: Config) -> list[str]:
    """Every output of every job of ``cfg``: the inputs of ``rule all``, and what ``check-outputs`` checks."""
    return [p for rule, w in expected_jobs(cfg) for p in _flat(registry()[rule].outputs(w))]


def outputs_of(rule: str, cfg: Config, name: str, **match: str) -> list[str]:
    """Output ``name`` of every job of ``rule`` in ``cfg`` whose wildcards include ``match`` — the inputs of
    a downstream rule (e.g. the shards of one (problem, α) for its merge)."""
    step = registry()[rule]
    return [p for w in step.jobs(cfg) if all(w.get(k) == v for k, v in match.items())
            for p in _paths(step.outputs(w)[name])]


def check_settings(cfg: Config) -> None:
    """Build the settings of every job of ``cfg`` once (the Snakefile calls this at start), so whatever a
    job's settings would reject is rejected before the first job runs."""
    for rule, w in expected_jobs(cfg):
        registry()[rule].settings(cfg, w)


def check_libraries(cfg: Config) -> None:
    """Check every solution library ``cfg`` reads against its manifest (the Snakefile calls this at start):
    a tampered, truncated, missing or unlisted file stops the workflow before the first job, naming the file
    (:func:`amorgs.data.library.verify_library`)."""
    from amorgs.data.library import verify_library

    for name in type(cfg.problems).model_fields:
        section = getattr(cfg.problems, name)
        if section.enabled and section.library.enabled and verify_library(section.library.path, name) is None:
            raise ConfigError(f"problems.{name}.library.enabled: no library at {section.library.path}/{name} "
                              f"(no provenance.json) — restore it (git checkout {section.library.path}) or set "
                              f"problems.{name}.library.enabled: false")


def check_rules(rules: Mapping[str, Any]) -> None:
    """Check the workflow's rules against the steps: ``rules`` maps each Snakemake rule name to its
    ``params.job`` (None for rules without one, like ``all``).  Every step needs a rule of its name, and a
    rule's job must be built for that rule; otherwise a ``RuntimeError`` names both."""
    for name, job in rules.items():
        step = getattr(job, "step", None)
        if job is not None and step != name:
            raise RuntimeError(f"rule {name} hands its job to step {step!r}: use params: **step_params({name!r})")
    missing = sorted(set(registry()) - set(rules))
    if missing:
        raise RuntimeError(f"steps without a rule of their name: {missing}")


class _Template(dict):
    """``str.format_map`` mapping that leaves every wildcard as ``{name}`` (the rule's output templates)."""

    def __getitem__(self, key: str) -> str:
        return "{" + key + "}"


def output_templates(rule: str) -> Outputs:
    """The named output templates of ``rule`` (wildcards left as ``{name}``), for the rule's ``output:``."""
    return registry()[rule].outputs(_Template())


# ---------------------------------------------------------------------------------------- running a job


def job_resources(rule: str, cfg: Config, wildcards: Wildcards) -> JobResources:
    """Threads, memory (MB) and wall-clock limit (minutes) of one job of ``rule`` (the rule's ``threads`` and
    ``resources``)."""
    return registry()[rule].resources(cfg, dict(wildcards.items()))


def job_settings(rule: str, cfg: Config, wildcards: Wildcards) -> dict:
    """The settings of one job of ``rule``: its step's typed slice of ``cfg`` for these wildcards, as JSON data."""
    wildcards = dict(wildcards.items())  # Snakemake's Wildcards is a list: `"key" in` it tests the values
    return registry()[rule].settings(cfg, wildcards).model_dump(mode="json")


def settings_param(rule: str, cfg: Config, wildcards: Wildcards) -> str:
    """``params.settings`` of a job: :func:`job_settings` as sorted JSON, from the config and the wildcards
    only.  Snakemake's params rerun trigger skips params derived from inputs or outputs, as ``params.job``
    is, so this one is what makes a changed setting rerun exactly the jobs it reaches."""
    return json.dumps(job_settings(rule, cfg, wildcards), sort_keys=True)


def job_spec(rule: str, cfg: Config, wildcards: Wildcards, input: Mapping, output: Mapping, threads: int) -> str:
    """The JSON a rule hands to ``amorgs step`` (Snakemake's named inputs and outputs, the step's settings)."""
    wildcards = dict(wildcards.items())  # Snakemake's Wildcards is a list: `"key" in` it tests the values
    return json.dumps(
        {
            "rule": rule,
            "wildcards": wildcards,
            "input": {k: (v if isinstance(v, str) else list(v)) for k, v in input.items()},
            "output": {k: (v if isinstance(v, str) else list(v)) for k, v in output.items()},
            "threads": int(threads),
            "settings": job_settings(rule, cfg, wildcards),
        },
        sort_keys=True,
    )


def run_job(spec_json: str) -> None:
    """Run one job from the JSON of :func:`job_spec` inside its MLflow child run (tagged with the rule and the
    wildcards Snakemake gave; the settings logged as parameters).  The job ends, its run KILLED, if the
    workflow that started it is killed (:mod:`amorgs.lifeline`)."""
    from amorgs import lifeline, tracking

    try:
        spec = json.loads(spec_json)
    except json.JSONDecodeError as exc:
        raise InputError(f"step --job is not JSON: {exc}") from None
    missing = {"rule", "wildcards", "input", "output", "threads", "settings"} - set(spec)
    if missing:
        raise InputError(f"step --job lacks {sorted(missing)}")
    rule = spec["rule"]
    step = get_step(rule)
    settings = step.settings_type.model_validate(spec["settings"])
    job = Job(rule, dict(spec["wildcards"]), spec["input"], spec["output"], int(spec["threads"]), settings)
    with tracking.job_run(rule, job.wildcards, deferred=step.deferred_tracking(settings)) as run:
        lifeline.watch_workflow()
        run.log_params(settings.model_dump(mode="json"))
        step.run(job, run)


def run_step(rule: str, cfg: Config, wildcards: Wildcards, input: Mapping, output: Mapping, threads: int = 1) -> None:
    """Run one job of ``rule`` in this process, as Snakemake would (for tests and notebooks)."""
    run_job(job_spec(rule, cfg, wildcards, input, output, threads))
