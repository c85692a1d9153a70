"""Test helpers for config files: the shipped configs, and mappings written to a temporary file."""

from __future__ import annotations

from pathlib import Path

import yaml

from amorgs import config as C

ROOT = Path(__file__).resolve().parents[1]
CONFIGS = sorted(p.stem for p in (ROOT / "config").glob("*.yaml"))


def load(name: str) -> C.Config:
    """The shipped config ``config/<name>.yaml``, validated."""
    return C.load_config(ROOT / "config" / f"{name}.yaml")


def overrides(name: str = "smoke") -> dict:
    """The raw mapping of ``config/<name>.yaml``: only what it changes from the typed defaults."""
    return yaml.safe_load((ROOT / "config" / f"{name}.yaml").read_text())


def mapping(name: str = "smoke") -> dict:
    """The effective mapping of ``config/<name>.yaml`` (its overrides merged over the defaults: every key), to
    edit in a test and write back as a complete config file."""
    return C.effective_mapping(overrides(name))


def write(tmp_path: Path, data: dict, name: str = "bad.yaml") -> Path:
    """``data`` written as YAML to ``tmp_path/name``."""
    path = tmp_path / name
    path.write_text(yaml.safe_dump(data))
    return path
