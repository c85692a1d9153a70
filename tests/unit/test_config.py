"""Config files and the typed config model that is their schema."""

from __future__ import annotations

import json
import math

import pytest
from config_files import CONFIGS, ROOT, load, mapping, overrides, write

from amorgs import config as C
from amorgs import steps
from amorgs.alphas import alpha_label


def test_the_main_configs_ship():
    assert {"smoke", "default", "paper", "study", "library"} <= set(CONFIGS)


@pytest.mark.parametrize("name", CONFIGS)
def test_shipped_configs_validate(name):
    cfg = load(name)
    assert cfg.problems.enabled(), "every config runs at least one problem"
    assert len(cfg.hash) == 12


def test_dejong_alphas_follow_the_paper():
    dj = load("default").problems.dejong
    train = dj.alphas.train_values()
    assert len(train) == 51
    assert all(math.isclose(a, i * math.pi / 100, abs_tol=1e-15) for i, a in enumerate(train))
    assert [round(a * 9 / math.pi, 12) for a in dj.alphas.test] == [1, 2, 3, 4]


def test_cr3bp_alphas_follow_the_spec():
    cr = load("paper").problems.cr3bp
    assert sorted(cr.alphas.train_values()) == [0.1, 0.13, 0.16, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9, 1.0]
    assert cr.alphas.test == (0.15, 0.85)
    assert cr.filter.min_final_mass_kg == 415.0
    assert list(cr.alpha_values())[:3] == ["0.100", "0.130", "0.160"]


def _error(tmp_path, data) -> str:
    path = write(tmp_path, data)
    with pytest.raises(C.ConfigError) as err:
        C.load_config(path)
    assert str(path) in str(err.value)
    return str(err.value)


def test_every_problem_is_one_line_naming_file_and_key(tmp_path):
    data = overrides()
    data["problems"]["dejong"]["generate"]["startz_per_shard"] = 3
    data["dejong_cvae"]["epochs"] = "many"
    data["sed"] = data.pop("seed")
    data["problems"]["cr3bp"]["alphas"]["train"] = {"num": 3}  # a grid needs start and stop: a list is the default
    lines = _error(tmp_path, data).splitlines()[1:]
    msg = "\n".join(lines)
    assert "bad.yaml: problems.dejong.generate.startz_per_shard: unknown key" in msg
    assert "bad.yaml: dejong_cvae.epochs: Input should be a valid integer" in msg and "(got 'many')" in msg
    assert "bad.yaml: sed: unknown key" in msg
    assert "bad.yaml: problems.cr3bp.alphas.train.start: required key is missing" in msg
    assert "bad.yaml: problems.cr3bp.alphas.train.stop: required key is missing" in msg
    assert len(lines) == 6 and "seed" not in msg.replace("sed", "")  # a key left out takes its default


def test_the_defaults_are_the_main_job_but_for_its_bounded_run():
    """config/default.yaml is the typed defaults but for a bounded run (issue 40): a fixed slice of the library per
    α, capped per-α training samples and early stopping — the typed defaults, which every other config starts
    from, read and train on everything."""
    assert overrides("default") == {
        "problems": {"cr3bp": {"library": {"max_rows_per_alpha": 2000}}},
        "cr3bp_models": {"max_rows_per_alpha": 600, "validation_fraction": 0.1, "patience": 30},
        "dejong_cvae": {"max_rows_per_alpha": 40}}
    typed = C.Config()
    assert typed.cr3bp_models.max_rows_per_alpha is None and typed.cr3bp_models.patience == 0
    assert typed.problems.cr3bp.library.max_rows_per_alpha is None
    assert typed.dejong_cvae.patience == 0 and typed.dejong_cvae.max_rows_per_alpha is None
    assert C.Config() == C.from_mapping({})
    assert C.defaults() == C.Config().model_dump(mode="json")
    assert load("default").ablation.samplers == C.Config().ablation.samplers  # every arm of the table


def test_overrides_merge_into_the_defaults_mappings_by_key_lists_replaced():
    base = {"a": {"b": 1, "c": [1, 2], "d": {"e": 1, "f": 2}}, "g": [3], "h": {"i": 1}}
    out = C.deep_merge(base, {"a": {"c": [9], "d": {"f": 5}}, "g": {"x": 1}, "h": None, "new": 1})
    assert out == {"a": {"b": 1, "c": [9], "d": {"e": 1, "f": 5}}, "g": {"x": 1}, "h": None, "new": 1}
    assert base == {"a": {"b": 1, "c": [1, 2], "d": {"e": 1, "f": 2}}, "g": [3], "h": {"i": 1}}  # untouched
    smoke = load("smoke")
    # a nested mapping: one key of the De Jong grid changed, the others kept from the default grid
    assert smoke.problems.dejong.alphas.train.values() == pytest.approx((0.0, math.pi / 4, math.pi / 2), abs=1e-15)
    # a list replaces the default; a key the file leaves out keeps it
    assert smoke.problems.dejong.alphas.test == pytest.approx((math.pi / 9, math.pi / 3), abs=1e-15)
    assert smoke.problems.cr3bp.alphas.train_values() == (0.7, 0.8, 0.9) and smoke.problems.cr3bp.alphas.test == (0.85,)
    assert smoke.problems.cr3bp.solver.tol == C.Config().problems.cr3bp.solver.tol
    assert smoke.resources.merge.threads == C.Config().resources.merge.threads


def _leaves(node: dict, prefix: str = ""):
    for key, value in node.items():
        if isinstance(value, dict) and value:
            yield from _leaves(value, f"{prefix}{key}.")
        else:
            yield f"{prefix}{key}", value


def _used_after(name: str) -> str | None:
    """The shipped file that ``config/<name>.yaml`` is used after, as its own usage line says (``--configfile
    config/<base>.yaml config/<name>.yaml``), or None for a file used alone."""
    import re

    text = (ROOT / "config" / f"{name}.yaml").read_text()
    found = re.search(rf"--configfile config/(\S+)\.yaml config/{re.escape(name)}\.yaml", text)
    return found.group(1) if found else None


@pytest.mark.parametrize("name", CONFIGS)
def test_a_shipped_config_holds_only_what_it_changes(name):
    """Every key a shipped file sets differs from what it overrides — the defaults, or for a file used after
    another (its usage line) the defaults with that file merged (no copies of the defaults to keep in step)."""
    base = _used_after(name)
    under = C.deep_merge(C.defaults(), overrides(base)) if base else C.defaults()
    what = f"config/{base}.yaml's value" if base else "the default"
    for key, value in _leaves(overrides(name)):
        node = under
        for part in key.split("."):
            node = node[part]
        assert value != node, f"config/{name}.yaml: {key}: {value!r} is {what}"


def test_a_file_used_after_another_is_checked_against_that_file():
    """The sparse-3 overlay turns off what config/global-search.yaml turns on (the transfer data): a change there,
    the default everywhere else."""
    assert _used_after("global-search-sparse-3") == "global-search" and _used_after("smoke") is None
    assert overrides("global-search-sparse-3")["transfer"]["enabled"] is False
    assert overrides("global-search")["transfer"]["enabled"] is True


def test_snakemake_merges_files_and_overrides_as_the_loader_does(tmp_path):
    """The workflow validates each --configfile over the defaults (naming the file), then Snakemake's merge of
    them and of --config (update_config: mappings by key, lists replaced) over the defaults."""
    from snakemake.utils import update_config

    extra = write(tmp_path, {"ablation": {"n_starts": 5}, "problems": {"cr3bp": {"alphas": {"test": [0.85]}}}},
                  "extra.yaml")
    merged = overrides("smoke")
    update_config(merged, overrides_of := C.read_yaml(extra))
    update_config(merged, {"seed": 3})
    cfg = C.load_workflow_config(merged, [str(ROOT / "config" / "smoke.yaml"), str(extra)])
    assert cfg == C.from_mapping(C.deep_merge(C.deep_merge(overrides("smoke"), overrides_of), {"seed": 3}))
    assert (cfg.seed, cfg.ablation.n_starts, cfg.problems.cr3bp.alphas.test) == (3, 5, (0.85,))
    assert cfg.ablation.workers == load("smoke").ablation.workers
    bad = write(tmp_path, {"ablation": {"n_startz": 5}}, "bad.yaml")
    with pytest.raises(C.ConfigError, match=r"bad\.yaml: ablation\.n_startz: unknown key"):
        C.load_workflow_config({}, [str(bad)])


def test_command_line_switches_arrive_as_strings_and_are_read_as_booleans(tmp_path):
    """Snakemake parses a nested --config value with YAML's base loader (every leaf a string): 'false' / 'True'
    where a switch stands are booleans; 'yes' stays an error, and so does a quoted switch in a config file."""
    from snakemake.cli import parse_config
    from snakemake.utils import update_config

    for text, expected in (("false", False), ("True", True)):
        merged = overrides("library")
        update_config(merged, parse_config([f"mlflow={{'enabled': {text}}}", f"cr3bp_models={{'enabled': {text}}}"]))
        cfg = C.load_workflow_config(merged, [str(ROOT / "config" / "library.yaml")])
        assert (cfg.mlflow.enabled, cfg.cr3bp_models.enabled) == (expected, expected)
        assert cfg.mlflow.experiment == "amorgs-library"
    merged = overrides("library")
    update_config(merged, parse_config(["mlflow={'enabled': yes}"]))
    with pytest.raises(C.ConfigError, match=r"mlflow\.enabled: Input should be a valid boolean \(got 'yes'\)"):
        C.load_workflow_config(merged, [str(ROOT / "config" / "library.yaml")])
    quoted = write(tmp_path, {"mlflow": {"enabled": "false"}}, "quoted.yaml")
    with pytest.raises(C.ConfigError, match=r"quoted\.yaml: mlflow\.enabled: Input should be a valid boolean"):
        C.load_workflow_config(C.read_yaml(quoted), [str(quoted)])


@pytest.mark.parametrize(
    ("path", "value", "expected"),
    [
        (("problems", "cr3bp", "library", "max_rows_per_alpha"), 0, "problems.cr3bp.library.max_rows_per_alpha: Input should be greater than or equal to 1"),
        (("problems", "cr3bp", "library", "enabled"), "yes", "problems.cr3bp.library.enabled: Input should be a valid boolean"),
        (("problems", "cr3bp", "solver", "max_itr"), 3, "problems.cr3bp.solver.max_itr: unknown key"),
        (("problems", "dejong", "solver", "gtol"), -1.0, "problems.dejong.solver.gtol"),
        (("cr3bp_analysis", "params", "focus_alphz"), 1.0, "cr3bp_analysis.params.focus_alphz: unknown key"),
        (("cr3bp_analysis", "params", "focus_alpha"), -1.0, "cr3bp_analysis.params: StructureParams.focus_alpha must be > 0"),
        (("cr3bp_models", "preset"), "huge", "cr3bp_models.preset: Input should be 'paper' or 'small'"),
        (("cr3bp_models", "epochz"), 1, "cr3bp_models.epochz: unknown key"),
        (("ablation", "perturbation_scale"), -0.1, "ablation.perturbation_scale: Input should be greater than or equal to 0"),
        (("ablation", "iteration_caps"), [25, 25], "ablation.iteration_caps: values must be unique"),
    ],
)
def test_a_bad_value_is_named_before_any_job(tmp_path, path, value, expected):
    """Everything a job would reject — the analysis parameters and solver options included — fails at load."""
    data = mapping()
    node = data
    for key in path[:-1]:
        node = node.setdefault(key, {})
    node[path[-1]] = value
    assert expected in _error(tmp_path, data)


def test_colliding_alpha_labels_are_rejected(tmp_path):
    data = mapping()
    data["problems"]["cr3bp"]["alphas"] = {"train": [0.15], "test": [0.1504]}
    assert "problems.cr3bp.alphas: α values 0.15 and 0.1504 share the label 0.150" in _error(tmp_path, data)


@pytest.mark.parametrize("problem,alpha", [("cr3bp", 0.05), ("cr3bp", 1.2), ("dejong", 2.0)])
def test_alpha_outside_the_problem_range_is_rejected(tmp_path, problem, alpha):
    data = mapping()
    data["problems"][problem]["alphas"]["test"] = [alpha]
    assert f"bad.yaml: problems.{problem}.alphas: α = {alpha} lies outside" in _error(tmp_path, data)


def test_library_slice_may_be_null(tmp_path):
    data = mapping()
    data["problems"]["cr3bp"]["library"]["max_rows_per_alpha"] = None
    assert C.load_config(write(tmp_path, data)).problems.cr3bp.library.max_rows_per_alpha is None


def test_stage_dependencies(tmp_path):
    data = mapping()
    data["problems"]["dejong"]["enabled"] = False
    assert "dejong_cvae.enabled needs problems.dejong.enabled" in _error(tmp_path, data)
    data = mapping()
    data["problems"]["cr3bp"]["alphas"]["test"] = []
    assert "cr3bp_models.enabled needs test α in problems.cr3bp.alphas.test" in _error(tmp_path, data)
    data["problems"]["cr3bp"]["enabled"] = False
    assert "cr3bp_analysis.enabled needs problems.cr3bp.enabled" in _error(tmp_path, data)


def test_bad_yaml_and_missing_file(tmp_path):
    (tmp_path / "x.yaml").write_text("seed: [1,\n")
    with pytest.raises(C.ConfigError, match=r"x\.yaml: not valid YAML at line 2, column 1: ") as err:
        C.load_config(tmp_path / "x.yaml")
    assert "\n" not in str(err.value)
    with pytest.raises(C.ConfigError, match="config file not found"):
        C.load_config(tmp_path / "none.yaml")


def test_hash_is_stable_and_sensitive():
    a, b = C.from_mapping(mapping()), C.from_mapping(mapping())
    assert a.hash == b.hash
    changed = mapping()
    changed["seed"] += 1
    assert C.from_mapping(changed).hash != a.hash
    # the hash is the effective config's: the overrides alone, or every key spelled out, hash alike
    assert C.from_mapping(overrides()).hash == a.hash == load("smoke").hash
    assert C.from_mapping({}).hash == C.from_mapping(C.defaults()).hash
    assert C.from_mapping(overrides("default")).hash == load("default").hash


#: The hashes of the shipped configs, pinned: a change to a default or a shipped file changes them, and must
#: be deliberate.  When the configs became overrides (issue 24) they kept their hashes (54ec484af246,
#: f525fd3bb34c, 2fb02d3f87c6, c1e2323bc951, 0f7cc1375afe); these are after the default solver became the
#: interpolated-coast one (issue 22), which changes every effective config's solver options, and default and
#: smoke run the continuation arm and the reuse-conditioned CVAE (issue 21); smoke was 67749cdeb1c3 until it
#: shrank to fewer jobs (issue 22 §4: one held-out CR3BP α, two De Jong ones, one learning-curve fraction).
#: The transcription's ``controls`` and ``controls_switch_alpha`` (issue 22, Cartesian controls) added two
#: keys to every effective config: before them default 1072eacfb8f2, smoke 70cf5d5cbe35, study 14008f6cb339,
#: study-paper 214116ab497f, paper ee4918b2a606 (their solver-option hashes, and so every stored row's, did not
#: change: the spherical default leaves both keys out of the solver's hash).
#: The section ``transfer`` (issue 38 §1: off by default, on in smoke) added its keys to every effective config:
#: before it default 65b555de46bc, smoke 2fba95aa2504, study 0a00fa3bde06, study-paper 850801f47506, paper
#: 480f9580ea9a (no solver options changed: every row's options hash is the same); smoke runs the selector arm
#: too (issue 38 §2).  ``ablation.selection_oversample`` (issue 38 §3, arm amorgs_selected, which smoke runs too)
#: added a key: before it default 34f56b9bfa3e, smoke cf804002275d, study 686f26e550b3, study-paper d01bdd3a0de9,
#: paper c153d2360a23 (no solver options changed).
#: Bounded training (issue 40 §3) added max_rows_per_alpha, validation_fraction and patience (off by default) to
#: every effective config, and default.yaml turned them on: before, default 2285aed86c5b, smoke 5beeb5860437,
#: study 99f6bcf284ca, study-paper f446678cf96d, paper a7edb7f1dc16.  The section ``global_search`` (issue 41:
#: off by default, on in smoke) added its keys: before it default 2535374921a9, smoke bb702dabd54e, study
#: b393108e152d, study-paper 9b7c46269e8b, paper 760b6dc0b88d (no solver options changed).
#: ``dejong_cvae.max_rows_per_alpha`` (issue 40 §3, off by default) added a key, and default.yaml turned it on and
#: capped its library slice (problems.cr3bp.library.max_rows_per_alpha: 2000): before, default c56031089737, smoke
#: 748a4f977337, study 1afb23932539, study-paper 443d07aa265e, paper 6cde77f2a1dd (no solver options changed).
#: smoke.yaml's ablation runs the arm selector_sampled too (issue 41): before, smoke 90ebe7692314.
#: ``global_search.hop_variables`` (issue 41: hops of the times only; empty, every variable, by default) added a
#: key: before it default 3b04e27f0302, smoke 0d1ac22b75b4, study 05a25f4c231a, study-paper 15c9a161e209, paper
#: d674604d81e4 (no solver options changed).
HASHES = {"default": "a89861e90fbe", "smoke": "5dba321b8291", "study": "baa4b32ea058",
          "study-paper": "6226b276eb16", "paper": "8cf80bb51f3d"}


@pytest.mark.parametrize("name", HASHES)
def test_a_config_rewritten_as_overrides_kept_its_hash(name):
    assert load(name).hash == HASHES[name]


def test_alpha_label_is_fixed_width():
    assert alpha_label(0.15) == "0.150"
    assert alpha_label(math.pi / 9) == "0.349"
    assert alpha_label(0.0) == "0.000"


def test_the_committed_schema_is_the_generated_one():
    """workflow/schemas/config.schema.json is generated from the model (`amorgs config-schema --write`)."""
    assert (ROOT / C.SCHEMA_PATH).read_text() == C.schema_text()


def test_schema_enums_and_ranges_come_from_the_registries():
    from amorgs.ablation.arms import SAMPLER_NAMES
    from amorgs.models.names import CR3BP_PRESETS

    schema = json.loads(C.schema_text())
    defs = schema["$defs"]
    assert tuple(defs["Ablation"]["properties"]["samplers"]["items"]["enum"]) == SAMPLER_NAMES
    assert tuple(defs["Cr3bpModels"]["properties"]["preset"]["enum"]) == CR3BP_PRESETS
    assert schema["additionalProperties"] is False
    assert "required" not in json.dumps(schema)  # a file holds overrides: every key has a default
    assert schema["properties"]["seed"]["default"] == C.Config().seed


def test_every_shipped_config_validates_against_the_generated_schema():
    """The JSON Schema is usable on its own (editors, other tools): every shipped config passes it, as the
    overrides it is and merged over the defaults; an unknown key fails it."""
    import jsonschema

    validator = jsonschema.Draft202012Validator(json.loads(C.schema_text()))
    for name in CONFIGS:
        validator.validate(overrides(name))
        validator.validate(mapping(name))
    assert not validator.is_valid({"ablation": {"n_startz": 3}})


def test_jobs_and_targets_follow_the_enabled_stages(tmp_path):
    cfg = load("smoke")
    targets = steps.targets(cfg)
    assert "results/dejong/high_quality.parquet" in targets
    assert "results/figures/fig16_dejong_predictions.png" in targets
    assert "results/cr3bp/models/fraction=0.1/cvae_gmm.pt" in targets
    assert "results/cr3bp/ablation/alpha=0.850/amorgs.parquet" in targets
    assert {"results/tables/table6.md", "results/cr3bp/analysis/metrics.json"} <= set(targets)
    jobs = steps.expected_jobs(cfg)
    assert ("train_cr3bp_fraction", {"fraction": "0.1", "model": "lstm"}) in jobs  # the real wildcards only
    assert ("ablation_cell_fraction", {"fraction": "0.1", "alpha": "0.850", "sampler": "amorgs"}) in jobs
    assert ("filter", {"problem": "cr3bp"}) in jobs and ("analyze_cr3bp", {}) in jobs
    assert sum(rule == "ablation_cell" for rule, _ in jobs) == len(cfg.problems.cr3bp.alphas.test) * len(cfg.ablation.samplers)
    assert ("global_search_cell", {"alpha": "0.850", "strategy": "mbh", "sampler": "nearest_alpha"}) in jobs
    assert "results/figures/fig_global_search_ecdf.png" in targets
    data = mapping()
    for key in ("cr3bp_analysis", "cr3bp_models", "ablation", "transfer", "global_search"):
        data[key]["enabled"] = False
    data["problems"]["cr3bp"]["enabled"] = False
    off = C.load_config(write(tmp_path, data, "dejong_only.yaml"))
    assert not [t for t in steps.targets(off) if t.startswith("results/cr3bp")]
    assert steps.outputs_of("generate", off, "table", alpha="0.349") == ["results/dejong/solutions/alpha=0.349/shard-0.parquet"]


@pytest.mark.parametrize("beta", [1e6, 452.0, -1.0])
def test_beta_beyond_what_a_transfer_can_keep_is_refused_naming_the_key(tmp_path, beta):
    """Issue 39: `filter.min_final_mass_kg: 1000000` was accepted by the workflow (no solution could count)."""
    data = mapping()
    data["problems"]["cr3bp"]["filter"]["min_final_mass_kg"] = beta
    said = _error(tmp_path, data)
    assert "problems.cr3bp.filter" in said and "lies outside [0, 451.9] kg" in said


@pytest.mark.parametrize("change, says", [
    ({"strategies": ["annealing"]}, "global_search.strategies"),
    ({"hop_distribution": "levy"}, "global_search.hop_distribution"),
    ({"deltas_kg": [0.0]}, "global_search.deltas_kg"),
    ({"samplers": ["uniform", "uniform"]}, "global_search.samplers"),
    ({"hop_variables": ["tau_s", "tau_q"]}, "global_search.hop_variables"),
])
def test_a_bad_global_search_setting_is_refused_naming_the_key(tmp_path, change, says):
    data = mapping()
    data["global_search"] = {"enabled": True, **change}
    assert says in _error(tmp_path, data)


def test_global_search_with_a_learned_sampler_needs_the_models(tmp_path):
    data = mapping()
    data["global_search"] = {"enabled": True, "samplers": ["amorgs"]}
    data["cr3bp_models"]["enabled"] = False
    data["ablation"]["enabled"] = False
    assert "global_search.samplers ['amorgs'] need cr3bp_models.enabled: true" in _error(tmp_path, data)
