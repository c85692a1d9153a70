"""Solution-table schema, atomic IO, shard merging, the β-filter and seed derivation."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest

from amorgs.data import filter as F
from amorgs.data import io, seeds, tables
from amorgs.problems.cr3bp import Cr3bpFilter


def solutions(n: int = 4, shard: int = 0, alpha: float = 0.5, seed: int = 11, problem: str = "cr3bp") -> pd.DataFrame:
    """A small solution table with the common columns and one decision variable ``m_f`` (kg)."""
    rng = np.random.default_rng(shard)
    m_f = np.linspace(400.0, 430.0, n)
    return pd.DataFrame(
        {
            "problem": problem,
            "alpha": alpha,
            "seed": seed,
            "shard": shard,
            "start": np.arange(n),
            "guess_m_f": rng.uniform(350, 450, n),
            "m_f": m_f,
            "status": "Solve_Succeeded",
            "converged": np.arange(n) % 2 == 1,
            "solver_success": True,
            "objective": -m_f,
            "iterations": np.full(n, 40),
            "wall_s": rng.uniform(1, 2, n),
            "cpu_s": rng.uniform(1, 2, n),
            "defect": 1e-9,
            "verify_defect": 1e-8,
            "options_hash": "abc",
        }
    )


def test_validate_accepts_a_complete_table():
    tables.validate_solutions(solutions(), ("m_f",), where="t.parquet")


def test_validate_names_missing_columns_and_wrong_kinds():
    with pytest.raises(ValueError, match=r"t.parquet: solution table lacks column\(s\) \['guess_m_f'\]"):
        tables.validate_solutions(solutions().drop(columns="guess_m_f"), ("m_f",), where="t.parquet")
    bad = solutions()
    bad["converged"] = bad["converged"].astype(float)
    with pytest.raises(ValueError, match="column 'converged' should be bool"):
        tables.validate_solutions(bad)


def test_merge_orders_shards_and_rejects_duplicates():
    a, b = solutions(3, shard=1, seed=2), solutions(3, shard=0, seed=1)
    merged = tables.merge_shards([a, b])
    assert merged["shard"].tolist() == [0, 0, 0, 1, 1, 1]
    assert merged["start"].tolist() == [0, 1, 2, 0, 1, 2]
    with pytest.raises(ValueError, match="duplicated solve"):
        tables.merge_shards([a, a])
    with pytest.raises(ValueError, match="different columns"):
        tables.merge_shards([a, b.drop(columns="defect")])
    reordered = tables.merge_shards([a, b[list(b.columns)[::-1]]])  # same columns, another order: a's order
    pd.testing.assert_frame_equal(reordered, merged)


def test_atomic_write_keeps_the_old_file_on_failure(tmp_path):
    path = tmp_path / "sub" / "t.parquet"
    io.write_parquet(solutions(2), path)
    before = path.read_bytes()
    with pytest.raises(RuntimeError):
        with io.atomic_path(path) as tmp:
            tmp.write_bytes(b"half a table")
            raise RuntimeError("killed")
    assert path.read_bytes() == before
    assert sorted(p.name for p in path.parent.iterdir()) == ["t.parquet"]
    pd.testing.assert_frame_equal(pd.read_parquet(path), solutions(2))


def test_json_writes_nan_as_null(tmp_path):
    io.write_json({"a": math.nan, "b": [1.0, math.nan]}, tmp_path / "r.json")
    assert io.read_json(tmp_path / "r.json") == {"a": None, "b": [1.0, None]}


def test_quality_report_per_alpha():
    # α = 0.5: m_f 400…430, converged 410 and 430; α = 0.1: m_f 400 and 430, converged 430
    df = pd.concat([solutions(4, alpha=0.5), solutions(2, alpha=0.1, seed=3)], ignore_index=True)
    hq = Cr3bpFilter(min_final_mass_kg=415.0).select(df)
    report = F.quality_report(df, hq, {"min_final_mass_kg": 415.0})
    assert (report["n"], report["converged"], report["high_quality"]) == (6, 3, 2)
    by_alpha = {e["alpha"]: e for e in report["per_alpha"]}
    assert by_alpha[0.5]["converged_fraction"] == 0.5
    assert by_alpha[0.5]["m_f_max"] == 430.0 and by_alpha[0.5]["high_quality"] == 1
    assert by_alpha[0.1]["high_quality"] == 1 and by_alpha[0.1]["converged"] == 1
    assert by_alpha[0.5]["m_f_min"] == 410.0 and by_alpha[0.5]["objective_min"] == -430.0


def test_shard_seeds_are_stable_and_distinct():
    s = seeds.shard_seed(20240917, "dejong", math.pi / 9, 0)
    assert s == seeds.shard_seed(20240917, "dejong", math.pi / 9, 0)
    assert s == 1105524325  # pinned: a change here changes every generated table
    others = {
        seeds.shard_seed(20240917, "dejong", math.pi / 9, 1),
        seeds.shard_seed(20240917, "cr3bp", math.pi / 9, 0),
        seeds.shard_seed(20240917, "dejong", 2 * math.pi / 9, 0),
        seeds.shard_seed(20240918, "dejong", math.pi / 9, 0),
    }
    assert s not in others and len(others) == 4
    with pytest.raises(ValueError):
        seeds.shard_seed(1, "dejong", 0.1, -1)


def test_cell_seed_is_stable_and_distinct_per_sampler_and_alpha():
    from amorgs.data.seeds import cell_seed

    a = cell_seed(13, "cr3bp", 0.15, "amorgs")
    assert a == cell_seed(13, "cr3bp", 0.15, "amorgs")
    others = {cell_seed(13, "cr3bp", 0.15, "uniform"), cell_seed(13, "cr3bp", 0.85, "amorgs"), cell_seed(14, "cr3bp", 0.15, "amorgs")}
    assert a not in others and len(others) == 3
    with pytest.raises(ValueError):
        cell_seed(-1, "cr3bp", 0.15, "amorgs")
