"""Atomic writes leave files with the permissions a plain ``open()`` would: readable by the group."""

from __future__ import annotations

import os
import stat

import pandas as pd
import pytest

from amorgs.data.io import atomic_path, write_json, write_parquet


@pytest.fixture
def umask():
    """Set the process umask for one test, restoring it afterwards."""
    old = os.umask(0o022)
    os.umask(old)
    yield lambda mask: os.umask(mask)
    os.umask(old)


def mode(path) -> int:
    return stat.S_IMODE(os.stat(path).st_mode)


@pytest.mark.parametrize("mask", [0o022, 0o002, 0o077])
def test_new_files_get_0666_less_the_umask(tmp_path, umask, mask):
    umask(mask)
    write_parquet(pd.DataFrame({"a": [1, 2]}), tmp_path / "t.parquet")
    write_json({"a": 1}, tmp_path / "sub" / "m.json")
    with atomic_path(tmp_path / "x.bin") as tmp:
        tmp.write_bytes(b"x")
    # what open() would give, measured rather than assumed
    with open(tmp_path / "reference", "w"):
        pass
    want = mode(tmp_path / "reference")
    assert want == 0o666 & ~mask
    for name in ("t.parquet", "sub/m.json", "x.bin"):
        assert mode(tmp_path / name) == want, name


def test_group_can_read_outputs_under_the_usual_umask(tmp_path, umask):
    umask(0o022)
    write_json([1], tmp_path / "m.json")
    assert mode(tmp_path / "m.json") & stat.S_IRGRP and mode(tmp_path / "m.json") & stat.S_IROTH


def test_replacing_a_file_keeps_its_permissions(tmp_path, umask):
    umask(0o022)
    path = tmp_path / "m.json"
    write_json({"v": 1}, path)
    os.chmod(path, 0o640)
    write_json({"v": 2}, path)
    assert mode(path) == 0o640
    assert path.read_text().count("2") == 1
    assert not list(tmp_path.glob(".*.tmp"))
