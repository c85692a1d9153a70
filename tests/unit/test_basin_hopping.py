"""Global search (amorgs.solvers.basin_hopping, amorgs.ablation.global_search): the hop distributions, the
acceptance rule, the search loop on real solves (De Jong's BFGS; one CR3BP search on IPOPT) and the runtime to
target with its bootstrap interval."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest

from amorgs.ablation.global_search import (
    Cell,
    best_known,
    distinct_near_best,
    expected_runtime,
    hit_iterations,
    run_cell,
    runtime_ecdf,
    runtime_to_target,
    strategy_settings,
)
from amorgs.problems import get_problem
from amorgs.solvers.basin_hopping import HOP_DISTRIBUTIONS, STRATEGIES, HopSettings, hop, improves, search
from amorgs.solvers.record import SolveRecord

#: Median of |draw| per distribution (scale-free checks of what each one draws).
MEDIAN_ABS = {"gaussian": 0.6745, "cauchy": 1.0, "uniform": 0.5, "pareto": 2 ** (1 / 1.5) - 1}


@pytest.mark.parametrize("name", sorted(HOP_DISTRIBUTIONS))
def test_every_hop_distribution_draws_what_it_says_and_stays_in_the_box(name):
    rng = np.random.default_rng(0)
    draws = HOP_DISTRIBUTIONS[name](rng, 200_000, 1.5)
    assert np.median(np.abs(draws)) == pytest.approx(MEDIAN_ABS[name], rel=0.02)
    assert abs(np.mean(np.sign(draws))) < 0.01  # symmetric
    lower, upper = np.array([0.0, -1.0, 10.0]), np.array([1.0, 1.0, 20.0])
    settings = HopSettings(distribution=name, scale=0.5)
    x = np.array([0.99, 0.0, 10.0])
    moved = np.array([hop(x, lower, upper, settings, rng) for _ in range(500)])
    assert np.all(moved >= lower) and np.all(moved <= upper) and np.any(moved != x)
    again = hop(x, lower, upper, settings, np.random.default_rng(5))
    np.testing.assert_array_equal(again, hop(x, lower, upper, settings, np.random.default_rng(5)))


def test_hop_settings_refuse_what_they_cannot_do():
    with pytest.raises(ValueError, match="one of pareto"):
        HopSettings(distribution="levy")
    with pytest.raises(ValueError, match="out of range"):
        HopSettings(scale=0.0)
    with pytest.raises(ValueError, match="one of multistart"):
        strategy_settings("annealing", HopSettings())
    assert strategy_settings("multistart", HopSettings(patience=7)).patience == 0
    assert strategy_settings("mbh", HopSettings(patience=7)).patience == 7
    assert set(STRATEGIES) == {"multistart", "mbh", "mbh_warm"}
    assert strategy_settings("mbh_warm", HopSettings(patience=7)).patience == 7


def test_a_hop_of_named_variables_moves_those_alone_and_a_hop_of_all_draws_as_it_always_did():
    """``HopSettings.variables`` picks what a hop moves (the CR3BP's times); without it a hop draws one step per
    component from the generator, as the committed studies' hops were drawn (their certificates re-solve them)."""
    names = ("tau_s", "tau_i", "tau_f", "m_f", "theta_01")
    lower, upper = np.array([0.0, 0.0, 0.0, 0.0, 0.0]), np.array([40.0, 15.0, 15.0, 450.0, 6.3])
    x = np.array([20.0, 7.0, 7.0, 420.0, 3.0])
    times = HopSettings(scale=0.05, variables=("tau_s", "tau_i", "tau_f"))
    movable = times.movable(names)
    assert movable.tolist() == [True, True, True, False, False]
    moved = np.array([hop(x, lower, upper, times, np.random.default_rng(s), movable) for s in range(200)])
    assert np.all(moved[:, 3:] == x[3:]) and np.all(np.any(moved[:, :3] != x[:3], axis=1))
    assert np.all(moved >= lower) and np.all(moved <= upper)
    every = HopSettings(scale=0.05)
    assert every.movable(names) is None and every.movable(None) is None
    step = HOP_DISTRIBUTIONS["pareto"](np.random.default_rng(9), x.size, 1.5)
    np.testing.assert_array_equal(hop(x, lower, upper, every, np.random.default_rng(9)),
                                  np.clip(x + 0.05 * (upper - lower) * step, lower, upper))
    with pytest.raises(ValueError, match="hop variables tau_q: not variables of the problem"):
        HopSettings(variables=("tau_s", "tau_q")).movable(names)
    with pytest.raises(ValueError, match="no variable names"):
        times.movable(None)
    with pytest.raises(ValueError, match="named twice"):
        HopSettings(variables=("tau_s", "tau_s"))
    assert HopSettings(variables=["tau_s"]) == HopSettings(variables=("tau_s",))  # as read back from JSON
    from amorgs.solvers.basin_hopping import Chains  # the designer's chains hop the same way

    chains = Chains(2, times, names)
    chains.incumbents[0] = SolveRecord(status="x", converged=True, solver_success=True, x=x, objective=-420.0)
    guesses, kinds = chains.propose(lambda m: np.tile(lower, (m, 1)), lower, upper, np.random.default_rng(1))
    assert kinds == ["hop", "start"] and np.all(guesses[0][3:] == x[3:]) and np.any(guesses[0][:3] != x[:3])


def test_a_study_says_which_variables_hop_only_where_not_all_do():
    """study.json of a study that hops every variable reads as before hop variables existed (the committed
    references' files); one that hops the times names them, and its settings are checked before any solve."""
    import json
    from pathlib import Path

    from amorgs.ablation.global_study import GlobalStudy
    from amorgs.errors import InputError

    root = Path(__file__).resolve().parents[2]
    committed = json.loads((root / "reference/global-search/alpha=0.160/study.json").read_text())
    assert "variables" not in committed["hops"] and "variables" not in GlobalStudy(alpha=0.16).summary()["hops"]
    assert committed["hops"] == GlobalStudy(alpha=0.16, hops=HopSettings(**committed["hops"])).summary()["hops"]
    times = GlobalStudy(alpha=0.16, hops=HopSettings(variables=("tau_s", "tau_i", "tau_f")))
    assert times.summary()["hops"]["variables"] == ("tau_s", "tau_i", "tau_f")
    times.check()
    with pytest.raises(InputError, match="--hop-variables: hop variables TOF"):
        GlobalStudy(alpha=0.16, hops=HopSettings(variables=("TOF",))).check()


def test_a_cr3bp_search_hopping_only_the_times_keeps_the_controls_of_its_incumbent():
    """A real CR3BP MBH search (α = 1, uniform starts) whose hops move τ_s, τ_i, τ_f only: every hop's guess is its
    run's incumbent — the last solution kept before it — with the same m_f and controls, other times."""
    problem = get_problem("cr3bp")
    solver = problem.make_local_solver({"max_iter": 300})
    cell = Cell(sampler="uniform", strategy="mbh", alpha=1.0, searches=1, budget=1500, seed=3,
                hops=HopSettings(scale=0.02, patience=6, variables=("tau_s", "tau_i", "tau_f")))
    events, solutions = run_cell(cell, problem.sample_uniform, solver, problem.lower, problem.upper,
                                 problem.variable_names)
    guesses = events[[f"guess_{n}" for n in problem.variable_names]].to_numpy()
    found = dict(zip(solutions["event"], solutions[list(problem.variable_names)].to_numpy()))
    hops = 0
    for _, run_events in events.groupby("run"):
        incumbent = None
        for i, row in run_events.iterrows():
            if row["kind"] == "hop":
                hops += 1
                np.testing.assert_array_equal(guesses[i][3:], incumbent[3:])
                assert np.any(guesses[i][:3] != incumbent[:3])
            if row["accepted"]:
                incumbent = found[row["solve"]]
    assert hops >= 1


def _record(objective: float, converged: bool = True) -> SolveRecord:
    return SolveRecord(status="x", converged=converged, solver_success=converged, x=np.zeros(2), objective=objective)


def test_a_hop_is_kept_only_when_feasible_and_better_by_more_than_the_threshold():
    incumbent = _record(-430.0)
    assert improves(_record(-431.0), incumbent, 1e-6)
    assert not improves(_record(-430.0), incumbent, 1e-6)  # equal is not better
    assert not improves(_record(-430.5), incumbent, 1.0)  # better, but by less than the threshold
    assert not improves(_record(-440.0, converged=False), incumbent, 0.0)  # infeasible
    assert not improves(_record(math.nan), None, 0.0)
    assert improves(_record(-400.0), None, 0.0)  # the first feasible one always


def test_searches_on_real_solves_follow_the_strategy_and_the_budget():
    """De Jong's BFGS (milliseconds per solve): multi-start never hops; MBH hops from a feasible incumbent, keeps
    only improvements, restarts after `patience` misses; the best objective never rises; the budget stops it;
    the same seed gives the same trace."""
    problem = get_problem("dejong")
    solver = problem.make_local_solver(None)

    def run(strategy: str, seed: int, budget: int = 600):
        rng = np.random.default_rng(seed)
        starts = iter(problem.sample_uniform(0.3, 1000, np.random.default_rng(seed + 1)))
        settings = strategy_settings(strategy, HopSettings(distribution="cauchy", scale=0.2, patience=3))
        return search(lambda x: solver.solve(x, 0.3), lambda: next(starts, None), problem.lower, problem.upper,
                      settings, budget, rng)

    multi, mbh = run("multistart", 0), run("mbh", 0)
    assert {e["kind"] for e in multi.events} == {"start"}
    kinds = [e["kind"] for e in mbh.events]
    assert "hop" in kinds and kinds[0] == "start"
    for trace in (multi, mbh):
        best = [e["best_objective"] for e in trace.events if not math.isnan(e["best_objective"])]
        assert best and all(b2 <= b1 for b1, b2 in zip(best, best[1:]))
        assert trace.iterations >= 600 and trace.iterations - trace.events[-1]["iterations"] < 600
        assert trace.stop == "budget"
        assert len(trace.solutions) == sum(e["converged"] for e in trace.events)
    # A run ends after exactly `patience` hops in a row that were not kept (the last run: at most that many).
    events = pd.DataFrame(mbh.events)
    last = events["run"].max()
    for run_id, run_events in events.groupby("run"):
        hops = run_events[run_events["kind"] == "hop"]["accepted"].tolist()
        tail = len(hops) - (max(i for i, kept in enumerate(hops) if kept) + 1 if any(hops) else 0)
        feasible_start = bool(run_events["converged"].iloc[0])
        assert tail <= 3 and (run_id == last or tail == (3 if feasible_start else 0))
    accepted_hops = events[(events["kind"] == "hop") & events["accepted"]]
    assert len(accepted_hops) >= 1
    assert [e["objective"] for e in run("mbh", 0).events] == [e["objective"] for e in mbh.events]
    one_start = iter([problem.upper - 1.0])
    exhausted = search(lambda x: solver.solve(x, 0.3), lambda: next(one_start, None), problem.lower, problem.upper,
                       HopSettings(patience=0), 10_000, np.random.default_rng(0))
    assert exhausted.stop == "starts exhausted" and len(exhausted.events) == 1


def test_one_cr3bp_mbh_cell_on_ipopt():
    """A real CR3BP cell (α = 1, two searches, 800 iterations each, uniform starts): events and feasible
    solutions line up, every kept hop improved m_f, and the metrics read it."""
    problem = get_problem("cr3bp")
    solver = problem.make_local_solver({"max_iter": 300})
    cell = Cell(sampler="uniform", strategy="mbh", alpha=1.0, searches=2, budget=800, seed=3,
                hops=HopSettings(scale=0.01, patience=4))
    events, solutions = run_cell(cell, problem.sample_uniform, solver, problem.lower, problem.upper,
                                 problem.variable_names)
    assert (events["options_hash"] == solver.options_hash).all()  # every event says which options solved it
    assert set(events["search"]) == {0, 1} and (events.groupby("search")["cumulative_iterations"].max() >= 800).all()
    assert len(solutions) == int(events["converged"].sum()) >= 1
    np.testing.assert_allclose(solutions["objective"], -solutions["m_f"], rtol=0, atol=1e-9)
    for _, run_events in events.groupby(["search", "run"]):
        kept = run_events[run_events["accepted"]]["objective"].to_numpy()
        assert np.all(np.diff(kept) < 0)  # each kept solution beats the one before it in its run
    best = best_known(solutions["objective"])
    table = runtime_to_target(events, best, deltas=(0.5, 50.0), n_boot=200)
    assert (table.loc[table["delta"] == 50.0, "successes"] >= 1).all()
    near = distinct_near_best(solutions, best, deltas=(50.0,))
    assert int(near["distinct"].iloc[0]) >= 1 and int(near["near_best"].iloc[0]) >= int(near["distinct"].iloc[0])
    # every event records the guess it started from: re-solved, a hop and a start give the recorded result exactly
    guesses = events[[f"guess_{n}" for n in problem.variable_names]].to_numpy()
    assert np.isfinite(guesses).all()
    for kind in ("start", "hop"):
        row = events.index[events["kind"] == kind][-1]
        again = solver.solve(guesses[row], 1.0)
        assert (again.iterations, again.status) == (events.at[row, "iterations"], events.at[row, "status"])
        assert again.objective == events.at[row, "objective"] or not again.converged


def test_runtime_to_target_is_the_expected_runtime_with_a_bootstrap_interval():
    """Three searches of budget 100: search 0 reaches the target at 30, search 1 at 60, search 2 never (it spent
    100): ERT = (30 + 60 + 100) / 2 = 95."""
    rows = []
    for s, trace in enumerate([[(10, -1.0), (30, -5.0), (100, -5.0)], [(60, -4.95), (100, -5.0)],
                               [(50, -2.0), (100, -3.0)]]):
        rows += [{"sampler": "uniform", "strategy": "mbh", "alpha": 1.0, "search": s, "cumulative_iterations": it,
                  "best_objective": b} for it, b in trace]
    events = pd.DataFrame(rows)
    assert list(hit_iterations(events, -4.9)) == [30.0, 60.0, math.inf]
    assert expected_runtime(np.array([30.0, 60.0, math.inf]), np.array([100.0, 100.0, 100.0])) == 95.0
    assert expected_runtime(np.array([math.inf]), np.array([100.0])) == math.inf
    table = runtime_to_target(events, -5.0, deltas=(0.1, 10.0), n_boot=500, seed=1)
    tight = table[table["delta"] == 0.1].iloc[0]
    assert tight["ert"] == 95.0 and tight["successes"] == 2 and tight["success_rate"] == pytest.approx(2 / 3)
    assert tight["ert_lo"] <= 95.0 <= tight["ert_hi"] and tight["median_hit"] == 45.0
    loose = table[table["delta"] == 10.0].iloc[0]
    assert loose["successes"] == 3 and loose["ert"] == pytest.approx((10 + 60 + 50) / 3)
    ecdf = runtime_ecdf(events, -5.0, deltas=(0.1, 10.0))
    assert list(ecdf["iterations"]) == [10, 30, 50, 60, 60] and ecdf["fraction"].iloc[-1] == pytest.approx(5 / 6)
    assert best_known([-1.0, math.nan], [-3.0]) == -3.0 and math.isnan(best_known([math.nan]))


@pytest.mark.parametrize("args, says", [
    (["--samplers", "bogus"], "--samplers: unknown sampler 'bogus'"),
    (["--strategies", "annealing"], "--strategies: strategy 'annealing'"),
    (["--hop", "levy"], "--hop: hop distribution 'levy'"),
    (["--hop-variables", "tau_s", "tau_q"], "--hop-variables: hop variables tau_q: not variables of the problem"),
    (["--samplers", "amorgs"], "--samplers amorgs: a learned sampler needs --models-dir"),
    (["--budget", "0"], "--searches and --budget must be positive"),
    (["--dest", "/proc/x"], "--dest /proc/x: cannot write there"),
    (["--samplers", "nearest_alpha", "--library-alphas", "0.5", "0.123"], "--library-alphas: 0.123 not in data/library"),
    (["--samplers", "nearest_alpha", "--library-alphas", "1.0"], "--library-alphas: holds the searched α 1"),
    (["--samplers", "uniform", "--library-alphas", "0.5"], "--library-alphas: no sampler of uniform draws on the"),
])
def test_the_global_search_command_refuses_bad_input_in_one_line(args, says, tmp_path):
    import subprocess
    import sys

    dest = [] if "--dest" in args else ["--dest", str(tmp_path)]
    out = subprocess.run([sys.executable, "-m", "amorgs", "global-search", "--alpha", "1.0", *dest, *args],
                         capture_output=True, text=True, timeout=120)
    assert out.returncode != 0 and says in out.stderr, out.stderr
    assert len(out.stderr.strip().splitlines()) <= 2
    assert not (tmp_path / ".searches").exists()  # refused before the checkpoint folder is made


def test_the_ert_ratio_to_the_baseline_has_an_interval_that_tells_faster_from_not():
    """Two cells of 20 searches: the fast one reaches the target at 100 iterations every time, the baseline at
    1000 in half of its searches (the other half spend 2000): ERT 100 vs (10·1000 + 10·2000)/10 = 3000."""
    from amorgs.ablation.global_search import ert_ratios

    rows = []
    for s in range(20):
        rows.append({"strategy": "mbh", "sampler": "uniform", "alpha": 1.0, "search": s,
                     "cumulative_iterations": 100, "best_objective": -10.0})
        hit = s % 2 == 0
        rows.append({"strategy": "multistart", "sampler": "uniform", "alpha": 1.0, "search": s,
                     "cumulative_iterations": 1000 if hit else 2000, "best_objective": -10.0 if hit else -1.0})
    table = ert_ratios(pd.DataFrame(rows), -10.0, deltas=(0.5,), n_boot=400).set_index("strategy")
    assert table.loc["mbh", "ratio"] == pytest.approx(100 / 3000)
    assert table.loc["mbh", "ratio_hi"] < 1  # significantly faster
    assert table.loc["multistart", "ratio"] == 1.0 and table.loc["multistart", "ratio_lo"] <= 1 <= table.loc["multistart", "ratio_hi"]


def test_paired_ratios_ask_whether_hopping_pays_and_whether_a_sampler_beats_reuse_under_each_strategy():
    """Four cells of 20 searches (hit at the given iterations every time, budget 1000): hopping ÷ multi-start is
    taken within each sampler, each sampler ÷ reuse within each strategy, and the ratios are those of the ERTs."""
    from amorgs.ablation.global_search import paired_ratios

    hits = {("multistart", "nearest_alpha"): 400, ("mbh", "nearest_alpha"): 800,
            ("multistart", "amorgs"): 200, ("mbh", "amorgs"): 100}
    rows = [{"strategy": t, "sampler": s, "alpha": 0.3, "search": r, "cumulative_iterations": k,
             "best_objective": -10.0} for (t, s), k in hits.items() for r in range(20)]
    table = paired_ratios(pd.DataFrame(rows), -10.0, deltas=(0.5,), n_boot=200)
    got = {(q, t, s): (ratio, hi) for q, t, s, ratio, hi in
           table[["question", "strategy", "sampler", "ratio", "ratio_hi"]].itertuples(index=False)}
    assert set(got) == {("hopping", "mbh", "nearest_alpha"), ("hopping", "mbh", "amorgs"),
                        ("sampler", "multistart", "amorgs"), ("sampler", "mbh", "amorgs")}
    assert got[("hopping", "mbh", "nearest_alpha")][0] == pytest.approx(2.0)
    assert got[("hopping", "mbh", "amorgs")][0] == pytest.approx(0.5)
    assert got[("sampler", "multistart", "amorgs")][0] == pytest.approx(0.5)
    assert got[("sampler", "mbh", "amorgs")] == pytest.approx((0.125, 0.125))  # every search alike: no spread
    assert set(table["baseline"]) == {"multistart × nearest_alpha", "multistart × amorgs", "mbh × nearest_alpha"}


def test_chains_advance_a_round_at_a_time_by_the_search_rule():
    """Three De Jong chains: the first round restarts all from the sampler; a chain with a feasible incumbent hops
    next; `patience` misses in a row restart it; a kept hop resets its misses."""
    from amorgs.solvers.basin_hopping import Chains

    problem = get_problem("dejong")
    solver = problem.make_local_solver(None)
    chains = Chains(3, HopSettings(distribution="gaussian", scale=0.01, patience=2))
    rng = np.random.default_rng(0)
    fresh = lambda m: problem.sample_uniform(0.3, m, rng)  # noqa: E731
    guesses, kinds = chains.propose(fresh, problem.lower, problem.upper, rng)
    assert kinds == ["start"] * 3 and guesses.shape == (3, 2)
    records = [solver.solve(x, 0.3) for x in guesses]
    assert chains.update(records, kinds) == [r.converged for r in records]
    for _ in range(6):
        before = list(chains.misses)
        had = [inc is not None for inc in chains.incumbents]
        guesses, kinds = chains.propose(fresh, problem.lower, problem.upper, rng, size=2)
        assert len(kinds) == 2
        for i, kind in enumerate(kinds):
            assert kind == ("hop" if had[i] and before[i] < 2 else "start")
        kept = chains.update([solver.solve(x, 0.3) for x in guesses], kinds)
        for i, kind in enumerate(kinds):
            if kind == "hop":
                assert chains.misses[i] == (0 if kept[i] else before[i] + 1)


def test_a_hit_beyond_the_budget_does_not_count_and_a_rare_success_widens_the_ratio():
    """Budget 100: a search that reaches the target at 150 (its last solve crossed the budget) failed, and spent
    100.  A cell that succeeds once in 12 against a baseline that never does has no ratio interval; against a
    baseline that succeeds once, the resamples where neither succeeds keep the interval wide."""
    from amorgs.ablation.global_search import ert_ratios

    rows = [{"strategy": "mbh", "sampler": "uniform", "alpha": 1.0, "search": 0, "cumulative_iterations": 150,
             "best_objective": -10.0}]
    events = pd.DataFrame(rows)
    assert list(hit_iterations(events, -9.0, budget=100)) == [math.inf]
    table = runtime_to_target(events, -10.0, deltas=(1.0,), n_boot=50, budget=100)
    assert table["successes"].iloc[0] == 0 and table["ert"].iloc[0] == math.inf
    rows = []
    for s in range(12):
        for strategy in ("mbh", "multistart"):
            hit = s == 0
            rows.append({"strategy": strategy, "sampler": "uniform", "alpha": 1.0, "search": s,
                         "cumulative_iterations": 1000, "best_objective": -10.0 if hit else -1.0})
    ratio = ert_ratios(pd.DataFrame(rows), -10.0, deltas=(0.5,), n_boot=400).set_index("strategy").loc["mbh"]
    assert ratio["ratio"] == 1.0 and ratio["ratio_lo"] == 0.0 and ratio["ratio_hi"] == math.inf


def test_warm_hops_are_re_solved_with_the_warm_options_and_starts_are_not():
    """mbh_warm: the hop solver is the start solver's options with WARM_HOP_IPOPT over its extra IPOPT options
    (typed options, the only form past the config); the search calls it for hops only."""
    from amorgs.solvers.basin_hopping import WARM_HOP_IPOPT, hop_solver_options
    from amorgs.solvers.options import IpoptOptions

    assert hop_solver_options("mbh", IpoptOptions(max_iter=5)) is None
    assert hop_solver_options("multistart", IpoptOptions()) is None
    warm = hop_solver_options("mbh_warm", IpoptOptions(max_iter=5, ipopt_options={"print_level": 0}))
    assert warm.max_iter == 5 and warm.ipopt_options == {"print_level": 0, **WARM_HOP_IPOPT}
    typed = hop_solver_options("mbh_warm", IpoptOptions(max_iter=7))
    assert typed.max_iter == 7 and typed.ipopt_options == WARM_HOP_IPOPT
    problem = get_problem("dejong")
    solver = problem.make_local_solver(None)
    calls = {"start": 0, "hop": 0}

    def counted(kind):
        def solve(x):
            calls[kind] += 1
            return solver.solve(x, 0.3)
        return solve

    starts = iter(problem.sample_uniform(0.3, 100, np.random.default_rng(1)))
    trace = search(counted("start"), lambda: next(starts, None), problem.lower, problem.upper,
                   HopSettings(distribution="cauchy", scale=0.2, patience=3), 300, np.random.default_rng(0),
                   solve_hop=counted("hop"))
    kinds = [e["kind"] for e in trace.events]
    assert calls == {"start": kinds.count("start"), "hop": kinds.count("hop")} and calls["hop"] > 0


def test_a_global_search_is_a_certifiable_reference(tmp_path):
    """`amorgs global-search` leaves a reference that `reference-certify` can check: every event solved with the
    study's options (starts, and plain MBH's hops) is in starts.parquet with its guess, fingerprint and options
    hash, a warm hop (other options) is not; the manifest verifies, and a seeded sample re-solves exactly."""
    import subprocess
    import sys

    from amorgs.certification import certify_reference
    from amorgs.reference import STARTS_FILE, verify_reference

    dest = tmp_path / "gs"
    out = subprocess.run([sys.executable, "-m", "amorgs", "global-search", "--alpha", "1.0", "--samplers", "uniform",
                          "--strategies", "mbh", "mbh_warm", "--searches", "1", "--budget", "900", "--max-iter", "200",
                          "--hop-scale", "0.005", "--patience", "3", "--deltas", "50", "--dest", str(dest)],
                         capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stderr[-2000:]
    events, starts = pd.read_parquet(dest / "events.parquet"), pd.read_parquet(dest / STARTS_FILE)
    warm_hops = (events["strategy"] == "mbh_warm") & (events["kind"] == "hop")
    assert (events["kind"] == "hop").any(), "no hop: the test would not see the options filter"
    assert events["nlp_fingerprint"].str.len().eq(12).all() and events["options_hash"].nunique() == 1 + warm_hops.any()
    assert len(starts) == int((~warm_hops).sum()) and starts["options_hash"].nunique() == 1
    assert f"{int(len(starts))} of {len(events)} events re-solvable" in out.stdout
    assert "global-search: 2/2 searches" in out.stderr and not (dest / ".searches").exists()  # progress, no leftovers
    manifest = verify_reference(dest)
    assert manifest["certifiable"]["events"] == len(starts) and manifest["identity"]["nlp_fingerprints"] == {
        "1": events["nlp_fingerprint"].iloc[0]}
    cert = certify_reference(dest, sample=3, seed=1)
    assert cert["exact"] and cert["sample"] == 3 and cert["route"] == "today"


def test_an_interrupted_study_resumes_from_its_saved_searches_with_the_same_tables(tmp_path):
    """Each finished search is saved at once (dest/.searches); a rerun of the same study solves only the searches
    that are missing and gives the same events bit for bit, and a run with fewer cells keeps theirs; a study of
    other settings or another library, or a folder that does not say whose searches it holds, is refused."""
    from amorgs.ablation.global_study import GlobalStudy, clear_checkpoint, run_study
    from amorgs.errors import InputError
    from amorgs.solvers.options import IpoptOptions

    study = GlobalStudy(alpha=1.0, samplers=("uniform",), strategies=("multistart", "mbh"), searches=2, budget=300,
                        hops=HopSettings(scale=0.005, patience=2), deltas=(50.0,), solver=IpoptOptions(max_iter=150))
    folder = tmp_path / ".searches"
    lines: list[str] = []
    full = run_study(study, checkpoint=folder, report=lines.append)
    saved = sorted(p.name for p in folder.glob("*--*.json"))
    assert saved == ["mbh--uniform--0000.json", "mbh--uniform--0001.json", "multistart--uniform--0000.json",
                     "multistart--uniform--0001.json"]
    assert len(lines) == 4 and lines[-1].startswith("global-search: 4/4 searches")
    (folder / "mbh--uniform--0001.json").unlink()  # as if killed before the last search finished
    lines.clear()
    again = run_study(study, checkpoint=folder, report=lines.append)
    assert lines[0] == f"global-search: 3 of 4 searches resumed from {folder}" and len(lines) == 2
    pd.testing.assert_frame_equal(again["events"], full["events"], check_exact=True)
    pd.testing.assert_frame_equal(again["solutions"], full["solutions"], check_exact=True)
    lines.clear()  # other cells are the same study: the searches of the cells it shares are kept, none solved
    part = run_study(GlobalStudy(**{**study.__dict__, "strategies": ("multistart",)}), checkpoint=folder,
                     report=lines.append)
    assert lines == [f"global-search: 2 of 2 searches resumed from {folder}"]
    pd.testing.assert_frame_equal(part["events"], full["events"][full["events"]["strategy"] == "multistart"]
                                  .reset_index(drop=True), check_exact=True)
    # its tables written, the run clears its own searches and leaves the other cells' for a later run
    assert clear_checkpoint(folder, GlobalStudy(**{**study.__dict__, "strategies": ("multistart",)})) == 2
    assert sorted(p.name for p in folder.glob("*--*.json")) == ["mbh--uniform--0000.json", "mbh--uniform--0001.json"]
    for other in ({"budget": 400}, {"library_dir": str(tmp_path / "another-library")}):  # settings, or the pools
        with pytest.raises(InputError, match=r"\.searches: holds the searches of a study with other settings"):
            run_study(GlobalStudy(**{**study.__dict__, **other}), checkpoint=folder, report=lines.append)
    (folder / "study.json").unlink()
    with pytest.raises(InputError, match=r"holds searches but no study\.json"):
        run_study(study, checkpoint=folder, report=lines.append)


def test_the_reuse_arms_draw_on_the_named_library_alphas_only():
    """A sparse design's study names the library α reuse may see (``--library-alphas``): the pools hold those α
    alone, the study records them (a study that names none records nothing new), and an α the library lacks or the
    searched α itself is refused before any solve, naming the option."""
    from amorgs.ablation.global_study import GlobalStudy, training_high_quality
    from amorgs.errors import InputError

    sparse = GlobalStudy(alpha=0.3, samplers=("nearest_alpha",), library_alphas=(0.1, 0.5, 1.0))
    sparse.check()
    hq, train = training_high_quality(sparse)
    assert train == (0.1, 0.5, 1.0) and sorted(hq["alpha"].round(6).unique()) == [0.1, 0.5, 1.0] and len(hq) > 100
    assert (hq["m_f"] >= sparse.min_final_mass_kg).all() and hq["converged"].all()
    assert sparse.summary()["library_alphas"] == [0.1, 0.5, 1.0]
    assert "library_alphas" not in GlobalStudy(alpha=0.3).summary()
    _, every = training_high_quality(GlobalStudy(alpha=0.3, samplers=("nearest_alpha",)))
    assert 0.3 not in every and {0.1, 0.2, 0.4, 0.5, 1.0} <= set(every)
    with pytest.raises(InputError, match=r"--library-alphas: 0\.123 not in data/library \(it holds α 0\.1, "):
        training_high_quality(GlobalStudy(alpha=0.3, samplers=("nearest_alpha",), library_alphas=(0.1, 0.123)))
    with pytest.raises(InputError, match=r"--library-alphas: holds the searched α 0\.3"):
        GlobalStudy(alpha=0.3, samplers=("nearest_alpha",), library_alphas=(0.3, 0.5)).check()


def test_a_multistart_from_the_selector_is_solved_once_for_every_seed(tmp_path, tiny_models_dir):
    """The selector's guesses are its ranking whatever the seed, and a multi-start never hops: every search is
    search 0, so the study (and the workflow's cell) solves it once, says so, and its tables equal the searches
    solved one by one."""
    from amorgs.ablation.global_search import run_cell, run_search
    from amorgs.ablation.global_study import GlobalStudy, _init_worker, _WORKER, run_study, training_high_quality
    from amorgs.solvers.options import IpoptOptions

    study = GlobalStudy(alpha=1.0, samplers=("selector",), strategies=("multistart", "mbh"), searches=3, budget=600,
                        hops=HopSettings(scale=0.005, patience=1), deltas=(50.0,), solver=IpoptOptions(max_iter=300),
                        models_dir=str(tiny_models_dir))
    lines: list[str] = []
    tables = run_study(study, checkpoint=tmp_path / ".searches", report=lines.append)
    assert lines[0].startswith("global-search: multistart × selector starts every search from the same guesses")
    assert len(lines) == 5 and lines[-1].startswith("global-search: 4/4 searches")  # hopping draws its hops: 3
    assert sorted(p.name for p in (tmp_path / ".searches").glob("*--*.json")) == [
        "mbh--selector--0000.json", "mbh--selector--0001.json", "mbh--selector--0002.json",
        "multistart--selector--0000.json"]
    multistart, mbh = study.cells()
    events, solutions = (tables[k][tables[k]["strategy"] == "multistart"].reset_index(drop=True)
                         for k in ("events", "solutions"))
    assert sorted(events["search"].unique()) == sorted(solutions["search"].unique()) == [0, 1, 2]
    _init_worker(study, *training_high_quality(study))
    try:
        p, sample = _WORKER["problem"], _WORKER["samplers"]["selector"].sample
        for r in (1, 2):  # solved, not copied: the same rows
            solved = [pd.DataFrame(t) for t in run_search(multistart, r, sample, _WORKER["solver"], p.lower, p.upper,
                                                          p.variable_names)]
            for table, alone in zip((events, solutions), solved):
                pd.testing.assert_frame_equal(table[table["search"] == r].reset_index(drop=True), alone,
                                              check_exact=True)
        alone = run_cell(multistart, sample, _WORKER["solver"], p.lower, p.upper, p.variable_names)
        for table, cell_table in zip((events, solutions), alone):  # the workflow's cell: the same shortcut
            pd.testing.assert_frame_equal(cell_table, table, check_exact=True)
    finally:
        _WORKER.clear()


def test_a_study_split_over_sessions_extends_its_finished_cells_to_the_tables_of_one_run(tmp_path):
    """``amorgs global-search --extend``: a finished study of some cells, extended with more, solves only the new
    cells' searches and writes the tables of a study that ran them all at once (the same events, solutions and
    ratios, bit for bit); a study.json records the inputs it drew on; a study of other settings, one that drops a
    held cell or a folder without a finished study is refused in one line, naming what differs."""
    import json
    import subprocess
    import sys

    def search(dest, *args):
        cmd = [sys.executable, "-m", "amorgs", "global-search", "--alpha", "1.0", "--strategies", "multistart",
               "--searches", "2", "--budget", "300", "--max-iter", "150", "--deltas", "50", "--dest", str(dest), *args]
        return subprocess.run(cmd, capture_output=True, text=True, timeout=600)

    both = ["--samplers", "uniform", "nearest_alpha"]
    assert search(tmp_path / "once", *both).returncode == 0
    assert search(tmp_path / "split", "--samplers", "uniform").returncode == 0
    out = search(tmp_path / "split", *both, "--extend")
    assert out.returncode == 0, out.stderr
    assert "global-search: 2 of 4 searches kept from the finished study" in out.stderr
    assert sum("searches (multistart × uniform" in line for line in out.stderr.splitlines()) == 0  # none solved
    for name in ("events.parquet", "solutions.parquet"):
        pd.testing.assert_frame_equal(pd.read_parquet(tmp_path / "split" / name),
                                      pd.read_parquet(tmp_path / "once" / name), check_exact=True)
    for name in ("runtime_to_target.csv", "ert_ratios.csv", "ert_pairs.csv", "distinct.csv", "study.json"):
        assert (tmp_path / "split" / name).read_text() == (tmp_path / "once" / name).read_text(), name
    study = json.loads((tmp_path / "once" / "study.json").read_text())
    assert set(study["inputs"]) == {"library_manifest_sha256", "models_sha256"}
    assert study["inputs"]["models_sha256"] == {}
    for args, says in [([*both, "--budget", "400"], "its study.json differs in budget (only the cells may change)"),
                       (["--samplers", "nearest_alpha"], "holds the cells multistart × uniform, which"),
                       ([*both, "--dest", str(tmp_path / "empty")],
                        "no events.parquet, solutions.parquet, study.json")]:
        refused = search(tmp_path / "split", *args, "--extend")
        assert refused.returncode != 0 and says in refused.stderr, refused.stderr
        assert len(refused.stderr.strip().splitlines()) <= 2


def test_an_extension_that_adds_the_library_samplers_may_name_the_library_alphas(tmp_path):
    """A study whose first cells draw on no library (``--library-alphas`` is refused there) is extended by
    reuse cells that name a sparse design's α: accepted; a held study whose reuse drew on every library α is not
    extended by one that names other α."""
    import json

    from amorgs.ablation.global_study import GlobalStudy, finished_searches, inputs_identity
    from amorgs.errors import InputError

    first = GlobalStudy(alpha=1.0, samplers=("uniform",), strategies=("multistart",), searches=1)
    row = {"sampler": "uniform", "strategy": "multistart", "alpha": 1.0, "search": 0, "solve": 0, "iterations": 5}
    pd.DataFrame([row]).to_parquet(tmp_path / "events.parquet")
    pd.DataFrame().to_parquet(tmp_path / "solutions.parquet")
    (tmp_path / "study.json").write_text(json.dumps({**first.summary(), "inputs": inputs_identity(first)}))
    later = GlobalStudy(alpha=1.0, samplers=("uniform", "nearest_alpha"), strategies=("multistart",), searches=1,
                        library_alphas=(0.5, 0.8))
    kept = finished_searches(tmp_path, later)
    assert list(kept) == [("multistart", "uniform", 0)] and kept[("multistart", "uniform", 0)][1] == []
    held = GlobalStudy(alpha=1.0, samplers=("uniform", "nearest_alpha"), strategies=("multistart",), searches=1)
    (tmp_path / "study.json").write_text(json.dumps({**held.summary(), "inputs": inputs_identity(held)}))
    with pytest.raises(InputError, match=r"its study\.json differs in library_alphas"):
        finished_searches(tmp_path, later)
