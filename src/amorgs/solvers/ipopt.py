"""IPOPT local solver for a transcribed problem (the CR3BP): caps, status mapping, stall abort, timing, records.

The problem supplies the NLP (:class:`TranscribedProblem`); this module solves it under the caps of
:class:`~amorgs.solvers.options.IpoptOptions`, stops stalled solves, and turns every outcome into a
:class:`~amorgs.solvers.record.SolveRecord` — a numerical failure is a record, never an exception.  Build the
solver inside the process that uses it: CasADi objects do not pickle.
"""

from __future__ import annotations

import math
import time
from pathlib import Path
from typing import Protocol

import casadi as ca
import numpy as np

from amorgs.alphas import check_alpha
from amorgs.solvers.record import SolveRecord
from amorgs.solvers.codegen import ipopt_nlpsol
from amorgs.solvers.fingerprint import nlp_fingerprint
from amorgs.solvers.options import IpoptOptions, TranscriptionOptions

#: IPOPT return statuses that count as the solver's own success.
IPOPT_SUCCESS = ("Solve_Succeeded", "Solved_To_Acceptable_Level")
#: Status of a solve stopped by the stall abort.
STALLED = "aborted_stalled"


class Transcription(Protocol):
    """An NLP in CasADi form and the map between its variables ``w`` and the problem's stored layout ``x``."""

    options: TranscriptionOptions
    nlp: dict  # {"x": w, "p": α, "f": objective, "g": constraints (bounds: constraint_bounds)}
    n_w: int
    n_g: int
    c_sources: tuple[Path, ...]  # C files of the external functions ``nlp`` calls (compiled in with it)

    def bounds(self) -> tuple[np.ndarray, np.ndarray]: ...

    def to_internal(self, x: np.ndarray, alpha: float) -> np.ndarray: ...

    def to_stored(self, w: np.ndarray) -> np.ndarray: ...

    def constraint_bounds(self) -> tuple[np.ndarray, np.ndarray]: ...


class TranscribedProblem(Protocol):
    """What :class:`IpoptSolver` needs of a problem (see :class:`~amorgs.problems.cr3bp.problem.LowThrustTransfer`)."""

    name: str
    alpha_range: tuple[float, float]

    def check_guess(self, x: np.ndarray) -> np.ndarray: ...

    def transcribe(self, options: TranscriptionOptions) -> Transcription: ...

    def code_identity(self) -> dict:
        """JSON-able constants the problem compiles into the NLP code (part of the compile-cache key)."""
        ...

    def objective(self, x: np.ndarray) -> float: ...

    def verify_defect(self, x: np.ndarray, alpha: float) -> float:
        """Independent check of a solution (e.g. re-propagation), compared with ``verify_tol``."""
        ...


def constraint_violation(g: np.ndarray, lbg: np.ndarray, ubg: np.ndarray) -> float:
    """The largest distance of a constraint value outside its bounds [lbg, ubg] (0 inside; |g| for an
    equality); ``inf`` when any value is not finite."""
    if not g.size:
        return 0.0
    if not np.all(np.isfinite(g)):
        return math.inf
    return float(np.max(np.maximum(np.maximum(lbg - g, g - ubg), 0.0)))


class StallMonitor(ca.Callback):
    """IPOPT iteration callback: records the primal infeasibility (:func:`constraint_violation` of g against
    its bounds) per iteration and stops a stalled solve.

    Rule (deterministic, iteration counts and infeasibility only): at iteration i ≥ ``window`` the solve is
    stopped when the best infeasibility of iterations 0…i is still above ``floor`` and above ``factor`` × the
    best of iterations 0…i−window, i.e. it did not fall by 1/factor over the last ``window`` iterations.
    ``window`` = 0 only records.
    """

    def __init__(self, name: str, n_x: int, g_bounds: tuple[np.ndarray, np.ndarray], n_p: int, window: int,
                 factor: float, floor: float):
        ca.Callback.__init__(self)
        self.lbg, self.ubg = (np.asarray(b, float) for b in g_bounds)
        n_g = self.lbg.size
        self._sizes = {"x": n_x, "f": 1, "g": n_g, "lam_x": n_x, "lam_g": n_g, "lam_p": n_p}
        self.window, self.factor, self.floor = int(window), float(factor), float(floor)
        self.trace: list[float] = []
        self.best: list[float] = []
        self.stopped_at: int | None = None
        self.construct(name, {})

    def reset(self) -> None:
        self.trace, self.best, self.stopped_at = [], [], None

    def get_n_in(self):
        return ca.nlpsol_n_out()

    def get_n_out(self):
        return 1

    def get_name_in(self, i):
        return ca.nlpsol_out(i)

    def get_name_out(self, i):
        return "ret"

    def get_sparsity_in(self, i):
        n = self._sizes.get(ca.nlpsol_out(i), 0)
        return ca.Sparsity.dense(n, 1) if n else ca.Sparsity(0, 0)

    def eval(self, arg):
        inf = constraint_violation(np.asarray(arg[ca.nlpsol_out().index("g")]).ravel(), self.lbg, self.ubg)
        self.trace.append(inf)
        self.best.append(min(inf, self.best[-1]) if self.best else inf)
        i = len(self.trace) - 1
        if self.window > 0 and i >= self.window and self.stopped_at is None:
            best, before = self.best[i], self.best[i - self.window]
            if best > self.floor and best > self.factor * before:
                self.stopped_at = i
                return [1]
        return [0]


def ipopt_settings(options: IpoptOptions) -> dict:
    """The IPOPT options of a solve: caps and tolerances from ``options``, then ``options.ipopt_options``."""
    return {
        "max_iter": options.max_iter,
        "max_wall_time": options.max_wall_s,
        "tol": options.tol,
        "acceptable_tol": options.acceptable_tol,
        "acceptable_iter": options.acceptable_iter,
        "constr_viol_tol": options.feasibility_tol,
        "acceptable_constr_viol_tol": options.feasibility_tol,
        "mu_strategy": "adaptive",
        "hessian_approximation": options.hessian,
        "limited_memory_max_history": options.lbfgs_memory,
        "limited_memory_aug_solver": options.lbfgs_aug_solver,
        "linear_solver": options.linear_solver,
        "print_level": 0,
        "sb": "yes",
        **options.ipopt_options,
    }


class IpoptSolver:
    """IPOPT on a problem's transcription; build inside the process that uses it.

    The NLP for a given integration grid is built (or loaded from the compile cache) on first use; α is a
    parameter of the NLP, so one build serves every α with the same resolved step count.
    """

    def __init__(self, problem: TranscribedProblem, options: IpoptOptions):
        self.problem = problem
        self.options = options
        self.options_hash = options.digest()
        self.build_s = 0.0
        self._built: dict[TranscriptionOptions, tuple] = {}
        self._monitors: dict[TranscriptionOptions, StallMonitor | None] = {}
        self._fingerprints: dict[float, str] = {}
        self._jit_dirs: list = []  # JIT builds live as long as the solver
        self.last_trace: list[float] = []  # max|g| per IPOPT iteration of the latest solve (stall abort on)
        self._ipopt = ipopt_settings(options)

    def build(self, alpha: float) -> None:
        """Build (or load from the compile cache) the NLP that solves at ``alpha`` now, not at the first solve."""
        self._nlp(alpha)

    def transcription(self, alpha: float) -> Transcription:
        """The transcription (integration grid resolved for α) that solves at this α."""
        return self._nlp(alpha)[0]

    def _nlp(self, alpha: float) -> tuple:
        tr_opts = self.options.transcription.for_alpha(alpha)
        if tr_opts not in self._built:
            t0 = time.perf_counter()
            p, o = self.problem, self.options
            tr = p.transcribe(tr_opts)
            opts = {"ipopt": self._ipopt, "print_time": False, "error_on_fail": False}
            # The monitor is a Python callback at every iteration (≈ 0.15 ms of ≈ 6, docs/performance.md):
            # attached only when the stall abort is on.  It never changes the iterates.
            monitor = None
            g_bounds = tr.constraint_bounds()
            if o.stall_window > 0:
                monitor = StallMonitor(f"{p.name}_monitor", tr.n_w, g_bounds, 1, o.stall_window, o.stall_factor,
                                       o.stall_floor)
                opts["iteration_callback"] = monitor
            identity = {"transcription": tr_opts.hash_dict(), **p.code_identity()}
            nlpsol, jit_dir = ipopt_nlpsol(p.name, tr.nlp, opts, o.compile, o.compile_flags, o.hessian, identity,
                                           tr.c_sources)
            if jit_dir is not None:
                self._jit_dirs.append(jit_dir)
            self._monitors[tr_opts] = monitor
            self._built[tr_opts] = (tr, nlpsol, *tr.bounds(), *g_bounds)
            self.build_s += time.perf_counter() - t0
        return self._built[tr_opts]

    def fingerprint(self, alpha: float) -> str:
        """The numerical fingerprint of the NLP this solver solves at ``alpha`` (:mod:`amorgs.solvers.fingerprint`:
        the exact bits of its objective, constraints and derivatives at seeded points), computed once per α
        (≈ 10 ms) and recorded with every solve."""
        alpha = float(alpha)
        if alpha not in self._fingerprints:
            _, nlpsol, *bounds = self._nlp(alpha)
            self._fingerprints[alpha] = nlp_fingerprint(nlpsol, tuple(bounds), alpha)
        return self._fingerprints[alpha]

    def solve(self, x0: np.ndarray, alpha: float) -> SolveRecord:
        """Solve from a stored-layout guess; invalid input raises ``ValueError``, numerical failure never does."""
        p = self.problem
        alpha = check_alpha(alpha, p.alpha_range, p.name)
        x0 = p.check_guess(x0)
        tr, nlpsol, lbw, ubw, lbg, ubg = self._nlp(alpha)
        fingerprint = self.fingerprint(alpha)
        w0 = tr.to_internal(x0, alpha)
        monitor = self._monitors[self.options.transcription.for_alpha(alpha)]
        if monitor is not None:
            monitor.reset()
        wall0, cpu0 = time.perf_counter(), time.process_time()
        try:
            sol = nlpsol(x0=w0, p=alpha, lbx=lbw, ubx=ubw, lbg=lbg, ubg=ubg)
            stats = nlpsol.stats()
        except RuntimeError as exc:  # evaluation errors at the start point etc.
            return SolveRecord(
                status="exception", converged=False, solver_success=False, x=np.full(x0.size, np.nan),
                wall_s=time.perf_counter() - wall0, cpu_s=time.process_time() - cpu0, message=str(exc)[:200],
                nlp_fingerprint=fingerprint,
            )
        wall, cpu = time.perf_counter() - wall0, time.process_time() - cpu0
        status = str(stats.get("return_status", "unknown"))
        self.last_trace = list(monitor.trace) if monitor is not None else []
        if monitor is not None and monitor.stopped_at is not None and status == "User_Requested_Stop":
            status = STALLED
        w = np.asarray(sol["x"]).ravel()
        # The defect is that of the equality constraints (the match point); an inequality IPOPT leaves a few
        # 1e-9 outside its bound (bound relaxation) is a control the stored layout clips (to_stored).
        eq = lbg == ubg
        g = np.asarray(sol["g"]).ravel()
        defect = constraint_violation(g[eq], lbg[eq], ubg[eq]) if np.all(np.isfinite(w)) else math.inf
        x = tr.to_stored(w)
        solver_success = status in IPOPT_SUCCESS and defect <= self.options.feasibility_tol
        verify = p.verify_defect(x, alpha) if solver_success else math.nan
        converged = bool(solver_success and verify <= self.options.verify_tol)
        return SolveRecord(
            status=status,
            converged=converged,
            solver_success=bool(solver_success),
            x=x,
            objective=p.objective(x),
            iterations=int(stats.get("iter_count", 0)),
            wall_s=wall,
            cpu_s=cpu,
            defect=defect,
            verify_defect=verify,
            nlp_fingerprint=fingerprint,
        )
