"""Shipped model checkpoints: export with a manifest, verification by SHA-256 before use."""

from __future__ import annotations

from pathlib import Path

import pandas as pd
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


def test_a_selector_ships_beside_the_checkpoints_with_its_own_record_and_survives_a_reexport(tmp_path):
    from amorgs.models.selector import SELECTOR_FILE
    from amorgs.models.shipped import SELECTOR_DATA, export_selector

    dest = tmp_path / "shipped"
    default, selector_config = ROOT / "config" / "default.yaml", ROOT / "config" / "selector-model.yaml"
    src = trained(tmp_path)
    with pytest.raises(InputError, match="no shipped models manifest"):  # the checkpoints come first
        export_selector(src, dest, load_config(selector_config), selector_config)
    export_models(src, dest, load_config(default), default, ROOT / "data" / "library")
    with pytest.raises(InputError, match=r"selector\.joblib: selector not found"):
        export_selector(src, dest, load_config(selector_config), selector_config)
    (src / SELECTOR_FILE).write_bytes(b"selector" * 50)
    with pytest.raises(InputError, match="no transfer shards beside the selector"):  # its training data ship too
        export_selector(src, dest, load_config(selector_config), selector_config)
    for k, (a, b) in enumerate(((0.3, 0.2), (0.2, 0.3))):
        shard = src.parent / "transfer" / f"alpha={a:.3f}" / f"from={b:.3f}" / "shard-0.parquet"
        shard.parent.mkdir(parents=True)
        pd.DataFrame({"alpha": [a] * 3, "source_alpha": [b] * 3, "iterations": [10 + k, 20, 30]}).to_parquet(shard)
    with pytest.raises(InputError, match="transfer.enabled is false"):  # not the config that trained it
        export_selector(src, dest, load_config(default), default)
    manifest = export_selector(src, dest, load_config(selector_config), selector_config, ROOT / "data" / "library")
    record = manifest["selector"]
    assert record["config_hash"] == load_config(selector_config).hash and record["transfer"]["enabled"]
    assert len(record["train_alphas"]) == 14 and record["library_rows"] > 0
    assert manifest["config_hash"] == load_config(default).hash  # the checkpoints' record is untouched
    assert verify_models(dest, (SELECTOR_FILE, SELECTOR_DATA))["selector"] == record
    assert len(pd.read_parquet(dest / SELECTOR_DATA)) == 6 and manifest["files"][-1]["rows"] == 6
    export_models(src, dest, load_config(default), default, ROOT / "data" / "library")  # re-export: the selector stays
    assert verify_models(dest, (*CHECKPOINT_FILES, SELECTOR_FILE))["selector"] == record
    (dest / SELECTOR_FILE).write_bytes(b"edited")
    with pytest.raises(InputError, match=r"selector\.joblib: SHA-256 .* differs"):
        verify_models(dest, (SELECTOR_FILE,))
    export_models(src, dest, load_config(default), default, ROOT / "data" / "library")  # an edited one is dropped
    assert "selector" not in verify_models(dest)
