"""The thrust segments' RK8 step and its Jacobian as C code that CasADi calls (an external function).

One step of the DOP853 8th-order tableau (12 stages) of the CR3BP position and velocity under a constant thrust,
with the fuel mass linear in time and exact (stage i sees m − ṁ·c_i·h; see
:mod:`~amorgs.problems.cr3bp.transcription`)::

    amorgs_rk8_step(s[6] DU, VU; m t; u3 = ρ·û; a_max t·DU/TU²; ṁ t/TU; h TU) → s_next[6]

and ``jac_amorgs_rk8_step``: its Jacobian by blocks, ∂s_next/∂s (6 × 6), ∂s_next/∂m, ∂s_next/∂u3 (6 × 3),
∂s_next/∂a_max, ∂s_next/∂ṁ, ∂s_next/∂h (6 × 1 each), in CasADi's external-function convention (inputs: the six
nominal inputs and the nominal output, which is not read).  The function is made with ``enable_forward`` and
``enable_reverse`` off, so CasADi takes every derivative through this Jacobian: the constraint Jacobian's reverse
sweep multiplies λᵀ·J per step for its six seeds (one per position/velocity defect) instead of sweeping the step
once per seed.

Why hand-written: CasADi's reverse derivative of the symbolic (SX) step sweeps the step once per seed, and
differentiates the divisions and square roots of the gravity terms anew in every sweep (≈ 1.3× the step's
operations per seed; ≈ 70 % of the constraint Jacobian, docs/performance.md).  Here the stages are computed once,
the six rows of J come from one reverse sweep with the seeds e_1 … e_6 as the innermost, contiguous array
dimension (the compiler vectorises every adjoint operation across them), and the gravity Jacobian is applied as
(diag(1, 1, 0) − (k₁+k₂)·I)·λ + q₁·d₁(d₁·λ) + q₂·d₂(d₂·λ), with d_i the offsets from the primaries,
k_i = μ_i/r_i³ and q_i = 3k_i/r_i² — no division per seed.  The step computes what the SX step it replaced
computed, in the same order (bit for bit); tests/unit/test_rk8_kernel.py checks the step and its Jacobian against
an SX reference and CasADi's automatic differentiation.

The C source is generated from scipy's DOP853 tableau and :mod:`.constants` (zero coefficients left out, the
stages unrolled), written once per content into :func:`~amorgs.solvers.codegen.cache_dir`, and compiled there
on its own (:data:`KERNEL_FLAGS`) for CasADi's virtual machine and the transcription's own functions; a compiled
NLP compiles the same source into its library with the solver's flags (``Transcription.c_sources``,
:func:`~amorgs.solvers.codegen.compiled_nlp_library`).
"""

from __future__ import annotations

import functools
import hashlib
import os
import subprocess
import tempfile
from pathlib import Path

import casadi as ca
from scipy.integrate._ivp import dop853_coefficients as dop853

from amorgs.problems.cr3bp import constants as K

SYMBOL = "amorgs_rk8_step"
#: gcc flags of the stand-alone kernel library (the solver's default ``compile_flags``).
KERNEL_FLAGS = "-O3 -march=native -ffp-contract=off"
N_STAGES = dop853.N_STAGES


def _lit(x: float) -> str:
    """A C double literal that reads back as exactly ``x``."""
    return repr(float(x))


def _sparsity(nrow: int, ncol: int, nnz: bool = True) -> list[int]:
    """CasADi's compressed-column sparsity of a dense (or, with ``nnz=False``, empty) nrow × ncol matrix."""
    if not nnz:
        return [nrow, ncol] + [0] * (ncol + 1)
    return [nrow, ncol] + [nrow * j for j in range(ncol + 1)] + list(range(nrow)) * ncol


def _forward_body() -> str:
    """C statements of one step: stages y[i], k[i] (and the adjoint's per-stage data) from s, m, u, a, mdot, h."""
    a, b, c = dop853.A, dop853.B, dop853.C
    out = []
    for i in range(N_STAGES):
        terms = [(j, a[i, j]) for j in range(i) if a[i, j] != 0.0]
        for comp in range(6):
            if terms:
                acc = " + ".join(f"{_lit(aij)} * k[{j}][{comp}]" for j, aij in terms)
                out.append(f"  D[{i}][{comp}] = {acc}; y[{i}][{comp}] = s[{comp}] + h * D[{i}][{comp}];")
            else:
                out.append(f"  D[{i}][{comp}] = 0.0; y[{i}][{comp}] = s[{comp}];")
        out.append(f"  rhs(y[{i}], m - mdot * ({_lit(c[i])} * h), u, amax, k[{i}], st ? &st[{i}] : 0);")
    for comp in range(6):
        acc = " + ".join(f"{_lit(b[i])} * k[{i}][{comp}]" for i in range(N_STAGES) if b[i] != 0.0)
        out.append(f"  S[{comp}] = {acc};")
    return "\n".join(out)


def _adjoint_body() -> str:
    """C statements of the reverse sweep over the stages, every seed loop innermost (``n`` seeds)."""
    a, b, c = dop853.A, dop853.B, dop853.C
    out = []
    for i in range(N_STAGES):  # kb[i] = h·b_i·λ
        for comp in range(6):
            if b[i] != 0.0:
                out.append(f"  for (d = 0; d < n; d++) kb[{i}][{comp}][d] = (h * {_lit(b[i])}) * lam[{comp}][d];")
            else:
                out.append(f"  for (d = 0; d < n; d++) kb[{i}][{comp}][d] = 0.0;")
    for i in reversed(range(N_STAGES)):
        terms = [(j, a[i, j]) for j in range(i) if a[i, j] != 0.0]
        lines = [
            f"    const double bax = kb[{i}][3][d], bay = kb[{i}][4][d], baz = kb[{i}][5][d];",
            f"    const double p1 = st[{i}].d1[0] * bax + st[{i}].d1[1] * bay + st[{i}].d1[2] * baz;",
            f"    const double p2 = st[{i}].d2[0] * bax + st[{i}].d2[1] * bay + st[{i}].d2[2] * baz;",
            f"    const double g1 = st[{i}].q1 * p1, g2 = st[{i}].q2 * p2, ks = st[{i}].ks;",
            f"    const double yb0 = bax - ks * bax + g1 * st[{i}].d1[0] + g2 * st[{i}].d2[0];",
            f"    const double yb1 = bay - ks * bay + g1 * st[{i}].d1[1] + g2 * st[{i}].d2[1];",
            f"    const double yb2 = -ks * baz + g1 * st[{i}].d1[2] + g2 * st[{i}].d2[2];",
            f"    const double yb3 = kb[{i}][0][d] - 2.0 * bay;",
            f"    const double yb4 = kb[{i}][1][d] + 2.0 * bax;",
            f"    const double yb5 = kb[{i}][2][d];",
            "    const double ua = u[0] * bax + u[1] * bay + u[2] * baz;",
            f"    const double bmi = -st[{i}].ta * st[{i}].inv_wet * ua;",
            f"    bu0[d] += st[{i}].ta * bax; bu1[d] += st[{i}].ta * bay; bu2[d] += st[{i}].ta * baz;",
            f"    ba[d] += ua * st[{i}].inv_wet;",
            "    bm[d] += bmi;",
        ]
        if c[i] != 0.0:
            lines += [f"    bmd[d] -= ({_lit(c[i])} * h) * bmi;", f"    bh[d] -= (mdot * {_lit(c[i])}) * bmi;"]
        lines += [f"    bs[{comp}][d] += yb{comp};" for comp in range(6)]
        if terms:
            lines.append("    bh[d] += " + " + ".join(f"D[{i}][{comp}] * yb{comp}" for comp in range(6)) + ";")
            for j, aij in terms:
                lines += [f"    kb[{j}][{comp}][d] += (h * {_lit(aij)}) * yb{comp};" for comp in range(6)]
        out.append(f"  /* stage {i} */\n  for (d = 0; d < n; d++) {{\n" + "\n".join(lines) + "\n  }")
    return "\n".join(out)


@functools.cache
def c_source() -> str:
    """The C source of :data:`SYMBOL` and ``jac_`` :data:`SYMBOL` (CasADi's external-function API)."""
    one_minus_mu = 1 - K.MU
    patterns = {"scalar": _sparsity(1, 1), "vec6": _sparsity(6, 1), "vec3": _sparsity(3, 1),
                "empty6": _sparsity(6, 1, nnz=False), "6x6": _sparsity(6, 6), "6x3": _sparsity(6, 3)}
    arrays = [f"static const casadi_int sp_{name}[] = {{{', '.join(map(str, sp))}}};" for name, sp in patterns.items()]
    newline = "\n"
    return f"""/* Generated by amorgs.problems.cr3bp.rk8_kernel: the DOP853 step of the CR3BP 6-state under
   constant thrust and its Jacobian, as CasADi external functions.  Do not edit. */
#include <math.h>
#ifndef casadi_real
#define casadi_real double
#endif
#ifndef casadi_int
#define casadi_int long long int
#endif
#define MU {_lit(K.MU)}
#define ONE_MINUS_MU {_lit(one_minus_mu)}
#define DRY_T {_lit(K.DRY_MASS_KG / 1000)}
{newline.join(arrays)}

typedef struct {{ double d1[3], d2[3], ks, q1, q2, ta, inv_wet; }} stage_t;

/* (ṙ, v̇) at fuel mass m (t); the gravity and thrust terms the adjoint needs go to *st. */
static inline __attribute__((always_inline)) void rhs(const double* y, double m, const double* u, double amax,
                                                     double* f, stage_t* st) {{
  const double dx1 = y[0] + MU, dx2 = (y[0] - 1.0) + MU;
  const double yy = y[1] * y[1], zz = y[2] * y[2];
  const double r1sq = (dx1 * dx1 + yy) + zz, r2sq = (dx2 * dx2 + yy) + zz;
  const double k1 = ONE_MINUS_MU / (r1sq * sqrt(r1sq)), k2 = MU / (r2sq * sqrt(r2sq));
  const double wet = DRY_T + m, ta = amax / wet;
  f[0] = y[3]; f[1] = y[4]; f[2] = y[5];
  f[3] = (((y[0] - k1 * dx1) - k2 * dx2) + 2.0 * y[4]) + ta * u[0];
  f[4] = ((y[1] - (k1 + k2) * y[1]) - 2.0 * y[3]) + ta * u[1];
  f[5] = -(k1 + k2) * y[2] + ta * u[2];
  if (!st) return;
  st->d1[0] = dx1; st->d1[1] = y[1]; st->d1[2] = y[2];
  st->d2[0] = dx2; st->d2[1] = y[1]; st->d2[2] = y[2];
  st->ks = k1 + k2; st->q1 = 3.0 * k1 / r1sq; st->q2 = 3.0 * k2 / r2sq;
  st->ta = ta; st->inv_wet = 1.0 / wet;
}}

/* One step: stage states y, slopes k, the increments D_i = Σ_j a_ij k_j and S = Σ_i b_i k_i. */
static inline __attribute__((always_inline)) void step(
    const double* s, double m, const double* u, double amax, double mdot, double h,
    double y[{N_STAGES}][6], double k[{N_STAGES}][6], double D[{N_STAGES}][6], double* S, stage_t* st) {{
{_forward_body()}
}}

static inline void load(const casadi_real** arg, double* s, double* m, double* u, double* amax, double* mdot,
                        double* h) {{
  int c;
  for (c = 0; c < 6; c++) s[c] = arg[0] ? arg[0][c] : 0.0;
  for (c = 0; c < 3; c++) u[c] = arg[2] ? arg[2][c] : 0.0;
  *m = arg[1] ? arg[1][0] : 0.0; *amax = arg[3] ? arg[3][0] : 0.0;
  *mdot = arg[4] ? arg[4][0] : 0.0; *h = arg[5] ? arg[5][0] : 0.0;
}}

int {SYMBOL}(const casadi_real** arg, casadi_real** res, casadi_int* iw, casadi_real* w, int mem) {{
  double s[6], u[3], m, amax, mdot, h, y[{N_STAGES}][6], k[{N_STAGES}][6], D[{N_STAGES}][6], S[6];
  int c;
  (void)iw; (void)w; (void)mem;
  load(arg, s, &m, u, &amax, &mdot, &h);
  step(s, m, u, amax, mdot, h, y, k, D, S, 0);
  if (res[0]) for (c = 0; c < 6; c++) res[0][c] = s[c] + h * S[c];
  return 0;
}}
casadi_int {SYMBOL}_n_in(void) {{ return 6; }}
casadi_int {SYMBOL}_n_out(void) {{ return 1; }}
const casadi_int* {SYMBOL}_sparsity_in(casadi_int i) {{ return i == 0 ? sp_vec6 : i == 2 ? sp_vec3 : sp_scalar; }}
const casadi_int* {SYMBOL}_sparsity_out(casadi_int i) {{ (void)i; return sp_vec6; }}
int {SYMBOL}_work(casadi_int* sz_arg, casadi_int* sz_res, casadi_int* sz_iw, casadi_int* sz_w) {{
  *sz_arg = 6; *sz_res = 1; *sz_iw = 0; *sz_w = 0; return 0;
}}

/* One reverse sweep of the step for the six seeds e_r (r = 0…5, the innermost index d):
   bs[c][r] = ∂s_next_r/∂s_c, bm[r] = ∂s_next_r/∂m, bu[c][r] = ∂s_next_r/∂u_c, ba, bmd, bh: ∂s_next_r/∂(a_max, ṁ, h). */
static inline __attribute__((always_inline)) void adjoint(const casadi_real** arg, double bs[6][6], double* bm,
                                                         double bu[3][6], double* ba, double* bmd, double* bh) {{
  const int n = 6;
  double s[6], u[3], m, amax, mdot, h, y[{N_STAGES}][6], k[{N_STAGES}][6], D[{N_STAGES}][6], S[6];
  double lam[6][6], kb[{N_STAGES}][6][6];
  double *bu0 = bu[0], *bu1 = bu[1], *bu2 = bu[2];
  stage_t st[{N_STAGES}];
  int c, d;
  load(arg, s, &m, u, &amax, &mdot, &h);
  step(s, m, u, amax, mdot, h, y, k, D, S, st);
  for (c = 0; c < 6; c++) for (d = 0; d < n; d++) lam[c][d] = c == d ? 1.0 : 0.0;
  for (d = 0; d < n; d++) {{
    bh[d] = S[d];
    bu0[d] = bu1[d] = bu2[d] = bm[d] = ba[d] = bmd[d] = 0.0;
  }}
  for (c = 0; c < 6; c++) for (d = 0; d < n; d++) bs[c][d] = lam[c][d];
{_adjoint_body()}
}}
/* The step's Jacobian, by blocks (CasADi's jac_ convention): ∂s_next/∂s (6 × 6), ∂/∂m, ∂/∂u3 (6 × 3), ∂/∂a_max,
   ∂/∂ṁ, ∂/∂h (6 × 1 each); row r is the adjoint of seed e_r. */
int jac_{SYMBOL}(const casadi_real** arg, casadi_real** res, casadi_int* iw, casadi_real* w, int mem) {{
  double b[6][6], bm[6], bu[3][6], ba[6], bmd[6], bh[6];
  int r, c;
  (void)iw; (void)w; (void)mem;
  adjoint(arg, b, bm, bu, ba, bmd, bh);
  if (res[0]) for (c = 0; c < 6; c++) for (r = 0; r < 6; r++) res[0][6 * c + r] = b[c][r];
  if (res[1]) for (r = 0; r < 6; r++) res[1][r] = bm[r];
  if (res[2]) for (c = 0; c < 3; c++) for (r = 0; r < 6; r++) res[2][6 * c + r] = bu[c][r];
  if (res[3]) for (r = 0; r < 6; r++) res[3][r] = ba[r];
  if (res[4]) for (r = 0; r < 6; r++) res[4][r] = bmd[r];
  if (res[5]) for (r = 0; r < 6; r++) res[5][r] = bh[r];
  return 0;
}}
casadi_int jac_{SYMBOL}_n_in(void) {{ return 7; }}
casadi_int jac_{SYMBOL}_n_out(void) {{ return 6; }}
const casadi_int* jac_{SYMBOL}_sparsity_in(casadi_int i) {{
  return i == 0 ? sp_vec6 : i == 2 ? sp_vec3 : i == 6 ? sp_empty6 : sp_scalar;
}}
const casadi_int* jac_{SYMBOL}_sparsity_out(casadi_int i) {{ return i == 0 ? sp_6x6 : i == 2 ? sp_6x3 : sp_vec6; }}
int jac_{SYMBOL}_work(casadi_int* sz_arg, casadi_int* sz_res, casadi_int* sz_iw, casadi_int* sz_w) {{
  *sz_arg = 7; *sz_res = 6; *sz_iw = 0; *sz_w = 0; return 0;
}}
"""


def _cached_file(key: str, suffix: str, build) -> Path:
    """``cache_dir()/amorgs_rk8_<hash of key><suffix>``, made once by ``build(tmp_path)`` and moved in atomically."""
    from amorgs.solvers.codegen import cache_dir

    target = cache_dir() / f"amorgs_rk8_{hashlib.sha256(key.encode()).hexdigest()[:16]}{suffix}"
    if target.is_file():
        return target
    target.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(prefix="amorgs-rk8-", dir=target.parent) as tmp:
        built = Path(tmp) / target.name
        build(built)
        os.replace(built, target)
    return target


def source_path() -> Path:
    """The C source, written once per content into the compile cache (a compiled NLP compiles it in)."""
    return _cached_file(c_source(), ".c", lambda path: path.write_text(c_source()))


def library_path() -> Path:
    """The kernel compiled on its own (:data:`KERNEL_FLAGS`; the key holds the CPU model for ``-march=native``)."""
    from amorgs.solvers.fingerprint import cpu_model

    source = source_path()

    def build(path: Path) -> None:
        subprocess.run(["gcc", *KERNEL_FLAGS.split(), "-fPIC", "-shared", str(source), "-o", str(path), "-lm"],
                       check=True, capture_output=True)

    return _cached_file(c_source() + KERNEL_FLAGS + cpu_model(), ".so", build)


def rk8_step() -> ca.Function:
    """The step as a CasADi function (s[6], m, u3[3], a_max, ṁ, h) → s_next[6]; derivatives through its Jacobian."""
    return _external(str(library_path()))


@functools.cache
def _external(path: str) -> ca.Function:
    """One CasADi function per library path (the compile cache may move: ``$AMORGS_CACHE_DIR``)."""
    return ca.external(SYMBOL, path, {"enable_forward": False, "enable_reverse": False})
