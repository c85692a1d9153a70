"""The multistart pool: determinism across worker counts, and crashes/hangs cost one row each."""

import numpy as np
import pytest

from amorgs.solvers.multistart import run_multistart, solve_guesses

CRASHY = "crashy_problem:CrashyProblem"


def test_crash_hang_and_exception_cost_one_row_each():
    guesses = np.array([[1.2], [3.5], [2.7], [4.5], [5.5], [8.1], [9.9]])
    records, info = solve_guesses(CRASHY, 0.5, guesses, workers=2, hard_timeout_s=3.0, progress=False)
    statuses = [r.status for r in records]
    assert statuses == ["ok", "crashed", "ok", "timeout", "exception", "ok", "ok"]
    assert [r.x[0] for r, s in zip(records, statuses) if s == "ok"] == [1, 3, 8, 10]
    assert "ZeroDivisionError" in records[4].message
    assert info["replaced_workers"] == 2


def test_bad_guess_is_rejected_before_any_work():
    with pytest.raises(ValueError, match=r"guess #1: .*'x'"):
        solve_guesses(CRASHY, 0.5, np.array([[1.0], [np.nan]]), progress=False)


@pytest.mark.slow
def test_dejong_table_is_identical_for_one_and_two_workers():
    one = run_multistart("dejong", 0.3, seed=11, n_starts=12, workers=1, progress=False)
    two = run_multistart("dejong", 0.3, seed=11, n_starts=12, workers=2, progress=False)
    cols = [c for c in one.columns if c not in ("wall_s", "cpu_s")]
    assert len(one) == 12 and one["start"].tolist() == list(range(12))
    assert one[cols].equals(two[cols])
    assert one["converged"].sum() >= 6
