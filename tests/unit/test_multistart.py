"""The multistart pool: determinism across worker counts, and crashes/hangs cost one row each."""

import numpy as np
import pydantic
import pytest

from amorgs.solvers.multistart import options_digest, run_multistart, solve_guesses, worker_timeout_s
from amorgs.solvers.options import BfgsOptions, IpoptOptions

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
    one = run_multistart("dejong", 0.3, seed=11, starts=12, workers=1, progress=False)
    two = run_multistart("dejong", 0.3, seed=11, starts=12, workers=2, progress=False)
    cols = [c for c in one.columns if c not in ("wall_s", "cpu_s")]
    assert len(one) == 12 and one["start"].tolist() == list(range(12))
    assert one[cols].equals(two[cols])
    assert one["converged"].sum() >= 6


def test_bad_options_are_rejected_in_the_parent_naming_the_field():
    with pytest.raises(pydantic.ValidationError, match="gtol"):
        run_multistart("dejong", 0.3, seed=1, starts=2, workers=1, options={"gtol": -1.0}, progress=False)
    with pytest.raises(pydantic.ValidationError, match="max_iters"):
        solve_guesses("cr3bp", 0.5, np.zeros((0, 64)), options={"max_iters": 5}, progress=False)
    with pytest.raises(TypeError, match="BfgsOptions"):
        run_multistart("dejong", 0.3, seed=1, starts=2, workers=1, options=IpoptOptions(), progress=False)


def test_typed_options_travel_to_the_worker_and_equal_the_mapping_path():
    typed = run_multistart("dejong", 0.3, 11, 4, 1, BfgsOptions(maxiter=1), progress=False)
    mapping = run_multistart("dejong", 0.3, 11, 4, 1, {"maxiter": 1}, progress=False)
    cols = [c for c in typed.columns if c not in ("wall_s", "cpu_s")]
    assert typed[cols].equals(mapping[cols])
    assert (typed["status"] == "max_iterations").all() and (typed["iterations"] == 1).all()
    assert set(typed["options_hash"]) == {BfgsOptions(maxiter=1).digest()}


def test_worker_timeout_follows_the_wall_cap_and_untyped_options_hash():
    assert worker_timeout_s(IpoptOptions(max_wall_s=10.0)) == 50.0
    assert worker_timeout_s({"max_wall_s": 10}) == 50.0  # an untyped user-defined problem's mapping
    assert options_digest("crashy", {"a": 1}) == options_digest("crashy", {"a": 1}) != options_digest("crashy", None)
    assert options_digest("dejong", BfgsOptions()) == BfgsOptions().digest()
