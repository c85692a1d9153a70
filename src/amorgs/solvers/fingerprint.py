"""The numerical fingerprint of a solver's problem: a short hash of the exact bits its compiled NLP returns.

Two codes that build "the same NLP" can still round differently (a reordered sum, a division turned into a
multiplication by a reciprocal): IPOPT's iterates then differ in the last bits, and a start can move to another
basin.  The solver options' hash (``options_hash``) cannot see that; the fingerprint can.  It is the first 12 hex
digits of a SHA-256 over

* the NLP's box and constraint bounds (``lbw, ubw, lbg, ubg``) as float64 bytes,
* at :data:`POINTS` points ``w`` drawn with ``numpy.random.default_rng(SEED)`` uniformly in the variables' box
  (an infinite bound is replaced by ±:data:`UNBOUNDED` in the variables' internal units), with the parameter
  ``p = α``: every output of every function IPOPT calls — ``nlp_f`` (objective), ``nlp_g`` (constraints),
  ``nlp_grad_f`` (objective gradient), ``nlp_jac_g`` (constraint Jacobian) and ``nlp_hess_l`` (the Lagrangian's
  Hessian, with seeded multipliers, only where the solver uses the exact Hessian) — as its sparsity pattern and
  its nonzeros' float64 bytes (NaN and infinity hash as their bits).

So a change that moves one bit of what IPOPT sees at those points changes the fingerprint.  It is computed from
the compiled functions themselves (:func:`nlp_fingerprint` takes the ``nlpsol``), so it covers the problem's
code, the transcription, the code generator, the C compiler and its flags.  It does **not** cover IPOPT's own
arithmetic, MUMPS, the BLAS, or the CPU's instruction set beyond what changes the NLP's values: those are the
versions recorded beside it (:func:`environment`: CasADi — whose wheel carries IPOPT, MUMPS and a fixed-kernel
OpenBLAS —, numpy and the kernel its OpenBLAS runs, the CPU model and its flags).  Docs:
``docs/reproducibility.md``.

This module imports only numpy and casadi, never the rest of amorgs: ``amorgs reference-certify --at-commit``
loads it by file path into an older checkout's process to fingerprint that checkout's solver.
"""

from __future__ import annotations

import hashlib
import platform

import numpy as np

#: Points per fingerprint, their seed, and the half-width used for an unbounded variable.
POINTS = 4
SEED = 20261204
UNBOUNDED = 4.0
#: The functions of CasADi's IPOPT interface that are hashed, in this order (those the nlpsol has).
FUNCTIONS = ("nlp_f", "nlp_g", "nlp_grad_f", "nlp_jac_g", "nlp_hess_l")
#: Length of the hex digest kept.
DIGITS = 12


def sample_points(lbw: np.ndarray, ubw: np.ndarray, points: int = POINTS, seed: int = SEED) -> np.ndarray:
    """``points`` vectors uniform in the box [lbw, ubw] (infinite bounds as ±:data:`UNBOUNDED`), shape
    (points, n), drawn with ``default_rng(seed)``."""
    lo = np.where(np.isfinite(lbw), lbw, -UNBOUNDED).astype(float)
    hi = np.where(np.isfinite(ubw), ubw, UNBOUNDED).astype(float)
    return lo + (hi - lo) * np.random.default_rng(seed).random((points, lo.size))


def _update(h, values) -> None:
    import casadi as ca

    m = values if isinstance(values, ca.DM) else ca.DM(values)
    sp = m.sparsity()
    h.update(np.asarray(sp.colind(), np.int64).tobytes())
    h.update(np.asarray(sp.row(), np.int64).tobytes())
    h.update(np.asarray(m.nonzeros(), "<f8").tobytes())


def nlp_fingerprint(nlpsol, bounds: tuple[np.ndarray, ...], alpha: float, points: int = POINTS,
                    seed: int = SEED) -> str:
    """The fingerprint (12 hex digits) of a CasADi IPOPT ``nlpsol`` at parameter ``alpha``; ``bounds`` are
    ``(lbw, ubw)`` or ``(lbw, ubw, lbg, ubg)`` as the solver passes them."""
    lbw, ubw = (np.asarray(b, float).ravel() for b in bounds[:2])
    h = hashlib.sha256(b"amorgs-nlp-fingerprint-1")
    for b in bounds:
        h.update(np.asarray(b, "<f8").ravel().tobytes())
    h.update(np.float64(alpha).tobytes())
    rng = np.random.default_rng(seed + 1)
    for w in sample_points(lbw, ubw, points, seed):
        for name in FUNCTIONS:
            if not nlpsol.has_function(name):
                continue
            f = nlpsol.get_function(name)
            args = {"x": w, "p": float(alpha)}
            for i in range(f.n_in()):  # multipliers of the Hessian of the Lagrangian: seeded too
                n_in = f.name_in(i)
                if n_in not in args:
                    args[n_in] = rng.standard_normal(f.sparsity_in(i).nnz())
            out = f(**{k: v for k, v in args.items() if k in f.name_in()})
            h.update(name.encode())
            for key in f.name_out():
                _update(h, out[key])
    return h.hexdigest()[:DIGITS]


def function_fingerprint(functions, points: np.ndarray, alpha: float) -> str:
    """The fingerprint of a problem solved without an NLP (De Jong's BFGS): the float64 bytes of every
    ``functions[i](x, alpha)`` at each row of ``points``."""
    h = hashlib.sha256(b"amorgs-function-fingerprint-1")
    h.update(np.float64(alpha).tobytes())
    for x in np.asarray(points, float):
        h.update(x.astype("<f8").tobytes())
        for fn in functions:
            h.update(np.asarray(fn(x, alpha), "<f8").ravel().tobytes())
    return h.hexdigest()[:DIGITS]


def cpu_model() -> str:
    """The CPU's model name and a hash of its instruction-set flags (Linux ``/proc/cpuinfo``)."""
    try:
        with open("/proc/cpuinfo") as fh:
            info = fh.read().splitlines()
    except OSError:
        return platform.processor() or platform.machine()
    model = next((line.split(":", 1)[1].strip() for line in info if line.startswith("model name")), "")
    flags = next((line.split(":", 1)[1].strip() for line in info if line.startswith(("flags", "Features"))), "")
    return f"{model}|{hashlib.sha256(flags.encode()).hexdigest()[:16]}"


def blas_core() -> str:
    """The kernel set numpy's OpenBLAS runs (``Haswell``, ``SkylakeX``, …): chosen from the CPU at load time, or
    forced by ``$OPENBLAS_CORETYPE``; ``""`` where threadpoolctl cannot tell.  Code that builds an NLP's constants
    with numpy's BLAS (this project's coast flow before 2026-12-05) gets other bits under another kernel."""
    try:
        from threadpoolctl import threadpool_info
    except ImportError:
        return ""
    for info in threadpool_info():
        if info.get("internal_api") == "openblas" and "numpy" in str(info.get("filepath", "")):
            return str(info.get("architecture") or "")
    return ""


def environment() -> dict[str, str]:
    """What the fingerprint does not cover but the solve depends on: CasADi (its wheel carries IPOPT, MUMPS and
    a fixed-kernel OpenBLAS), numpy and the kernel set of its OpenBLAS, the machine and the CPU (model and
    instruction-set flags)."""
    import casadi as ca

    return {"casadi": ca.__version__, "numpy": np.__version__, "blas": blas_core(), "machine": platform.machine(),
            "cpu": cpu_model()}
