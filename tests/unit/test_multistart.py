"""The multistart pool: determinism across worker counts, and crashes/hangs cost one row each."""

import contextlib
import multiprocessing as mp
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pydantic
import pytest

from amorgs.problems import get_problem
from amorgs.solvers.multistart import (
    WorkerPool, detach_worker, kill_worker, options_digest, run_multistart, solve_guesses, worker_timeout_s,
)
from amorgs.solvers.options import BfgsOptions, IpoptOptions

CRASHY = "crashy_problem:CrashyProblem"


def test_crash_hang_and_exception_cost_one_row_each():
    guesses = np.array([[1.2], [3.5], [2.7], [4.5], [5.5], [8.1], [9.9]])
    records, info = solve_guesses(get_problem(CRASHY), 0.5, guesses, workers=2, hard_timeout_s=3.0, progress=False)
    statuses = [r.status for r in records]
    assert statuses == ["ok", "crashed", "ok", "timeout", "exception", "ok", "ok"]
    assert [r.x[0] for r, s in zip(records, statuses) if s == "ok"] == [1, 3, 8, 10]
    assert "ZeroDivisionError" in records[4].message
    assert info["replaced_workers"] == 2


def test_a_pool_keeps_its_workers_across_calls_and_replaces_the_dead_ones():
    """`amorgs design` solves in rounds with one pool: the same processes serve every call, each call's records
    equal a one-off solve_guesses of the same guesses, a worker lost to a crash is back at the next call."""
    problem = get_problem(CRASHY)
    first, second = np.array([[1.2], [2.7], [8.1]]), np.array([[3.5], [6.4], [9.9]])
    with WorkerPool(problem, 2, hard_timeout_s=3.0) as pool:
        pids = {slot.proc.pid for slot in pool._slots}
        records, info = pool.solve(0.5, first, progress=False)
        assert [r.x[0] for r in records] == [1, 3, 8] and 1 <= len(info["build_s"]) <= 2  # a ready worker starts at once
        assert {slot.proc.pid for slot in pool._slots} == pids and pool.cpu_seconds() > 0
        records, info = pool.solve(0.5, second, progress=False)
        assert [r.status for r in records] == ["crashed", "ok", "ok"] and info["replaced_workers"] == 1
        assert [r.status for r in records] == [r.status for r in solve_guesses(problem, 0.5, second, 2, progress=False,
                                                                               hard_timeout_s=3.0)[0]]
        records, _ = pool.solve(0.5, first, progress=False)
        assert [r.x[0] for r in records] == [1, 3, 8] and len(pool._slots) == 2
        live = [slot.proc for slot in pool._slots]
    assert not any(proc.is_alive() for proc in live)  # the end of the block kills them


def test_bad_guess_is_rejected_before_any_work():
    with pytest.raises(ValueError, match=r"guess #1: .*'x'"):
        solve_guesses(get_problem(CRASHY), 0.5, np.array([[1.0], [np.nan]]), progress=False)


@pytest.mark.slow
def test_dejong_table_is_identical_for_one_and_two_workers():
    one = run_multistart(get_problem("dejong"), 0.3, seed=11, starts=12, workers=1, progress=False)
    two = run_multistart(get_problem("dejong"), 0.3, seed=11, starts=12, workers=2, progress=False)
    cols = [c for c in one.columns if c not in ("wall_s", "cpu_s")]
    assert len(one) == 12 and one["start"].tolist() == list(range(12))
    assert one[cols].equals(two[cols])
    assert one["converged"].sum() >= 6


def test_bad_options_are_rejected_in_the_parent_naming_the_field():
    with pytest.raises(pydantic.ValidationError, match="gtol"):
        run_multistart(get_problem("dejong"), 0.3, seed=1, starts=2, workers=1, options={"gtol": -1.0}, progress=False)
    with pytest.raises(pydantic.ValidationError, match="max_iters"):
        solve_guesses(get_problem("cr3bp"), 0.5, np.zeros((0, 64)), options={"max_iters": 5}, progress=False)
    with pytest.raises(TypeError, match="BfgsOptions"):
        run_multistart(get_problem("dejong"), 0.3, seed=1, starts=2, workers=1, options=IpoptOptions(), progress=False)


def test_typed_options_travel_to_the_worker_and_equal_the_mapping_path():
    typed = run_multistart(get_problem("dejong"), 0.3, 11, 4, 1, BfgsOptions(maxiter=1), progress=False)
    mapping = run_multistart(get_problem("dejong"), 0.3, 11, 4, 1, {"maxiter": 1}, progress=False)
    cols = [c for c in typed.columns if c not in ("wall_s", "cpu_s")]
    assert typed[cols].equals(mapping[cols])
    assert (typed["status"] == "max_iterations").all() and (typed["iterations"] == 1).all()
    assert set(typed["options_hash"]) == {BfgsOptions(maxiter=1).digest()}


def test_worker_timeout_follows_the_wall_cap_and_untyped_options_hash():
    assert worker_timeout_s(IpoptOptions(max_wall_s=10.0)) == 50.0
    assert worker_timeout_s({"max_wall_s": 10}) == 50.0  # an untyped user-defined problem's mapping
    assert options_digest("crashy", {"a": 1}) == options_digest("crashy", {"a": 1}) != options_digest("crashy", None)
    assert options_digest("dejong", BfgsOptions()) == BfgsOptions().digest()


# --------------------------------------------------------------------------- worker process groups
def _gone(pid: int, within_s: float = 10.0) -> bool:
    """True once ``pid`` no longer runs: absent, or a zombie waiting for init to reap it."""
    deadline = time.monotonic() + within_s
    while time.monotonic() < deadline:
        try:
            state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
        except FileNotFoundError:
            return True
        if state in ("Z", "X"):
            return True
        time.sleep(0.05)
    return False


def _worker_with_a_child(pid_file: str) -> None:
    """A pool worker that, like one compiling its solver, has started a long-running child."""
    detach_worker()
    child = subprocess.Popen(["sleep", "600"])
    Path(pid_file).write_text(str(child.pid))
    time.sleep(600)


def _pool_with_a_worker(pid_file: str) -> None:
    worker = mp.get_context("fork").Process(target=_worker_with_a_child, args=(pid_file,))
    worker.start()
    Path(pid_file + ".worker").write_text(str(worker.pid))
    time.sleep(600)


def _wait_for(path: Path) -> int:
    deadline = time.monotonic() + 30
    while not (path.is_file() and path.read_text()):
        assert time.monotonic() < deadline, f"{path} never written"
        time.sleep(0.05)
    return int(path.read_text())


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="process groups and /proc: Linux")
def test_killing_a_worker_kills_the_compiler_it_started(tmp_path):
    proc = mp.get_context("fork").Process(target=_worker_with_a_child, args=(str(tmp_path / "pid"),))
    proc.start()
    child = _wait_for(tmp_path / "pid")
    assert os.getpgid(proc.pid) == proc.pid and os.getpgid(child) == proc.pid
    kill_worker(proc)
    assert not proc.is_alive() and _gone(child), "the worker's child outlived it"


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="PR_SET_PDEATHSIG: Linux")
def test_a_worker_dies_with_its_pool(tmp_path):
    pool = mp.get_context("fork").Process(target=_pool_with_a_worker, args=(str(tmp_path / "pid"),))
    pool.start()
    worker = _wait_for(tmp_path / "pid.worker")
    child = _wait_for(tmp_path / "pid")
    os.kill(pool.pid, signal.SIGKILL)  # kill -9 of the pool: its worker is in another process group
    pool.join(5)
    assert _gone(worker), "the worker outlived its pool"
    with contextlib.suppress(ProcessLookupError):  # the worker's own child is orphaned, not killed: tidy up
        os.kill(child, signal.SIGKILL)


def _as_in_a_terminal() -> None:
    """A child's SIGINT as a terminal's shell leaves it: Python's handler, not blocked."""
    signal.signal(signal.SIGINT, signal.default_int_handler)
    signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})


_CTRL_C_WHILE_A_WORKER_STARTS = '''
import multiprocessing as mp, os, signal, sys, time
from amorgs.solvers.multistart import _sigint_held


def survive_a_ctrl_c(path):
    os.kill(os.getpid(), signal.SIGINT)  # the terminal's Ctrl-C reaches the starting worker too
    time.sleep(0.5)
    with open(path, "w") as f:
        f.write("alive")


if __name__ == "__main__":
    worker = mp.get_context("spawn").Process(target=survive_a_ctrl_c, args=(sys.argv[1],))
    try:
        with _sigint_held():
            worker.start()
            os.kill(os.getpid(), signal.SIGINT)  # Ctrl-C while the worker starts
            time.sleep(0.2)
        print("not interrupted")
    except KeyboardInterrupt:
        print("interrupted")
    worker.join(60)
    print(worker.exitcode)
'''


def test_a_ctrl_c_while_a_worker_starts_stops_the_caller_and_not_the_worker(tmp_path):
    """While a worker starts (before it leaves the terminal's process group), a Ctrl-C is the caller's: the
    caller gets its KeyboardInterrupt (ignoring SIGINT during the start lost it: a job ran on after Snakemake's
    Ctrl-C), and the worker, which the same Ctrl-C reaches, runs on (blocking SIGINT alone did not keep it from
    the worker: the resource tracker's start unblocked it, and the worker printed a KeyboardInterrupt)."""
    script, mark = tmp_path / "ctrl_c.py", tmp_path / "worker-alive"
    script.write_text(_CTRL_C_WHILE_A_WORKER_STARTS)
    run = subprocess.run([sys.executable, str(script), str(mark)], capture_output=True, text=True, timeout=120,
                         preexec_fn=_as_in_a_terminal)
    assert run.stdout.split() == ["interrupted", "0"], run.stdout + run.stderr
    assert mark.read_text() == "alive"
    assert "KeyboardInterrupt" not in run.stderr, run.stderr


_CTRL_C_AS_THE_POOL_STARTS_A_WORKER = '''
import os, signal, sys, time
from multiprocessing.context import SpawnProcess
sys.path.insert(0, sys.argv[1])  # crashy_problem
from amorgs.problems import get_problem
from amorgs.solvers.multistart import WorkerPool

started = []
real_start = SpawnProcess.start


def start_then_ctrl_c(self):
    real_start(self)
    started.append(self.pid)
    os.kill(os.getpid(), signal.SIGINT)  # Ctrl-C the moment the worker has started


if __name__ == "__main__":
    SpawnProcess.start = start_then_ctrl_c
    try:
        WorkerPool(get_problem("crashy_problem:CrashyProblem"), 2)
        print("not interrupted")
    except KeyboardInterrupt:
        print("interrupted")
    print(len(started), sum(os.path.exists(f"/proc/{pid}") for pid in started))
'''


def test_a_ctrl_c_as_the_pool_starts_a_worker_leaves_no_worker_behind(tmp_path):
    """The Ctrl-C held during a worker's start arrives before the pool has recorded that worker: the slot kills
    it itself, so nothing the pool started outlives the interrupt (no second worker is started either)."""
    script = tmp_path / "ctrl_c_pool.py"
    script.write_text(_CTRL_C_AS_THE_POOL_STARTS_A_WORKER)
    run = subprocess.run([sys.executable, str(script), str(Path(__file__).parent)], capture_output=True, text=True,
                         timeout=120, preexec_fn=_as_in_a_terminal)
    assert run.stdout.split() == ["interrupted", "1", "0"], run.stdout + run.stderr
    assert "Traceback" not in run.stderr, run.stderr
