"""The C RK8 step (amorgs.problems.cr3bp.rk8_kernel) against a symbolic reference and CasADi's own AD.

The reference is the SX step the kernel replaced (issue 22): the DOP853 tableau over the CR3BP right-hand side
with the thrust acceleration a_max/(dry + m)·u3 and the mass exact (stage i at m − ṁ·c_i·h).  The kernel must give
the same step (bit for bit: the same operations in the same order) and the same derivatives (to rounding: its
Jacobian comes from a hand-written reverse sweep), also through a chain of steps as the transcription builds it.
"""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest
from scipy.integrate._ivp import dop853_coefficients as dop853

from amorgs.problems.cr3bp import constants as K
from amorgs.problems.cr3bp import rk8_kernel


def reference_step() -> ca.Function:
    """The SX step: (s[6], m, u3[3], a_max, ṁ, h) → s_next[6]."""
    s, m, u = ca.SX.sym("s", 6), ca.SX.sym("m"), ca.SX.sym("u", 3)
    a_max, mdot, h = ca.SX.sym("a"), ca.SX.sym("mdot"), ca.SX.sym("h")

    def rhs(y, mass):
        x, yy, z, vx, vy, vz = ca.vertsplit(y)
        dx1, dx2 = x + K.MU, x - 1 + K.MU
        r1sq, r2sq = dx1**2 + yy**2 + z**2, dx2**2 + yy**2 + z**2
        k1, k2 = (1 - K.MU) / (r1sq * ca.sqrt(r1sq)), K.MU / (r2sq * ca.sqrt(r2sq))
        ta = a_max / (K.DRY_MASS_KG / 1000 + mass)
        return ca.vertcat(vx, vy, vz, x - k1 * dx1 - k2 * dx2 + 2 * vy + ta * u[0],
                          yy - (k1 + k2) * yy - 2 * vx + ta * u[1], -(k1 + k2) * z + ta * u[2])

    a, b, c = dop853.A, dop853.B, dop853.C
    k = []
    for i in range(dop853.N_STAGES):
        si = s + h * sum((a[i, j] * k[j] for j in range(i) if a[i, j] != 0.0), ca.SX.zeros(6))
        k.append(rhs(si, m - mdot * (c[i] * h)))
    s_next = s + h * sum(b[i] * k[i] for i in range(dop853.N_STAGES))
    return ca.Function("reference_step", [s, m, u, a_max, mdot, h], [s_next])


def random_arguments(rng: np.random.Generator, n: int) -> list[list]:
    """Steps anywhere in the Earth–Moon box, forward and backward, some 0.02 DU from the Moon."""
    args = []
    for i in range(n):
        pos = rng.uniform(-1.2, 1.2, 3) if i % 4 else np.array([1 - K.MU, 0.0, 0.0]) + 0.02 * rng.normal(size=3)
        args.append([np.r_[pos, rng.uniform(-2, 2, 3)], rng.uniform(0.0, 0.7), rng.uniform(-1, 1, 3),
                     rng.uniform(0.0, 0.02), rng.uniform(0.0, 0.01), rng.uniform(-0.08, 0.08)])
    return args


def test_the_step_is_the_reference_step_bit_for_bit():
    kernel, reference = rk8_kernel.rk8_step(), reference_step()
    for args in random_arguments(np.random.default_rng(0), 40):
        assert np.array_equal(np.asarray(kernel(*args)), np.asarray(reference(*args)))


def test_the_jacobian_is_the_reference_jacobian():
    kernel, reference = rk8_kernel.rk8_step(), reference_step()
    jac_k, jac_r = kernel.jacobian(), reference.jacobian()
    for args in random_arguments(np.random.default_rng(1), 40):
        out = reference(*args)
        for got, want in zip(jac_k(*args, out), jac_r(*args, out)):
            got, want = np.asarray(got), np.asarray(want)
            assert got.shape == want.shape
            assert np.max(np.abs(got - want)) <= 1e-12 * max(np.max(np.abs(want)), 1.0)


@pytest.mark.parametrize("mode", ["reverse", "forward"])
def test_derivatives_through_a_chain_of_steps_match_casadi_ad(mode):
    """The transcription's pattern: a mapaccum of steps inside an MX graph, differentiated in reverse mode (the
    constraint Jacobian) and in forward mode; CasADi routes both through the kernel's Jacobian."""
    results = []
    for step in (rk8_kernel.rk8_step(), reference_step()):
        s, m, u = ca.MX.sym("s", 6), ca.MX.sym("m"), ca.MX.sym("u", 3)
        a_max, mdot, h = ca.MX.sym("a"), ca.MX.sym("mdot"), ca.MX.sym("h")
        n = 5
        masses = m - mdot * h * ca.DM(np.arange(n)).T
        row = lambda v: ca.repmat(v, 1, n)  # noqa: E731
        end = step.mapaccum(n)(s, masses, row(u), row(a_max), row(mdot), row(h))[:, -1]
        inputs = ca.vertcat(s, m, u, a_max, mdot, h)
        jac = ca.jacobian(end, inputs) if mode == "reverse" else ca.jtimes(end, inputs, ca.DM.ones(13))
        f = ca.Function("f", [s, m, u, a_max, mdot, h], [end, jac])
        results.append([np.asarray(v) for args in random_arguments(np.random.default_rng(3), 12) for v in f(*args)])
    for got, want in zip(*results):
        assert np.max(np.abs(got - want)) <= 1e-11 * max(np.max(np.abs(want)), 1.0)


def test_the_source_is_cached_by_content(tmp_path, monkeypatch):
    """The C file and its library live in the compile cache under a content hash, built once."""
    monkeypatch.setenv("AMORGS_CACHE_DIR", str(tmp_path))
    source, library = rk8_kernel.source_path(), rk8_kernel.library_path()
    assert source.parent == tmp_path and library.parent == tmp_path
    assert source.read_text() == rk8_kernel.c_source()
    stamp = library.stat().st_mtime_ns
    assert rk8_kernel.library_path() == library and library.stat().st_mtime_ns == stamp
