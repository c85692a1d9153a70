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


@pytest.fixture(scope="module")
def low_thrust_best():
    """The library's best verified row at α = 0.16 and its stored vector (max throttle ≈ 0.6: it flies at any α
    above ≈ 0.096 N)."""
    rows = read_library("data/library", "cr3bp", "0.160")
    best = rows[rows["converged"]].sort_values("m_f", ascending=False).head(1)
    from amorgs.problems import get_problem

    return best, best[list(get_problem("cr3bp").variable_names)].to_numpy(float)[0]


def test_a_trajectory_flies_unchanged_at_another_thrust_with_its_throttles_rescaled(low_thrust_best):
    from amorgs.problems import get_problem
    from amorgs.problems.cr3bp.controls import rescale_throttle
    from amorgs.problems.cr3bp.propagation import independent_defect, propagate

    problem = get_problem("cr3bp")
    _, x = low_thrust_best
    rho = x[6::3]
    assert 0.3 < rho.max() < 1.0
    here = propagate(x, 0.16, problem.initial_state, problem.terminal_state)
    for alpha in (0.5, 1.0, 0.16 * rho.max() / 0.999):  # higher, and lower down to (almost) full throttle
        y = rescale_throttle(x, 0.16, alpha)
        assert y is not None and y.max() <= problem.upper.max() and y[6::3].max() <= 1.0
        np.testing.assert_array_equal(np.delete(y, np.s_[6::3]), np.delete(x, np.s_[6::3]))  # times, m_f, angles
        np.testing.assert_allclose(y[6::3] * alpha, rho * 0.16, rtol=1e-14)  # the same thrust α ρ
        there = propagate(y, alpha, problem.initial_state, problem.terminal_state)
        np.testing.assert_allclose(there.t, here.t, atol=1e-12)
        np.testing.assert_allclose(there.states[:6], here.states[:6], atol=1e-7)  # DU, VU
        np.testing.assert_allclose(there.states[6], here.states[6], atol=1e-6)  # fuel, kg
        assert independent_defect(y, alpha, problem.initial_state, problem.terminal_state) < 1e-5
    assert rescale_throttle(x, 0.16, 0.16 * rho.max() / 1.01) is None  # would need ρ > 1


def test_lifting_carries_an_entry_to_every_alpha_it_flies_at_and_beats(tmp_path, low_thrust_best, library_rows):
    best, x = low_thrust_best
    record = bk.read_record(tmp_path / "none.json")
    bk.add_solutions(record, best, {"kind": "library", "where": "lib-0.16", "commit": "abc"})
    worse = library_rows[library_rows["m_f"] < best["m_f"].iloc[0] - 0.1].head(1)  # α = 1.0, below it
    bk.add_solutions(record, worse, {"kind": "library", "where": "lib-1.0"})
    assert bk.best_m_f(record, 1.0) < bk.best_m_f(record, 0.16)
    improved = bk.lift(record, alphas=[0.05, 0.16, 0.6, 1.0])
    assert improved == ["0.600", "1.000"]  # not 0.05: the trajectory needs more than 0.05 N
    for label in improved:
        entry = record["alphas"][label]
        assert entry["m_f_kg"] == pytest.approx(best["m_f"].iloc[0], abs=1e-12)
        assert entry["source"] == {"kind": "lift", "from_alpha": 0.16, "where": "lib-0.16", "commit": "abc"}
        assert entry["verify_defect"] < 1e-5
    assert bk.lift(record) == []  # already lifted
    # at an α the record has no entry for, the best known is the best trajectory that flies there
    assert bk.best_m_f_lifted(record, 0.45) == pytest.approx(best["m_f"].iloc[0], abs=1e-12)
    assert np.isnan(bk.best_m_f_lifted(record, 0.05)) and "0.450" not in record["alphas"]
    there = bk.best_entry_lifted(record, 0.45)  # and its trajectory, flown at 0.45, with its provenance
    y = np.asarray(there["x"])
    assert there["source"]["from_alpha"] == 0.16 and there["m_f_kg"] == y[3] == x[3]
    np.testing.assert_allclose(y[6::3] * 0.45, x[6::3] * 0.16, rtol=1e-14)  # the same thrust α ρ
    assert bk.verify(y, 0.45) == there["verify_defect"] and bk.best_entry_lifted(record, 0.05) is None
    m_f = [e["m_f_kg"] for _, e in sorted(record["alphas"].items())]
    assert m_f == sorted(m_f)  # the best known no longer falls as α grows
    bk.save_record(record, tmp_path / "best.json")
    out = subprocess.run([sys.executable, "-m", "amorgs", "best-known", "--record", str(tmp_path / "best.json"),
                          "--lift"], capture_output=True, text=True)
    assert out.returncode == 0 and "unchanged" in out.stdout and "lift (α = 0.16's trajectory) lib-0.16" in out.stdout
