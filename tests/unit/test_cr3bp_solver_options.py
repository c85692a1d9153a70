"""CR3BP transcription options and compile cache: α step law, stored-vector clipping (no IPOPT solves).

Validation, defaults and hashes of IpoptOptions: tests/unit/test_solver_options.py.
"""

import math

import numpy as np

from scipy.integrate import solve_ivp

from amorgs.problems import get_problem
from amorgs.problems.cr3bp.dynamics import ballistic_rhs
from amorgs.problems.cr3bp.transcription import TAU_COAST_MAX, ForwardBackwardTranscription
from amorgs.solvers.codegen import cpu_identity
from amorgs.solvers.options import IpoptOptions, TranscriptionOptions


def test_defaults_keep_bit_identical_flags_and_no_abort():
    base = IpoptOptions()
    assert base.stall_window == 0 and 0 < base.stall_factor <= 1
    assert "-ffp-contract=off" in base.compile_flags and base.compile == "cache"


def test_step_law_up_and_optionally_down():
    up_only = TranscriptionOptions(steps_per_segment=24, step_scaling_alpha=0.3)
    assert up_only.for_alpha(0.1).steps_per_segment == 42
    assert up_only.for_alpha(1.0).steps_per_segment == 24
    both = TranscriptionOptions(steps_per_segment=24, step_scaling_alpha=0.3, scale_down=True, min_steps_per_segment=16)
    assert both.for_alpha(0.1).steps_per_segment == 42
    assert both.for_alpha(0.5).steps_per_segment == math.ceil(24 * math.sqrt(0.3 / 0.5))  # 19
    assert both.for_alpha(1.0).steps_per_segment == 16  # 14 from the law, raised to the floor
    resolved = both.for_alpha(1.0)
    assert resolved.step_scaling_alpha == 0.0 and not resolved.scale_down
    assert resolved.for_alpha(0.1) == resolved  # resolving twice is a no-op


def test_to_stored_clips_times_and_mass_into_the_box():
    problem = get_problem("cr3bp")
    tr = ForwardBackwardTranscription(
        problem.initial_state, problem.terminal_state,
        TranscriptionOptions(coast="rk8", steps_per_segment=1, steps_per_coast=8, step_scaling_alpha=0.0),
    )
    x = problem.sample_uniform(1.0, 1, np.random.default_rng(0))[0]
    w = tr.to_internal(x, 1.0)
    lo, hi = tr.bounds()
    # IPOPT's bound relaxation: a few 1e-9 outside the box on every bounded core variable.
    w_low, w_high = w.copy(), w.copy()
    w_low[:4] = lo[:4] - 9e-9
    w_high[:4] = hi[:4] + 9e-9
    w_low[6::3], w_high[6::3] = -9e-9, 1 + 9e-9
    for v in (w_low, w_high):
        stored = tr.to_stored(v)
        assert np.all(stored >= problem.lower) and np.all(stored <= problem.upper)
        problem.check_guess(stored)  # a valid warm start
    np.testing.assert_array_equal(tr.to_stored(w_low)[:4], problem.lower[:4])
    np.testing.assert_array_equal(tr.to_stored(w_high)[:4], problem.upper[:4])
    # Inside the box nothing changes (round trip of an interior point).
    np.testing.assert_allclose(tr.to_stored(w), x, rtol=1e-12, atol=1e-12)


def test_interpolated_coasts_follow_the_ballistic_flow_to_1e_9():
    """The B-spline coasts against an independent DOP853 (rtol 1e-12) at random durations, both directions:
    far inside the 1e-5 verification tolerance, and the fuel mass passes through unchanged."""
    problem = get_problem("cr3bp")
    tr = ForwardBackwardTranscription(problem.initial_state, problem.terminal_state,
                                      TranscriptionOptions(coast="interpolant", step_scaling_alpha=0.0))
    assert tr.kc == 1  # one piece per coast
    taus = np.random.default_rng(3).uniform(0.0, TAU_COAST_MAX, 25)
    for kind, start, sign in (("coast_f", problem.initial_state[:6], 1), ("coast_b", problem.terminal_state[:6], -1)):
        s0 = np.r_[start, 0.4]
        for tau in taus:
            ref = solve_ivp(ballistic_rhs, (0.0, sign * tau), start, method="DOP853", rtol=1e-12, atol=1e-12).y[:, -1]
            got = np.asarray(tr.coast_pieces[kind](s0, np.zeros(4), np.zeros(2), sign * tau)).ravel()
            assert np.max(np.abs(got[:6] - ref)) < 1e-9, (kind, tau)
            assert got[6] == 0.4


def test_cpu_identity_is_a_stable_string():
    assert cpu_identity() == cpu_identity() and isinstance(cpu_identity(), str)
