"""The committed reference result (reference/study/): every file matches its manifest, and the manifest
describes a complete run of the shipped config/study.yaml."""

from __future__ import annotations

from pathlib import Path

from amorgs.data.library import sha256_file
from amorgs.reference import verify_reference

ROOT = Path(__file__).resolve().parents[2]
STUDY = ROOT / "reference" / "study"


def test_committed_study_reference_matches_its_manifest():
    manifest = verify_reference(STUDY)
    assert manifest["config_file"] == "config/study.yaml"
    assert manifest["config_sha256"] == sha256_file(ROOT / "config" / "study.yaml"), (
        "config/study.yaml changed since reference/study was exported: rerun the study and re-export")
    files = {f["file"] for f in manifest["files"]}
    assert {"tables/ablation_ert.md", "tables/ablation_rates.md", "tables/ablation_seeds.md",
            "cr3bp/ablation/summary.json"} <= files
    cells = [t for t in manifest["solve_tables"] if t["file"].startswith("cr3bp/ablation/")]
    assert sum(t["rows"] for t in cells if "/fraction=" not in t["file"]) >= 8 * 2 * 200
    assert manifest["cpu_hours"]["total"] > 0


def test_committed_readme_names_the_reference_as_the_repository_sees_it():
    readme = (STUDY / "README.md").read_text()
    assert "--dest reference/study --check" in readme and str(ROOT) not in readme


def test_dest_is_shown_relative_to_the_run_when_inside_it(tmp_path):
    from amorgs.reference import _shown

    assert _shown(tmp_path / "reference" / "x", tmp_path) == Path("reference/x")
    assert _shown(tmp_path / "elsewhere", tmp_path / "run") == tmp_path / "elsewhere"
