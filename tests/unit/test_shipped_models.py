"""Shipped model checkpoints: export with a manifest, verification by SHA-256 before use."""

from __future__ import annotations

from pathlib import Path

import pytest

from amorgs.config import load_config
from amorgs.errors import InputError
from amorgs.models.shipped import CHECKPOINT_FILES, export_models, verify_models

ROOT = Path(__file__).resolve().parents[2]


def trained(tmp_path: Path) -> Path:
    src = tmp_path / "run" / "models"
    src.mkdir(parents=True)
    for i, name in enumerate(CHECKPOINT_FILES):
        (src / name).write_bytes(bytes([i]) * (100 + i))
    return src


def test_export_then_verify_and_detect_tampering(tmp_path):
    dest = tmp_path / "shipped"
    config = ROOT / "config" / "default.yaml"
    manifest = export_models(trained(tmp_path), dest, load_config(config), config, ROOT / "data" / "library")
    assert [f["file"] for f in manifest["files"]] == list(CHECKPOINT_FILES)
    assert manifest["library_rows"] > 0 and len(manifest["library_manifest_sha256"]) == 64
    assert {g["generation"] for g in manifest["library_identity"]} >= {1, 2, 3}  # the code of the training rows
    assert all(g["options_hashes"] and "nlp_fingerprints" in g for g in manifest["library_identity"])
    assert verify_models(dest)["config_hash"] == manifest["config_hash"]
    (dest / "lstm.pt").write_bytes(b"edited")
    assert verify_models(dest, ("cvae_gmm.pt",)) is not None  # only what a sampler needs is checked
    with pytest.raises(InputError, match=r"lstm\.pt: SHA-256 .* differs"):
        verify_models(dest)
    (dest / "lstm.pt").unlink()
    with pytest.raises(InputError, match=r"lstm\.pt: listed in .* but missing"):
        verify_models(dest)


def test_export_needs_every_checkpoint_and_unshipped_folders_are_trusted(tmp_path):
    src = trained(tmp_path)
    (src / "vanilla_cvae.pt").unlink()
    config = ROOT / "config" / "default.yaml"
    with pytest.raises(InputError, match=r"vanilla_cvae\.pt: checkpoint not found"):
        export_models(src, tmp_path / "shipped", load_config(config), config)
    assert verify_models(src) is None
