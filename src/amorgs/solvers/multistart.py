"""Parallel multi-start: solve many initial guesses of one (problem, α) across worker processes.

Design (see DESIGN.md §4): CasADi objects do not pickle and IPOPT is not thread-safe, so every worker is a
*spawned process* that builds its own local solver once and then solves the guesses it is sent.  The
solver's options travel typed end to end: the caller's options object (or a mapping, converted through the
problem's ``options_type``, see :mod:`amorgs.solvers.options`) is validated in the parent, pickled to every
worker and handed to the problem's local solver as it is.  The guesses are drawn in the parent from
``numpy.random.default_rng(seed)`` before any work starts, and every solve is deterministic (iteration cap
first, wall cap only as a safety net), so the table is identical for any number of workers.  A worker that
crashes or hangs past ``hard_timeout_s`` is killed and replaced; its guess becomes one row with status
``crashed`` / ``timeout`` — it never takes the job down.

The pool takes a *problem object* (the :class:`~amorgs.problems.base.Problem` protocol: ``name``,
``variable_names``, ``check_guess``, ``sample_uniform``, ``make_local_solver``, optionally ``options_type``;
the caller resolves a name with :func:`amorgs.problems.get_problem`): it is plain data, pickled to each worker,
which builds its local solver there.  So the solvers import nothing of the problem families.

:class:`WorkerPool` keeps its workers across calls: a caller that solves in rounds (``amorgs design``) pays
the start-up — spawn, imports, the solver's build — once, and can start the workers before it has its first
guesses, so that they build while it loads its inputs.  :func:`solve_guesses` is one pool for one batch.

Every worker leads its own process group, and the pool kills the whole group: a worker killed while gcc
builds its solver (:mod:`amorgs.solvers.codegen`) takes the compiler with it instead of leaving it running
under init.  On Linux a worker also dies with the process that started it (``PR_SET_PDEATHSIG``), so a
pool killed outright (``kill -9``, Snakemake killing a job's process group) leaves no worker behind.  Workers
start, and stay, with SIGINT blocked: a Ctrl-C is the caller's (it stops the pool, which kills them), and
one that arrives while a worker starts still reaches the caller.
"""

from __future__ import annotations

import ctypes
import hashlib
import json
import math
import multiprocessing as mp
import os
import signal
import sys
import threading
import time
from collections.abc import Callable, Iterator, Mapping
from contextlib import contextmanager
from multiprocessing import resource_tracker
from multiprocessing.connection import wait

import numpy as np
import pandas as pd

from amorgs.solvers.options import Options, as_options
from amorgs.solvers.record import SolveRecord

BUILD_TIMEOUT_S = 900.0
#: A worker's hard timeout per solve (s) when the solver has no wall cap of its own (``max_wall_s``).
UNCAPPED_TIMEOUT_S = 600.0
_THREAD_ENV = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")


OptionsLike = Options | Mapping | None
"""What callers may pass as solver options: the problem's options object, a plain mapping, or ``None``."""


def options_digest(problem: str, options: OptionsLike) -> str:
    """Stable short hash of the options: the options object's own ``digest()``, else (an untyped user-defined
    problem's mapping) the hash of (problem, options)."""
    if hasattr(options, "digest"):
        return options.digest()
    text = json.dumps({"problem": problem, "options": dict(options or {})}, sort_keys=True, default=str)
    return hashlib.sha256(text.encode()).hexdigest()[:12]


def resolve_options(problem, options: OptionsLike):
    """``options`` as the typed object ``problem``'s solver takes (``problem.options_type``; a mapping or
    ``None`` is converted, a bad value or unknown key raises ``ValueError`` naming it); a problem without an
    ``options_type`` gets ``options`` as they are."""
    options_type = getattr(problem, "options_type", None)
    return options if options_type is None else as_options(options_type, options)


def worker_timeout_s(options: OptionsLike) -> float:
    """Hard timeout per solve (s): 2 × the solver's own wall cap ``max_wall_s`` + 30 s, or
    ``UNCAPPED_TIMEOUT_S`` for a solver without one."""
    wall = options.get("max_wall_s") if isinstance(options, Mapping) else getattr(options, "max_wall_s", None)
    return UNCAPPED_TIMEOUT_S if wall is None else 2 * float(wall) + 30.0


_PR_SET_PDEATHSIG = 1  # linux/prctl.h


def detach_worker() -> None:
    """In a freshly started worker: lead a new process group (so :func:`kill_worker` reaches the processes the
    worker starts, e.g. gcc) and, on Linux, receive SIGKILL when the parent dies (the group no longer shares
    the parent's, so a kill of the parent's group would otherwise miss it)."""
    parent = os.getppid()
    os.setpgrp()
    if sys.platform.startswith("linux"):
        ctypes.CDLL(None, use_errno=True).prctl(_PR_SET_PDEATHSIG, signal.SIGKILL)
        if os.getppid() != parent:  # the parent died before the request took effect
            os._exit(1)


def kill_worker(proc) -> None:
    """SIGKILL a worker started with :func:`detach_worker` together with every process of its group (they
    may outlive it, e.g. a compiler it started), then reap it."""
    try:
        os.killpg(proc.pid, signal.SIGKILL)
    except (ProcessLookupError, PermissionError):  # group gone (or not yet formed): the worker alone
        if proc.is_alive():
            proc.kill()
    proc.join(5)


@contextmanager
def _sigint_held() -> Iterator[None]:
    """Keep a Ctrl-C from the worker that starts in this block, and hold it for the caller until the block ends.

    SIGINT is blocked in this thread while the worker starts, and a blocked signal stays blocked across fork and
    exec: the worker starts, and stays, out of reach of the terminal's Ctrl-C (it leaves the terminal's process
    group in :func:`detach_worker`; the pool, not a signal, ends it).  In the main thread a Ctrl-C that arrives
    meanwhile (taken by another thread, or pending until the block lifts) is only noted, and raised again with
    the caller's own handler when the block ends — never inside the start, where it could leave a started worker
    unrecorded (ignoring SIGINT instead, process-wide, lost it).  The resource tracker is started first because
    its start *unblocks* SIGINT in the calling thread (CPython 3.11's ``resource_tracker.ensure_running``),
    which would otherwise let the worker start with it."""
    resource_tracker.ensure_running()
    noted: list[int] = []
    previous_handler = None
    if threading.current_thread() is threading.main_thread() and signal.getsignal(signal.SIGINT) is not None:
        previous_handler = signal.signal(signal.SIGINT, lambda signum, frame: noted.append(signum))
    previous_mask = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, previous_mask)
        if previous_handler is not None:
            signal.signal(signal.SIGINT, previous_handler)
            if noted:
                signal.raise_signal(signal.SIGINT)


def _own_cpu_s() -> float:
    """CPU seconds (user + system) of this process and of the children it waited for (a compiler)."""
    t = os.times()
    return t.user + t.system + t.children_user + t.children_system


def _worker(conn, problem, options: OptionsLike, alpha: float | None = None) -> None:
    """Worker loop: build the problem's local solver (for ``alpha`` too, if given and the solver has a
    ``build(alpha)``), announce readiness, then answer (index, x0, alpha) tasks until the pool kills it;
    every message ends with the worker's CPU seconds so far (:func:`_own_cpu_s`)."""
    detach_worker()
    try:
        solver = problem.make_local_solver(options)
        if alpha is not None and hasattr(solver, "build"):
            solver.build(alpha)
        digest = getattr(solver, "options_hash", None) or options_digest(problem.name, options)
        conn.send(("ready", digest, float(getattr(solver, "build_s", 0.0)), _own_cpu_s()))
    except Exception as exc:  # configuration errors surface in the parent with their message
        conn.send(("error", f"{type(exc).__name__}: {exc}"))
        return
    while True:
        index, x0, alpha = conn.recv()
        wall0, cpu0 = time.perf_counter(), time.process_time()
        try:
            record = solver.solve(x0, alpha)
        except Exception as exc:  # a bug or numerical blow-up in one solve costs one row
            record = SolveRecord(
                status="exception", converged=False, solver_success=False, x=np.full(len(x0), np.nan),
                wall_s=time.perf_counter() - wall0, cpu_s=time.process_time() - cpu0,
                message=f"{type(exc).__name__}: {exc}"[:200],
            )
        conn.send(("done", index, record, _own_cpu_s()))


class _Slot:
    """One worker process and the task it is working on."""

    def __init__(self, ctx, problem, options: OptionsLike, alpha: float | None = None):
        self.conn, child = ctx.Pipe()
        self.proc = ctx.Process(target=_worker, args=(child, problem, options, alpha), daemon=True)
        try:
            with _sigint_held():  # Ctrl-C is the caller's to handle: a starting worker never sees it
                self.proc.start()
        except BaseException:  # the Ctrl-C held during the start: the caller's pool does not know this worker yet
            if self.proc.pid is not None:
                kill_worker(self.proc)
            self.conn.close()
            raise
        finally:
            child.close()
        self.ready = False
        self.task: int | None = None
        self.since = time.monotonic()
        self.cpu_s = 0.0  # the worker's CPU seconds as of its latest message

    def kill(self) -> None:
        kill_worker(self.proc)
        self.conn.close()


def check_guesses(problem, guesses: np.ndarray) -> None:
    """``ValueError`` naming the first guess (row of ``guesses``) that ``problem`` refuses."""
    for i, g in enumerate(guesses):
        try:
            problem.check_guess(g)
        except ValueError as exc:
            raise ValueError(f"guess #{i}: {exc}") from None


class WorkerPool:
    """``workers`` solver processes of one problem and one set of options, started at once and kept across
    :meth:`solve` calls until :meth:`close` (or the end of a ``with`` block) kills them.

    ``problem``: a problem object (module docstring); ``options``: see :func:`resolve_options` (validated here,
    in the parent); ``hard_timeout_s`` (default :func:`worker_timeout_s`) kills a stuck worker, whose guess
    becomes one ``timeout`` row; ``alpha``: the α the workers build their solver for as they start (a solver
    with ``build(alpha)``, e.g. the NLP of that α's integration grid), so that the first solve starts at once.  A worker that dies is replaced while guesses are pending, and the pool is
    topped up to ``workers`` at the next :meth:`solve`.  Which worker solves a guess never changes its record.
    """

    def __init__(self, problem, workers: int = 1, options: OptionsLike = None, hard_timeout_s: float | None = None,
                 alpha: float | None = None):
        if workers < 1:
            raise ValueError(f"workers must be ≥ 1, got {workers}")
        self.problem = problem
        self.options = resolve_options(problem, options)
        self.workers = int(workers)
        self.hard_timeout_s = worker_timeout_s(self.options) if hard_timeout_s is None else float(hard_timeout_s)
        self.options_hash: str | None = None  # reported by the first worker that built its solver
        self.alpha = alpha
        for key in _THREAD_ENV:
            os.environ.setdefault(key, "1")
        self._ctx = mp.get_context("spawn")
        self._slots: list[_Slot] = []
        try:
            self._top_up()
        except BaseException:
            self.close()
            raise

    def __enter__(self) -> WorkerPool:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def _top_up(self) -> None:
        """Drop the idle workers that died and start new ones until the pool holds ``workers`` processes."""
        for slot in [s for s in self._slots if s.task is None and not s.proc.is_alive()]:
            slot.kill()
            self._slots.remove(slot)
        while len(self._slots) < self.workers:
            self._slots.append(_Slot(self._ctx, self.problem, self.options, self.alpha))

    def close(self) -> None:
        """Kill every worker (and whatever it started) and reap it; the pool cannot solve afterwards."""
        slots, self._slots = self._slots, []
        for slot in slots:
            slot.kill()

    def cpu_seconds(self) -> float:
        """CPU seconds of the live workers so far (each as of its latest message: its solver build, its solves).
        Workers already ended count in ``resource.getrusage(RUSAGE_CHILDREN)`` of this process instead."""
        return float(sum(slot.cpu_s for slot in self._slots))

    def solve(self, alpha: float, guesses: np.ndarray, progress: bool = True, label: str = "",
              started: Callable[[], None] | None = None) -> tuple[list[SolveRecord], dict]:
        """Solve every row of ``guesses`` at ``alpha``; returns the records in input order and run info
        (``build_s`` of the workers that became ready during this call, ``options_hash``, ``replaced_workers``).
        ``started`` is called once, as soon as the first guess is with a worker (work the caller defers until
        the solving has begun).  Any exception (a solver that cannot be built, Ctrl-C) closes the pool before
        it propagates."""
        guesses = np.asarray(guesses, float)
        check_guesses(self.problem, guesses)
        try:
            return self._solve(float(alpha), guesses, progress, label, started)
        except BaseException:
            self.close()
            raise

    def _solve(self, alpha: float, guesses: np.ndarray, progress: bool, label: str,
               started: Callable[[], None] | None) -> tuple[list[SolveRecord], dict]:
        problem, hard_timeout_s = self.problem, self.hard_timeout_s
        self._top_up()
        slots = self._slots
        n = len(guesses)
        records: list[SolveRecord | None] = [None] * n
        info = {"build_s": [], "options_hash": self.options_hash, "replaced_workers": 0}
        pending = list(range(n))[::-1]
        done = converged = 0
        t_start = time.monotonic()

        def dispatch(slot: _Slot) -> None:
            nonlocal started
            if pending:
                slot.task = pending.pop()
                slot.since = time.monotonic()
                slot.conn.send((slot.task, guesses[slot.task], alpha))
                if started is not None:
                    started, call = None, started
                    call()
            else:
                slot.task = None  # idle until the next call

        def failed(index: int, status: str, elapsed: float) -> SolveRecord:
            return SolveRecord(status=status, converged=False, solver_success=False, x=np.full(guesses.shape[1], np.nan),
                               wall_s=elapsed, cpu_s=math.nan, message=f"worker {status}")

        for slot in slots:  # workers ready since an earlier call start at once
            if slot.ready:
                dispatch(slot)
        while done < n:
            ready = wait([s.conn for s in slots] + [s.proc.sentinel for s in slots], timeout=1.0)
            for slot in list(slots):
                msg = None
                if slot.conn in ready or (slot.proc.sentinel in ready and slot.conn.poll()):
                    try:
                        msg = slot.conn.recv()
                    except (EOFError, OSError):
                        msg = None
                if msg is not None:
                    if msg[0] == "error":
                        raise ValueError(f"{problem.name} solver could not be built: {msg[1]}")
                    if msg[0] == "ready":
                        slot.ready = True
                        self.options_hash = info["options_hash"] = msg[1]
                        info["build_s"].append(msg[2])
                        slot.cpu_s = msg[3]
                        dispatch(slot)
                        continue
                    _, index, record, slot.cpu_s = msg
                    records[index] = record
                    done += 1
                    converged += bool(record.converged)
                    if progress:
                        rate = (time.monotonic() - t_start) / done
                        print(f"[{label or problem.name} α={alpha:g}] {done}/{n} solved, {converged} converged, "
                              f"{rate:.1f} s/solve wall", file=sys.stderr, flush=True)
                    dispatch(slot)
                    continue
                elapsed = time.monotonic() - slot.since
                dead = not slot.proc.is_alive()
                limit = hard_timeout_s if slot.ready else BUILD_TIMEOUT_S
                if slot.task is not None and (dead or elapsed > limit):
                    records[slot.task] = failed(slot.task, "crashed" if dead else "timeout", elapsed)
                    done += 1
                    info["replaced_workers"] += 1
                    slot.kill()
                    slots.remove(slot)
                    if pending:
                        slots.append(_Slot(self._ctx, problem, self.options, self.alpha))
                elif not slot.ready and (dead or elapsed > limit):
                    raise RuntimeError(f"{problem.name} worker failed to start (exit code {slot.proc.exitcode})")
                elif dead:  # ready and idle, and gone: replaced at the next call
                    slot.kill()
                    slots.remove(slot)
        return records, info  # type: ignore[return-value]


def solve_guesses(
    problem,
    alpha: float,
    guesses: np.ndarray,
    workers: int = 1,
    options: OptionsLike = None,
    hard_timeout_s: float | None = None,
    progress: bool = True,
    label: str = "",
) -> tuple[list[SolveRecord], dict]:
    """Solve every row of ``guesses`` at ``alpha`` with ``problem``'s local solver (a problem object, see the
    module docstring) in a :class:`WorkerPool` of ``min(workers, len(guesses))`` processes, closed on return;
    returns records in input order and run info.

    ``options``: the solver's options (see :func:`resolve_options`); ``hard_timeout_s`` (default
    :func:`worker_timeout_s`) kills a stuck worker.  Bad options or guesses raise before any process starts.
    """
    options = resolve_options(problem, options)
    guesses = np.asarray(guesses, float)
    check_guesses(problem, guesses)
    if workers < 1:
        raise ValueError(f"workers must be ≥ 1, got {workers}")
    with WorkerPool(problem, min(workers, max(len(guesses), 1)), options, hard_timeout_s) as pool:
        return pool.solve(alpha, guesses, progress, label)


def run_multistart(
    problem,
    alpha: float,
    seed: int,
    starts: int,
    workers: int = 1,
    options: OptionsLike = None,
    progress: bool = True,
    hard_timeout_s: float | None = None,
) -> pd.DataFrame:
    """``starts`` uniform guesses of ``problem`` (a problem object) drawn with ``default_rng(seed)``, solved with ``options`` (the problem's
    options object; a mapping or ``None`` is converted, see :func:`resolve_options`); one row per start.

    Columns: problem, alpha, seed, start, guess_<var>…, <var>…, status, converged, solver_success,
    objective, iterations, wall_s, cpu_s, defect, verify_defect, message, options_hash.
    """
    options = resolve_options(problem, options)
    guesses = problem.sample_uniform(alpha, starts, np.random.default_rng(seed))
    records, info = solve_guesses(problem, alpha, guesses, workers, options, hard_timeout_s, progress)
    return records_table(problem.name, alpha, seed, guesses, records, problem.variable_names, info["options_hash"])


def records_table(problem, alpha, seed, guesses, records, names, options_hash) -> pd.DataFrame:
    """Assemble solve records and their guesses into the solution-table layout (docs/data-format.md)."""
    rows = []
    for i, (g, r) in enumerate(zip(guesses, records)):
        row = {"problem": problem, "alpha": float(alpha), "seed": int(seed), "start": i}
        row.update({f"guess_{k}": float(v) for k, v in zip(names, g)})
        row.update(r.to_row(names))
        row["options_hash"] = options_hash
        rows.append(row)
    df = pd.DataFrame(rows)
    if not rows:
        return df
    order = ["problem", "alpha", "seed", "start", *[f"guess_{k}" for k in names], *names]
    return df[order + [c for c in df.columns if c not in order]]
