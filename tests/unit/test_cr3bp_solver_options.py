"""CR3BP transcription options and compile cache: α step law, stored-vector clipping (no IPOPT solves).

Validation, defaults and hashes of IpoptOptions: tests/unit/test_solver_options.py.
"""

import dataclasses
import math

import numpy as np

from scipy.integrate import solve_ivp

from amorgs.problems import get_problem
from amorgs.problems.cr3bp.dynamics import ballistic_rhs
from amorgs.problems.cr3bp.transcription import TAU_COAST_MAX, ForwardBackwardTranscription
from amorgs.solvers.fingerprint import cpu_model
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


def test_cartesian_controls_switch_to_spherical_from_their_alpha():
    """``controls_switch_alpha`` resolves per α like the step count: Cartesian below it, the stored layout's
    spherical controls from it on (whose grid, and compiled code, is the spherical solver's own)."""
    both = TranscriptionOptions(controls="cartesian", controls_switch_alpha=0.5)
    assert both.for_alpha(0.1).controls == "cartesian" and both.for_alpha(0.49).controls == "cartesian"
    assert both.for_alpha(0.5) == TranscriptionOptions().for_alpha(0.5)
    assert both.for_alpha(1.0).hash_dict() == TranscriptionOptions().for_alpha(1.0).hash_dict()
    assert both.for_alpha(0.1).controls_switch_alpha == 0.0 and both.for_alpha(0.1).for_alpha(1.0).controls == "cartesian"
    everywhere = TranscriptionOptions(controls="cartesian")
    assert everywhere.for_alpha(1.0).controls == "cartesian"
    try:
        get_problem("cr3bp").transcribe(dataclasses.replace(both.for_alpha(0.1), controls_switch_alpha=0.5))
    except ValueError as exc:
        assert "for_alpha" in str(exc)
    else:
        raise AssertionError("an unresolved controls switch was transcribed")


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
    far inside the 1e-5 verification tolerance, and a coast burns no fuel."""
    problem = get_problem("cr3bp")
    tr = ForwardBackwardTranscription(problem.initial_state, problem.terminal_state,
                                      TranscriptionOptions(coast="interpolant", step_scaling_alpha=0.0))
    assert tr.kc == 1  # one piece per coast
    taus = np.random.default_rng(3).uniform(0.0, TAU_COAST_MAX, 25)
    for kind, start, sign in (("coast_f", problem.initial_state[:6], 1), ("coast_b", problem.terminal_state[:6], -1)):
        for tau in taus:
            ref = solve_ivp(ballistic_rhs, (0.0, sign * tau), start, method="DOP853", rtol=1e-12, atol=1e-12).y[:, -1]
            got = np.asarray(tr.coast_pieces[kind](start, 0.4, np.zeros(4), np.zeros(2), sign * tau)).ravel()
            assert np.max(np.abs(got - ref)) < 1e-9, (kind, tau)
        assert tr._apply(kind, (start, 0.4), np.zeros(4), np.zeros(2), sign * 3.0)[1] == 0.4  # no fuel burnt


def test_cpu_model_is_a_stable_string():
    assert cpu_model() == cpu_model() and isinstance(cpu_model(), str)


def test_cartesian_controls_pose_the_same_problem_as_the_stored_layout():
    """With ``controls='cartesian'`` the NLP's match defects at ``to_internal(x)`` are the stored layout's own
    (the same thrust and fuel flow), the ‖v‖² ≤ 1 inequalities sit on their bound for the unit directions of a
    stored vector, and ``to_stored`` gives back x — azimuth, elevation and throttle."""
    import casadi as ca

    problem = get_problem("cr3bp")
    opts = TranscriptionOptions(coast="rk8", steps_per_segment=2, steps_per_coast=8, step_scaling_alpha=0.0)
    spherical = ForwardBackwardTranscription(problem.initial_state, problem.terminal_state, opts)
    cartesian = ForwardBackwardTranscription(problem.initial_state, problem.terminal_state,
                                             TranscriptionOptions(**{**opts.to_dict(), "controls": "cartesian"}))
    assert cartesian.n_w == 4 + 4 * 20 and cartesian.n_g == 7 + 20 and spherical.n_g == 7
    lbg, ubg = cartesian.constraint_bounds()
    assert np.all(lbg[:7] == 0) and np.all(ubg == 0) and np.all(lbg[7:] == -np.inf)
    lo, hi = cartesian.bounds()
    assert np.all(lo[4:].reshape(20, 4)[:, :3] == -1) and np.all(lo[4:].reshape(20, 4)[:, 3] == 0)
    g = ca.Function("g", [cartesian.nlp["x"], cartesian.nlp["p"]], [cartesian.nlp["g"]])
    for x in problem.sample_uniform(0.3, 3, np.random.default_rng(5)):
        w = cartesian.to_internal(x, 0.3)
        assert np.all(w >= lo) and np.all(w <= hi)
        gw = np.asarray(g(w, 0.3)).ravel()
        np.testing.assert_allclose(gw[:7], spherical.match_defect(x, 0.3), rtol=1e-10, atol=1e-12)
        np.testing.assert_allclose(gw[7:], 0.0, atol=1e-12)
        np.testing.assert_allclose(cartesian.to_stored(w), x, rtol=1e-10, atol=1e-12)
    # A shorter direction stores the thrust it produces: throttle ρ·‖v‖ along v.
    w = cartesian.to_internal(x, 0.3)
    w[4:7] *= 0.5
    stored = cartesian.to_stored(w)
    assert np.isclose(stored[6], 0.5 * x[6]) and np.isclose(stored[4], x[4]) and np.isclose(stored[5], x[5])


def test_the_compile_cache_key_follows_the_nlp_graph_not_only_the_options(tmp_path, monkeypatch):
    """Two NLPs under the same identity (options) but with different expression graphs never share a cached
    library — a code change that changes the NLP cannot load a stale one; the same graph finds the same file."""
    import casadi as ca

    from amorgs.solvers.codegen import compiled_library_path

    monkeypatch.setenv("AMORGS_CACHE_DIR", str(tmp_path))
    x, p = ca.MX.sym("x", 2), ca.MX.sym("p")
    one = {"x": x, "p": p, "f": ca.sumsqr(x), "g": x[0] * p}
    two = {"x": x, "p": p, "f": ca.sumsqr(x), "g": x[0] * p + 1e-12}
    path = lambda nlp: compiled_library_path("toy", nlp, "limited-memory", {"options": "same"}, "-O2")
    assert path(one) == path({**one}) and path(one).parent == tmp_path
    assert path(one) != path(two)


def test_cartesian_to_stored_clips_a_relaxed_solution_into_a_valid_warm_start():
    """IPOPT's bound relaxation leaves v, ρ and ‖v‖ a few 1e-9 outside their bounds: the stored vector is
    still inside the spec's box (ρ·min(‖v‖, 1) clipped to [0, 1]) and a valid warm start."""
    problem = get_problem("cr3bp")
    tr = ForwardBackwardTranscription(problem.initial_state, problem.terminal_state, TranscriptionOptions(
        coast="rk8", steps_per_segment=1, steps_per_coast=8, step_scaling_alpha=0.0, controls="cartesian"))
    x = problem.sample_uniform(1.0, 1, np.random.default_rng(2))[0]
    w = tr.to_internal(x, 1.0)
    controls = w[4:tr.core_size].reshape(-1, 4)
    controls[0, :3] *= 1 + 9e-9          # ‖v‖ just above 1
    controls[1, 3], controls[2, 3] = -9e-9, 1 + 9e-9  # ρ just outside [0, 1]
    controls[3] = [0.0, 0.0, 0.0, 0.4]    # no direction at all
    stored = problem.check_guess(tr.to_stored(w))
    assert np.all(stored >= problem.lower) and np.all(stored <= problem.upper)
    assert stored[6 + 3 * 1] == 0.0 and stored[6 + 3 * 2] == 1.0 and stored[6 + 3 * 3] == 0.0


def test_the_compile_cache_path_is_the_same_in_every_process_and_shared_past_the_switch():
    """The real NLP's graph hash is deterministic across processes (else every worker would recompile), and
    generation 3 at α ≥ its switch compiles to generation 2's library (the same NLP, the same file)."""
    import subprocess
    import sys

    script = (
        "import sys; from amorgs.problems import get_problem; from amorgs.solvers.codegen import compiled_library_path\n"
        "from amorgs.solvers.options import IpoptOptions\n"
        "p = get_problem('cr3bp')\n"
        "for t in ({}, {'controls': 'cartesian', 'controls_switch_alpha': 0.25}):\n"
        "    o = IpoptOptions.from_mapping({'transcription': t}).transcription.for_alpha(0.3)\n"
        "    tr = p.transcribe(o)\n"
        "    print(compiled_library_path('cr3bp', tr.nlp, 'limited-memory', {'transcription': o.hash_dict(), "
        "**p.code_identity()}, '-O2').name)\n"
    )
    runs = [subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, check=True).stdout.split()
            for _ in range(2)]
    assert runs[0] == runs[1] and len(runs[0]) == 2 and runs[0][0] == runs[0][1]
