"""The step registry (amorgs.steps): one source for each job's settings, outputs and expected jobs."""

from __future__ import annotations

import json

import pytest
from config_files import load

from amorgs import steps
from amorgs.errors import InputError


def test_every_step_has_settings_for_every_job_of_every_shipped_config():
    for name in ("smoke", "default", "study", "paper"):
        cfg = load(name)
        steps.check_settings(cfg)
        jobs = steps.expected_jobs(cfg)
        targets = steps.targets(cfg)
        assert len(targets) == len(set(targets)), f"{name}: two jobs write one file"
        assert {rule for rule, _ in jobs} <= set(steps.registry())


def test_every_job_takes_its_resources_from_the_config_through_its_step():
    """A rule's threads, memory and runtime come from its step (workflow/rules/common.smk: step_threads,
    step_resources); the step reads them from the config section that sizes the job."""
    from amorgs.config import Job

    cfg = load("paper")
    for rule, wildcards in steps.expected_jobs(cfg):
        assert isinstance(steps.job_resources(rule, cfg, wildcards), Job), rule
    cr3bp = cfg.problems.cr3bp.generate
    assert steps.job_resources("generate", cfg, {"problem": "cr3bp", "alpha": "0.150", "shard": "0"}) == Job(
        threads=cr3bp.workers, mem_mb=cr3bp.mem_mb, runtime_min=cr3bp.runtime_min) == Job(
        threads=16, mem_mb=16000, runtime_min=1440)
    assert steps.job_resources("ablation_cell", cfg, {"alpha": "0.150", "sampler": "amorgs"}).threads == 16
    assert steps.job_resources("train_cr3bp", cfg, {"model": "lstm"}) == cfg.resources.train
    assert steps.job_resources("ablation_report", cfg, {}) == cfg.resources.figure


def test_output_templates_keep_the_wildcards():
    assert steps.output_templates("generate") == {"table": "results/{problem}/solutions/alpha={alpha}/shard-{shard}.parquet"}
    assert steps.output_templates("ablation_cell_replicate")["table"].count("{") == 3


def test_job_spec_round_trip_and_a_bad_job_is_one_clear_error():
    cfg = load("smoke")
    w = {"problem": "cr3bp", "alpha": "0.850", "shard": "0"}
    spec = json.loads(steps.job_spec("generate", cfg, w, {}, {"table": "x.parquet"}, 2))
    assert spec["rule"] == "generate" and spec["wildcards"] == w and spec["threads"] == 2
    assert spec["settings"]["solver"]["max_iter"] == cfg.problems.cr3bp.solver.max_iter
    assert spec["settings"]["alpha"] == 0.85
    with pytest.raises(InputError, match="not JSON"):
        steps.run_job("{")
    with pytest.raises(InputError, match="lacks"):
        steps.run_job(json.dumps({"rule": "generate"}))
    with pytest.raises(InputError, match="no workflow step 'nope'"):
        steps.run_job(json.dumps({**spec, "rule": "nope"}))


def test_check_rules_catches_a_rule_handing_over_another_name_and_a_step_without_rule():
    def job():
        pass

    job.step = "filter"
    rules = {name: None for name in steps.registry()}
    steps.check_rules({**rules, "all": None})
    with pytest.raises(RuntimeError, match=r"rule merge hands its job to step 'filter'"):
        steps.check_rules({**rules, "merge": job})
    del rules["ablation_report"]
    with pytest.raises(RuntimeError, match=r"steps without a rule of their name: \['ablation_report'\]"):
        steps.check_rules(rules)


def test_snakemake_wildcards_give_the_replicate_its_own_seed():
    """Snakemake hands params functions a Wildcards object (a list subclass): the settings must see its keys."""
    import snakemake.api  # noqa: F401  (import order of snakemake's own modules)
    from snakemake.iocontainers import Wildcards

    cfg = load("study")
    cell = {"alpha": "0.150", "sampler": "amorgs"}
    main = json.loads(steps.job_spec("ablation_cell", cfg, Wildcards(fromdict=cell), {}, {}, 1))["settings"]
    rep = json.loads(steps.job_spec("ablation_cell_replicate", cfg, Wildcards(fromdict={**cell, "mseed": "12"}),
                                    {}, {}, 1))["settings"]
    assert rep["model_seed"] == 12 and main["model_seed"] == cfg.cr3bp_models.seed
    assert rep["seed"] != main["seed"]
    train = json.loads(steps.job_spec("train_cr3bp_replicate", cfg, Wildcards(fromdict={"mseed": "13", "model": "lstm"}),
                                      {}, {}, 1))["settings"]
    assert train["seed"] == 13 and train["model"] == "lstm"


def test_a_workflow_that_reads_a_missing_library_is_refused_naming_the_key(tmp_path):
    """Issue 39: with the library enabled and data/library missing, the workflow planned and ran every job with
    no library and no warning (amorgs design refused the same situation)."""
    from amorgs.config import from_mapping
    from amorgs.errors import ConfigError
    from config_files import mapping

    data = mapping("default")
    data["problems"]["cr3bp"]["library"].update(enabled=True, path=str(tmp_path / "nope"))
    with pytest.raises(ConfigError, match=r"problems\.cr3bp\.library\.enabled: no library at .*nope/cr3bp"):
        steps.check_libraries(from_mapping(data, "test"))
    data["problems"]["cr3bp"]["library"]["enabled"] = False
    steps.check_libraries(from_mapping(data, "test"))  # nothing to read, nothing to check


def test_only_short_jobs_defer_their_mlflow_run():
    """Merges and small shards of a quick-solve family (De Jong) leave their run to the invocation's end; a large
    De Jong shard (seen RUNNING while it works) and every CR3BP shard open their own."""
    from amorgs.steps import job_settings, registry
    from amorgs.steps.generate import QUICK_SHARD_STARTS

    cfg = load("default")
    steps = registry()

    def deferred(rule, w):
        step = steps[rule]
        return step.deferred_tracking(step.settings_type.model_validate(job_settings(rule, cfg, w)))

    assert deferred("generate", {"problem": "dejong", "alpha": "0.000", "shard": "0"})
    assert cfg.problems.dejong.generate.starts_per_shard <= QUICK_SHARD_STARTS
    assert not deferred("generate", {"problem": "cr3bp", "alpha": "0.100", "shard": "0"})
    assert deferred("merge", {"problem": "cr3bp", "alpha": "0.100"})
    big = steps["generate"].settings_type.model_validate(
        {**job_settings("generate", cfg, {"problem": "dejong", "alpha": "0.000", "shard": "0"}),
         "starts": QUICK_SHARD_STARTS + 1})
    assert not steps["generate"].deferred_tracking(big)
    assert not any(steps[r].deferred_tracking(None) for r in ("train_cr3bp", "ablation_cell", "filter"))
