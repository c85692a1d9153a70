"""The best-known record (amorgs.data.best_known): it rises only to a better solution that passes the independent
check here — a row's own `converged` flag is not trusted — and says where each entry came from."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from amorgs.data import best_known as bk
from amorgs.data.library import read_library
from amorgs.errors import InputError


@pytest.fixture(scope="module")
def library_rows():
    rows = read_library("data/library", "cr3bp", "1.000")
    return rows[rows["converged"]].sort_values("m_f", ascending=False).head(20).reset_index(drop=True)


def test_the_record_rises_only_to_verified_better_solutions(tmp_path, library_rows):
    record = bk.read_record(tmp_path / "none.json")
    assert record["alphas"] == {} and np.isnan(bk.best_m_f(record, 1.0))
    second = library_rows.iloc[[1]]
    assert bk.add_solutions(record, second, {"kind": "library", "where": "test"}) == ["1.000"]
    assert bk.best_m_f(record, 1.0) == pytest.approx(second["m_f"].iloc[0])
    forged = library_rows.iloc[[1]].copy()
    forged["m_f"] += 5.0  # flagged converged, but the mass no longer closes the match point
    assert bk.add_solutions(record, forged, {"kind": "search", "where": "forged"}) == []
    assert bk.add_solutions(record, library_rows.iloc[[5]], {"kind": "search", "where": "worse"}) == []
    assert bk.add_solutions(record, library_rows, {"kind": "search", "where": "all"}) == ["1.000"]
    entry = record["alphas"]["1.000"]
    assert entry["m_f_kg"] == pytest.approx(library_rows["m_f"].max()) and entry["source"]["where"] == "all"
    assert entry["verify_defect"] <= 1e-5 and len(entry["x"]) == 64
    bk.save_record(record, tmp_path / "best.json")
    assert bk.read_record(tmp_path / "best.json")["alphas"]["1.000"]["m_f_kg"] == entry["m_f_kg"]
    with pytest.raises(InputError, match="not a solutions table"):
        bk.add_solutions(record, library_rows[["alpha", "m_f"]], {"where": "bare"})
    (tmp_path / "bad.json").write_text('{"problem": "dejong"}')
    with pytest.raises(InputError, match="not a best-known record"):
        bk.read_record(tmp_path / "bad.json")


def test_the_command_names_a_missing_table_in_one_line(tmp_path):
    out = subprocess.run([sys.executable, "-m", "amorgs", "best-known", "--record", str(tmp_path / "r.json"), "--add",
                          str(tmp_path / "nope.parquet")], capture_output=True, text=True)
    assert out.returncode != 0 and "--add" in out.stderr and "no such file" in out.stderr
    assert len(out.stderr.strip().splitlines()) == 1


def test_an_entry_names_its_table_relative_to_the_checkout(tmp_path, library_rows):
    checkout, outside = tmp_path / "checkout", tmp_path / "elsewhere"
    (checkout / "runs").mkdir(parents=True)
    outside.mkdir()
    library_rows.iloc[[3]].to_parquet(checkout / "runs" / "solutions.parquet")
    library_rows.iloc[[0]].to_parquet(outside / "solutions.parquet")
    assert bk.source_where(checkout / "runs" / "solutions.parquet", checkout) == "runs/solutions.parquet"
    assert bk.source_where(outside / "solutions.parquet", checkout) == str((outside / "solutions.parquet").resolve())

    def add(table):
        return subprocess.run([sys.executable, "-m", "amorgs", "best-known", "--record", "best.json", "--add", table],
                              capture_output=True, text=True, cwd=checkout)

    inside = add(str(checkout / "runs" / "solutions.parquet"))  # absolute, but inside the checkout
    assert inside.returncode == 0 and "outside this checkout" not in inside.stderr
    assert bk.read_record(checkout / "best.json")["alphas"]["1.000"]["source"]["where"] == "runs/solutions.parquet"
    far = add(str(outside / "solutions.parquet"))
    assert far.returncode == 0 and "outside this checkout" in far.stderr
    assert Path(bk.read_record(checkout / "best.json")["alphas"]["1.000"]["source"]["where"]).is_absolute()
