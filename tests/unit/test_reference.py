"""The committed reference results (reference/study/, reference/study-paper/): every file matches its
manifest, and the manifest describes a complete run of the shipped config it names."""

from __future__ import annotations

from pathlib import Path

import pytest

from amorgs.config import load_config
from amorgs.data.library import sha256_file
from amorgs.reference import verify_reference

ROOT = Path(__file__).resolve().parents[2]
#: Each committed reference result and the config that made it.
REFERENCES = {"study": "config/study.yaml", "study-paper": "config/study-paper.yaml"}


@pytest.mark.parametrize("name", REFERENCES)
def test_committed_reference_matches_its_manifest_and_config(name):
    config_file = REFERENCES[name]
    manifest = verify_reference(ROOT / "reference" / name)
    assert manifest["config_file"] == config_file
    assert manifest["config_sha256"] == sha256_file(ROOT / config_file), (
        f"{config_file} changed since reference/{name} was exported: rerun it and re-export")
    files = {f["file"] for f in manifest["files"]}
    assert {"tables/ablation_ert.md", "tables/ablation_rates.md", "tables/ablation_seeds.md",
            "cr3bp/ablation/summary.json"} <= files
    cfg = load_config(ROOT / config_file)
    cells = [t for t in manifest["solve_tables"] if t["file"].startswith("cr3bp/ablation/")]
    n_arms, n_alphas = len(cfg.ablation.samplers), len(cfg.problems.cr3bp.alphas.test)
    assert sum(t["rows"] for t in cells if "/fraction=" not in t["file"]) >= n_arms * n_alphas * 200
    assert manifest["cpu_hours"]["total"] > 0


@pytest.mark.parametrize("name", REFERENCES)
def test_committed_readme_names_the_reference_as_the_repository_sees_it(name):
    readme = (ROOT / "reference" / name / "README.md").read_text()
    assert f"--dest reference/{name} --check" in readme and str(ROOT) not in readme


def test_dest_is_shown_relative_to_the_run_when_inside_it(tmp_path):
    from amorgs.reference import _shown

    assert _shown(tmp_path / "reference" / "x", tmp_path) == Path("reference/x")
    assert _shown(tmp_path / "elsewhere", tmp_path / "run") == tmp_path / "elsewhere"
