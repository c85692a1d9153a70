"""The low-thrust Earth–Moon transfer as a problem family over α (max thrust in N), solved with IPOPT.

Decision vector (stored layout, 64 entries): ``(τ_s, τ_i, τ_f, m_f, θ_1, φ_1, ρ_1, …, θ_20, φ_20, ρ_20)``
with times in TU, m_f in kg of fuel at the terminal state, angles in rad, throttle in [0, 1]; see
:mod:`amorgs.problems.cr3bp.transcription`.  The objective is −m_f (kg), minimised.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import platform
import subprocess
import tempfile
import time
from dataclasses import asdict, dataclass, field, fields
from pathlib import Path

import casadi as ca
import numpy as np

from amorgs.problems.base import SolveRecord, check_alpha, check_vector
from amorgs.problems.cr3bp.boundary import load_boundary_conditions
from amorgs.problems.cr3bp.propagation import VERIFY_TOLERANCE, independent_defect
from amorgs.problems.cr3bp.transcription import (
    N_SEGMENTS,
    ForwardBackwardTranscription,
    TranscriptionOptions,
    variable_names,
)

ALPHA_RANGE = (0.1, 1.0)
IPOPT_SUCCESS = ("Solve_Succeeded", "Solved_To_Acceptable_Level")


@dataclass(frozen=True)
class SolverOptions:
    """Everything that determines a CR3BP local solve; hashed into every solution row.

    ``max_iter`` is the primary cap (deterministic); ``max_wall_s`` is only a safety net.  ``feasibility_tol``
    bounds the NLP's own match-point defect (DU, VU, t) for the solve to count; ``verify_tol`` bounds the
    independent DOP853 defect (spec §6).

    Stall abort (deterministic: iteration counts and infeasibility only, never wall time): with
    ``stall_window`` = W > 0 a solve stops with status ``aborted_stalled`` at the first iteration i ≥ W where
    the best max|g| so far is above ``stall_floor`` and above ``stall_factor`` × the best max|g| up to
    iteration i − W (the primal infeasibility did not fall by 1/``stall_factor`` in W iterations).  The rule
    and its default were chosen from the infeasibility traces of converged vs failed starts
    (docs/performance.md); 0 switches it off.

    ``compile_flags``: gcc flags of the cached NLP library (part of its cache key, with the CPU model when
    ``-march=native``).  ``-ffp-contract=off`` keeps the floating-point results of ``-O2`` bit for bit
    (no fused multiply-adds), so only the speed changes.  ``ipopt_options``: extra IPOPT options, applied
    last (they override the ones derived from the fields above).
    """

    hessian: str = "limited-memory"  # or "exact"
    lbfgs_memory: int = 30
    max_iter: int = 1000
    max_wall_s: float = 60.0
    tol: float = 1e-6
    acceptable_tol: float = 1e-4
    acceptable_iter: int = 10
    feasibility_tol: float = 1e-8
    verify_tol: float = VERIFY_TOLERANCE
    linear_solver: str = "mumps"
    stall_window: int = 0
    stall_factor: float = 0.5
    stall_floor: float = 1e-6
    compile: str = "cache"  # "cache": C code compiled once per machine; "jit": per process; "none"
    compile_flags: str = "-O3 -march=native -ffp-contract=off"
    ipopt_options: dict = field(default_factory=dict)
    transcription: TranscriptionOptions = field(default_factory=TranscriptionOptions)

    @classmethod
    def from_dict(cls, options: dict | None) -> "SolverOptions":
        """Build from a plain dict (config section); unknown keys raise a ``ValueError`` naming them."""
        options = dict(options or {})
        known = {f.name for f in fields(cls)}
        unknown = sorted(set(options) - known)
        if unknown:
            raise ValueError(f"unknown cr3bp solver option(s) {unknown}; known: {sorted(known)}")
        tr = options.pop("transcription", {})
        if isinstance(tr, dict):
            tknown = {f.name for f in fields(TranscriptionOptions)}
            bad = sorted(set(tr) - tknown)
            if bad:
                raise ValueError(f"unknown cr3bp transcription option(s) {bad}; known: {sorted(tknown)}")
            tr = TranscriptionOptions(**tr)
        opts = cls(transcription=tr, **options)
        if opts.compile not in ("cache", "jit", "none"):
            raise ValueError(f"cr3bp solver option compile must be 'cache', 'jit' or 'none', got {opts.compile!r}")
        if opts.hessian not in ("exact", "limited-memory"):
            raise ValueError(f"cr3bp solver option hessian must be 'exact' or 'limited-memory', got {opts.hessian!r}")
        if not isinstance(opts.stall_window, int) or isinstance(opts.stall_window, bool) or opts.stall_window < 0:
            raise ValueError(f"cr3bp solver option stall_window must be an integer ≥ 0, got {opts.stall_window!r}")
        if not 0.0 < float(opts.stall_factor) <= 1.0:
            raise ValueError(f"cr3bp solver option stall_factor must be in (0, 1], got {opts.stall_factor!r}")
        if not float(opts.stall_floor) >= 0.0:
            raise ValueError(f"cr3bp solver option stall_floor must be ≥ 0, got {opts.stall_floor!r}")
        if not isinstance(opts.compile_flags, str) or not opts.compile_flags.split():
            raise ValueError(f"cr3bp solver option compile_flags must be a non-empty string, got {opts.compile_flags!r}")
        if not isinstance(opts.ipopt_options, dict) or not all(isinstance(k, str) for k in opts.ipopt_options):
            raise ValueError(f"cr3bp solver option ipopt_options must be a dict of IPOPT options, got {opts.ipopt_options!r}")
        return opts

    def to_dict(self) -> dict:
        return asdict(self)

    def digest(self) -> str:
        """Short stable hash of the options (stored in every row as ``options_hash``)."""
        return hashlib.sha256(json.dumps(self.to_dict(), sort_keys=True).encode()).hexdigest()[:12]


class _Monitor(ca.Callback):
    """IPOPT iteration callback: records max|g| per iteration and stops a stalled solve.

    Rule (deterministic, iteration counts and infeasibility only): at iteration i ≥ ``window`` the solve is
    stopped when the best max|g| of iterations 0…i is still above ``floor`` and above ``factor`` × the best
    max|g| of iterations 0…i−window, i.e. the primal infeasibility did not fall by 1/factor over the last
    ``window`` iterations.  ``window`` = 0 only records.
    """

    def __init__(self, n_x: int, n_g: int, n_p: int, window: int, factor: float, floor: float):
        ca.Callback.__init__(self)
        self._sizes = {"x": n_x, "f": 1, "g": n_g, "lam_x": n_x, "lam_g": n_g, "lam_p": n_p}
        self.window, self.factor, self.floor = int(window), float(factor), float(floor)
        self.trace: list[float] = []
        self.best: list[float] = []
        self.stopped_at: int | None = None
        self.construct("cr3bp_monitor", {})

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
        g = np.asarray(arg[ca.nlpsol_out().index("g")]).ravel()
        inf = float(np.max(np.abs(g))) if g.size and np.all(np.isfinite(g)) else math.inf
        self.trace.append(inf)
        self.best.append(min(inf, self.best[-1]) if self.best else inf)
        i = len(self.trace) - 1
        if self.window > 0 and i >= self.window and self.stopped_at is None:
            best, before = self.best[i], self.best[i - self.window]
            if best > self.floor and best > self.factor * before:
                self.stopped_at = i
                return [1]
        return [0]


class LowThrustTransfer:
    """Problem family: minimum-fuel transfer from the GTO spiral end to the L1-halo stable manifold."""

    name = "cr3bp"
    alpha_range = ALPHA_RANGE

    def __init__(self, boundary_conditions: dict):
        self.bc = boundary_conditions
        self.initial_state = np.asarray(boundary_conditions["initial_state"], float)
        self.terminal_state = np.asarray(boundary_conditions["terminal_state"], float)
        self.variable_names = variable_names(N_SEGMENTS)
        m0 = float(self.initial_state[6])
        self.lower = np.array([0.0, 0.0, 0.0, 0.0] + [0.0, -math.pi / 2, 0.0] * N_SEGMENTS)
        self.upper = np.array([40.0, 15.0, 15.0, m0] + [2 * math.pi, math.pi / 2, 1.0] * N_SEGMENTS)

    @classmethod
    def from_resource(cls, path=None) -> "LowThrustTransfer":
        return cls(load_boundary_conditions(path))

    def sample_uniform(self, alpha: float, n: int, rng: np.random.Generator) -> np.ndarray:
        """Uniform initial guesses of spec §6 (m_f ~ U[350, 450] kg); shape (n, 64)."""
        check_alpha(alpha, self.alpha_range, self.name)
        lo = self.lower.copy()
        hi = self.upper.copy()
        lo[3], hi[3] = 350.0, 450.0
        return lo + (hi - lo) * rng.random((n, lo.size))

    def check_guess(self, x: np.ndarray) -> np.ndarray:
        return check_vector(x, self.variable_names, self.lower, self.upper, self.name)

    def make_local_solver(self, options: dict | SolverOptions | None = None) -> "IpoptSolver":
        opts = options if isinstance(options, SolverOptions) else SolverOptions.from_dict(options)
        return IpoptSolver(self, opts)


def cache_dir() -> Path:
    """Where compiled NLP libraries are kept: ``$AMORGS_CACHE_DIR`` or ``~/.cache/amorgs``."""
    return Path(os.environ.get("AMORGS_CACHE_DIR", Path.home() / ".cache" / "amorgs"))


def cpu_identity() -> str:
    """CPU model and instruction-set flags (part of the cache key when code is built with -march=native)."""
    try:
        info = Path("/proc/cpuinfo").read_text().splitlines()
    except OSError:
        return platform.processor() or platform.machine()
    model = next((line.split(":", 1)[1].strip() for line in info if line.startswith("model name")), "")
    flags = next((line.split(":", 1)[1].strip() for line in info if line.startswith(("flags", "Features"))), "")
    return f"{model}|{hashlib.sha256(flags.encode()).hexdigest()[:16]}"


def compiled_nlp_library(
    transcription: ForwardBackwardTranscription, hessian: str, problem, flags: str = "-O2"
) -> Path:
    """Shared library with the NLP functions IPOPT needs, generated and compiled once per machine.

    The key covers everything compiled into the code: transcription options, Hessian mode, boundary
    conditions (embedded as constants), CasADi version, CPU architecture and the gcc flags (plus the CPU
    model and instruction-set flags when they include ``-march=native``).  Concurrent workers may race
    to build it; each compiles into a private temp file and ``os.replace`` makes the winner atomic.
    """
    key = json.dumps(
        {
            "transcription": asdict(transcription.options),
            "hessian": hessian,
            "initial": problem.initial_state.tolist(),
            "terminal": problem.terminal_state.tolist(),
            "casadi": ca.__version__,
            "machine": platform.machine(),
            "flags": flags,
            "cpu": cpu_identity() if "native" in flags else "",
            "format": 1,
        },
        sort_keys=True,
    )
    target = cache_dir() / f"cr3bp_nlp_{hashlib.sha256(key.encode()).hexdigest()[:16]}.so"
    if target.is_file():
        return target
    target.parent.mkdir(parents=True, exist_ok=True)
    opts = {"ipopt": {"hessian_approximation": hessian}}
    plain = ca.nlpsol("cr3bp", "ipopt", transcription.nlp, opts)
    with tempfile.TemporaryDirectory(prefix="amorgs-codegen-", dir=target.parent) as tmp:
        cwd = os.getcwd()
        try:
            os.chdir(tmp)
            plain.generate_dependencies("cr3bp_nlp.c")
        finally:
            os.chdir(cwd)
        built = Path(tmp) / target.name
        subprocess.run(
            ["gcc", *flags.split(), "-fPIC", "-shared", str(Path(tmp) / "cr3bp_nlp.c"), "-o", str(built), "-lm"],
            check=True,
            capture_output=True,
        )
        os.replace(built, target)
    return target


class IpoptSolver:
    """IPOPT on the forward–backward transcription; build inside the process that uses it.

    The NLP for a given integration grid is built (or loaded from the compile cache) on first use; α is a
    parameter of the NLP, so one build serves every α with the same resolved step count.
    """

    def __init__(self, problem: LowThrustTransfer, options: SolverOptions):
        self.problem = problem
        self.options = options
        self.options_hash = options.digest()
        self.build_s = 0.0
        self._built: dict[TranscriptionOptions, tuple] = {}
        self._monitors: dict[TranscriptionOptions, _Monitor] = {}
        self.last_trace: list[float] = []  # max|g| per IPOPT iteration of the latest solve
        self._ipopt = {
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
            "linear_solver": options.linear_solver,
            "print_level": 0,
            "sb": "yes",
            **options.ipopt_options,
        }

    def transcription(self, alpha: float) -> ForwardBackwardTranscription:
        """The transcription (integration grid resolved for α) that solves at this α."""
        return self._nlp(alpha)[0]

    def _nlp(self, alpha: float) -> tuple:
        tr_opts = self.options.transcription.for_alpha(alpha)
        if tr_opts not in self._built:
            t0 = time.perf_counter()
            tr = ForwardBackwardTranscription(self.problem.initial_state, self.problem.terminal_state, tr_opts)
            o = self.options
            monitor = _Monitor(tr.n_w, tr.n_g, 1, o.stall_window, o.stall_factor, o.stall_floor)
            opts = {"ipopt": self._ipopt, "print_time": False, "error_on_fail": False,
                    "iteration_callback": monitor}
            mode = self.options.compile
            if mode == "cache":
                library = compiled_nlp_library(tr, self.options.hessian, self.problem, self.options.compile_flags)
                nlpsol = ca.nlpsol("cr3bp", "ipopt", str(library), opts)
            elif mode == "jit":
                options_flags = self.options.compile_flags.split()
                # CasADi writes the JIT source into the working directory: build inside a private temp dir.
                self._jit_dir = tempfile.TemporaryDirectory(prefix="amorgs-jit-")
                opts.update(jit=True, jit_cleanup=False, compiler="shell",
                            jit_options={"flags": options_flags, "verbose": False, "directory": self._jit_dir.name})
                cwd = os.getcwd()
                try:
                    os.chdir(self._jit_dir.name)
                    nlpsol = ca.nlpsol("cr3bp", "ipopt", tr.nlp, opts)
                finally:
                    os.chdir(cwd)
            else:
                nlpsol = ca.nlpsol("cr3bp", "ipopt", tr.nlp, opts)
            self._monitors[tr_opts] = monitor
            self._built[tr_opts] = (tr, nlpsol, *tr.bounds())
            self.build_s += time.perf_counter() - t0
        return self._built[tr_opts]

    def solve(self, x0: np.ndarray, alpha: float) -> SolveRecord:
        """Solve from a stored-layout guess; never raises for numerical failures."""
        p = self.problem
        alpha = check_alpha(alpha, p.alpha_range, p.name)
        x0 = p.check_guess(x0)
        tr, nlpsol, lbw, ubw = self._nlp(alpha)
        w0 = tr.to_internal(x0, alpha)
        monitor = self._monitors[self.options.transcription.for_alpha(alpha)]
        monitor.reset()
        wall0, cpu0 = time.perf_counter(), time.process_time()
        try:
            sol = nlpsol(x0=w0, p=alpha, lbx=lbw, ubx=ubw, lbg=0.0, ubg=0.0)
            stats = nlpsol.stats()
        except RuntimeError as exc:  # evaluation errors at the start point etc.
            return SolveRecord(
                status="exception", converged=False, solver_success=False, x=np.full(x0.size, np.nan),
                wall_s=time.perf_counter() - wall0, cpu_s=time.process_time() - cpu0, message=str(exc)[:200],
            )
        wall, cpu = time.perf_counter() - wall0, time.process_time() - cpu0
        status = str(stats.get("return_status", "unknown"))
        self.last_trace = list(monitor.trace)
        if monitor.stopped_at is not None and status == "User_Requested_Stop":
            status = "aborted_stalled"
        w = np.asarray(sol["x"]).ravel()
        defect = float(np.max(np.abs(np.asarray(sol["g"]).ravel()))) if np.all(np.isfinite(w)) else math.inf
        x = tr.to_stored(w)
        solver_success = status in IPOPT_SUCCESS and defect <= self.options.feasibility_tol
        verify = independent_defect(x, alpha, p.initial_state, p.terminal_state) if solver_success else math.nan
        converged = bool(solver_success and verify <= self.options.verify_tol)
        return SolveRecord(
            status=status,
            converged=converged,
            solver_success=bool(solver_success),
            x=x,
            objective=-float(x[3]),
            iterations=int(stats.get("iter_count", 0)),
            wall_s=wall,
            cpu_s=cpu,
            defect=defect,
            verify_defect=verify,
        )
