"""Config files, the JSON Schema and the typed dataclasses that mirror it."""

from __future__ import annotations

import dataclasses
import math
import typing
from pathlib import Path

import pytest
import yaml

from amorgs import config as C
from amorgs import layout

ROOT = Path(__file__).resolve().parents[2]
SCHEMA = ROOT / "workflow" / "schemas" / "config.schema.yaml"
CONFIGS = sorted(p.stem for p in (ROOT / "config").glob("*.yaml"))


def load(name: str) -> C.Config:
    return C.load_config(ROOT / "config" / f"{name}.yaml", SCHEMA)


def write(tmp_path: Path, mapping: dict) -> Path:
    path = tmp_path / "bad.yaml"
    path.write_text(yaml.safe_dump(mapping))
    return path


def test_the_three_main_configs_ship():
    assert {"smoke", "default", "paper"} <= set(CONFIGS)


@pytest.mark.parametrize("name", CONFIGS)
def test_shipped_configs_validate(name):
    cfg = load(name)
    assert cfg.problems.enabled(), "every config runs at least one problem"
    assert len(cfg.hash) == 12


def test_dejong_alphas_follow_the_paper():
    cfg = load("default")
    dj = cfg.problems.dejong
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


def test_unknown_key_is_named_with_file_and_path(tmp_path):
    mapping = yaml.safe_load((ROOT / "config" / "smoke.yaml").read_text())
    mapping["problems"]["dejong"]["generate"]["startz_per_shard"] = 3
    path = write(tmp_path, mapping)
    with pytest.raises(C.ConfigError) as err:
        C.load_config(path, SCHEMA)
    msg = str(err.value)
    assert str(path) in msg
    assert "problems.dejong.generate" in msg and "'startz_per_shard' was unexpected" in msg


def test_wrong_type_and_missing_key_are_named(tmp_path):
    mapping = yaml.safe_load((ROOT / "config" / "smoke.yaml").read_text())
    mapping["dejong_cvae"]["epochs"] = "many"
    del mapping["mlflow"]["experiment"]
    with pytest.raises(C.ConfigError) as err:
        C.load_config(write(tmp_path, mapping), SCHEMA)
    msg = str(err.value)
    assert "dejong_cvae.epochs: 'many' is not of type 'integer'" in msg
    assert "mlflow: 'experiment' is a required property" in msg


def test_top_level_typo_is_named(tmp_path):
    mapping = yaml.safe_load((ROOT / "config" / "smoke.yaml").read_text())
    mapping["sed"] = mapping.pop("seed")
    with pytest.raises(C.ConfigError, match=r"\(top level\): Additional properties are not allowed \('sed'"):
        C.load_config(write(tmp_path, mapping), SCHEMA)


def test_colliding_alpha_labels_are_rejected(tmp_path):
    mapping = yaml.safe_load((ROOT / "config" / "smoke.yaml").read_text())
    mapping["problems"]["cr3bp"]["alphas"] = {"train": [0.15], "test": [0.1504]}
    with pytest.raises(C.ConfigError, match=r"problems\.cr3bp\.alphas: .* share the label 0\.150"):
        C.load_config(write(tmp_path, mapping), SCHEMA)


@pytest.mark.parametrize("problem,alpha", [("cr3bp", 0.05), ("cr3bp", 1.2), ("dejong", 2.0)])
def test_alpha_outside_the_problem_range_is_rejected_before_any_job(tmp_path, problem, alpha):
    mapping = yaml.safe_load((ROOT / "config" / "smoke.yaml").read_text())
    mapping["problems"][problem]["alphas"]["test"] = [alpha]
    with pytest.raises(C.ConfigError, match=rf"bad\.yaml: problems\.{problem}\.alphas: α = {alpha} lies outside"):
        C.load_config(write(tmp_path, mapping), SCHEMA)


def test_library_slice_must_be_positive_or_null(tmp_path):
    mapping = yaml.safe_load((ROOT / "config" / "smoke.yaml").read_text())
    mapping["problems"]["cr3bp"]["library"]["max_rows_per_alpha"] = 0
    with pytest.raises(C.ConfigError, match=r"problems\.cr3bp\.library\.max_rows_per_alpha: 0 is less than the minimum of 1"):
        C.load_config(write(tmp_path, mapping), SCHEMA)
    mapping["problems"]["cr3bp"]["library"]["max_rows_per_alpha"] = None
    assert C.load_config(write(tmp_path, mapping), SCHEMA).problems.cr3bp.library.max_rows_per_alpha is None


def test_cvae_needs_dejong(tmp_path):
    mapping = yaml.safe_load((ROOT / "config" / "smoke.yaml").read_text())
    mapping["problems"]["dejong"]["enabled"] = False
    with pytest.raises(C.ConfigError, match="dejong_cvae.enabled needs problems.dejong.enabled"):
        C.load_config(write(tmp_path, mapping), SCHEMA)


def test_bad_yaml_and_missing_file(tmp_path):
    (tmp_path / "x.yaml").write_text("seed: [1,\n")
    with pytest.raises(C.ConfigError, match="not valid YAML"):
        C.load_config(tmp_path / "x.yaml", SCHEMA)
    with pytest.raises(C.ConfigError, match="config file not found"):
        C.load_config(tmp_path / "none.yaml", SCHEMA)


def test_hash_is_stable_and_sensitive():
    mapping = yaml.safe_load((ROOT / "config" / "smoke.yaml").read_text())
    a, b = C.from_mapping(mapping), C.from_mapping(yaml.safe_load((ROOT / "config" / "smoke.yaml").read_text()))
    assert a.hash == b.hash
    mapping["seed"] += 1
    assert C.from_mapping(mapping).hash != a.hash


def test_alpha_label_is_fixed_width():
    assert C.alpha_label(0.15) == "0.150"
    assert C.alpha_label(math.pi / 9) == "0.349"
    assert C.alpha_label(0.0) == "0.000"


def test_targets_follow_the_enabled_stages():
    cfg = load("smoke")
    targets = layout.targets(cfg)
    assert "results/dejong/high_quality.parquet" in targets
    assert "results/figures/fig16_dejong_predictions.png" in targets
    assert all(not t.startswith("results/cr3bp") for t in targets) or cfg.problems.cr3bp.enabled
    assert layout.shard_paths(cfg, "dejong", "0.314") == ["results/dejong/solutions/alpha=0.314/shard-0.parquet"]


def _resolve(node: dict, schema: dict) -> dict:
    while "$ref" in node:
        ref = node["$ref"].removeprefix("#/").split("/")
        target = schema
        for part in ref:
            target = target[part]
        node = {**target, **{k: v for k, v in node.items() if k != "$ref"}}
    return node


def _mirror(cls: type, node: dict, schema: dict, path: str) -> None:
    node = _resolve(node, schema)
    fields = {f.name for f in dataclasses.fields(cls)}
    assert node.get("additionalProperties") is False, f"{path}: additionalProperties must be false"
    assert set(node["properties"]) == fields, f"{path}: schema {sorted(node['properties'])} vs {sorted(fields)}"
    assert set(node["required"]) == fields, f"{path}: every key is required"
    hints = typing.get_type_hints(cls)
    for name in fields:
        for tp in typing.get_args(hints[name]) or (hints[name],):
            if dataclasses.is_dataclass(tp):
                sub = _resolve(node["properties"][name], schema)
                options = [_resolve(o, schema) for o in sub.get("oneOf", [sub])]
                _mirror(tp, next(o for o in options if o.get("type") == "object"), schema, f"{path}.{name}")


def test_dataclasses_mirror_the_schema():
    schema = yaml.safe_load(SCHEMA.read_text())
    _mirror(C.Config, schema, schema, "config")


@pytest.mark.parametrize(
    ("section", "key"),
    [("cr3bp_models", "epochz"), ("ablation", "n_startz"), ("cr3bp_analysis", "paramz")],
)
def test_unknown_key_in_cr3bp_stage_sections_is_named(tmp_path, section, key):
    mapping = yaml.safe_load((ROOT / "config" / "smoke.yaml").read_text())
    mapping[section][key] = 1
    with pytest.raises(C.ConfigError) as err:
        C.load_config(write(tmp_path, mapping), SCHEMA)
    assert f"{section}: Additional properties are not allowed ('{key}' was unexpected)" in str(err.value)


def test_library_section_is_checked(tmp_path):
    mapping = yaml.safe_load((ROOT / "config" / "smoke.yaml").read_text())
    mapping["problems"]["cr3bp"]["library"]["enabled"] = "yes"
    del mapping["problems"]["dejong"]["library"]
    with pytest.raises(C.ConfigError) as err:
        C.load_config(write(tmp_path, mapping), SCHEMA)
    msg = str(err.value)
    assert "problems.cr3bp.library.enabled: 'yes' is not of type 'boolean'" in msg
    assert "problems.dejong: 'library' is a required property" in msg


def test_ablation_sampler_names_and_model_dependency(tmp_path):
    mapping = yaml.safe_load((ROOT / "config" / "smoke.yaml").read_text())
    mapping["ablation"]["samplers"] = ["uniform", "amorgz"]
    with pytest.raises(C.ConfigError, match=r"ablation\.samplers\.1: 'amorgz' is not one of"):
        C.load_config(write(tmp_path, mapping), SCHEMA)
    mapping["ablation"]["samplers"] = ["uniform", "amorgs"]
    mapping["cr3bp_models"]["enabled"] = False
    with pytest.raises(C.ConfigError, match=r"ablation\.samplers \['amorgs'\] need cr3bp_models\.enabled"):
        C.load_config(write(tmp_path, mapping), SCHEMA)
    mapping["ablation"]["samplers"] = ["uniform"]
    assert C.load_config(write(tmp_path, mapping), SCHEMA).ablation.samplers == ("uniform",)


def test_cr3bp_stages_need_cr3bp_and_test_alphas(tmp_path):
    mapping = yaml.safe_load((ROOT / "config" / "smoke.yaml").read_text())
    mapping["problems"]["cr3bp"]["alphas"]["test"] = []
    with pytest.raises(C.ConfigError, match=r"cr3bp_models\.enabled needs test α in problems\.cr3bp\.alphas\.test"):
        C.load_config(write(tmp_path, mapping), SCHEMA)
    mapping["problems"]["cr3bp"]["enabled"] = False
    with pytest.raises(C.ConfigError, match=r"cr3bp_analysis\.enabled needs problems\.cr3bp\.enabled"):
        C.load_config(write(tmp_path, mapping), SCHEMA)


def test_cr3bp_targets_and_jobs():
    from amorgs.checks import expected_jobs

    cfg = load("smoke")
    targets = layout.targets(cfg)
    assert "results/cr3bp/models/fraction=0.1/cvae_gmm.pt" in targets
    assert "results/cr3bp/ablation/alpha=0.850/amorgs.parquet" in targets
    assert {"results/tables/table6.md", "results/cr3bp/analysis/metrics.json", "results/figures/fig23_amorgs_diversity.png"} <= set(targets)
    jobs = expected_jobs(cfg)
    assert ("train_cr3bp_fraction", {"problem": "cr3bp", "model": "cvae_gmm", "fraction": "0.5"}) in jobs
    assert sum(rule == "ablation_cell" for rule, _ in jobs) == len(cfg.problems.cr3bp.alphas.test) * len(cfg.ablation.samplers)
    assert not any(rule.startswith("fig03") for rule, _ in jobs)  # drawn by analyze_cr3bp, not a rule of its own
