"""`amorgs design` end to end (issue 12): real solves at α = 0.42 warm-started from the shipped library, the
written files, the OEM read back with the `oem` package and compared with `propagate`, the verification of
every stored solution, the MLflow run, determinism across worker counts, and the one-line errors."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from processes import session_left_after, session_pids

REPO = Path(__file__).resolve().parents[2]
ALPHA = 0.42
SEED = 1


def amorgs(*args: str, timeout: float = 900) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "amorgs", *args], cwd=REPO, capture_output=True, text=True,
                          timeout=timeout)


@pytest.fixture(scope="module")
def designed(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("design")
    out, store = tmp / "out", tmp / "mlflow"
    proc = amorgs("design", "--alpha", str(ALPHA), "-n", "2", "--round-size", "4", "--max-starts", "12",
                  "--workers", "2", "--seed", str(SEED), "--output", str(out), "--mlflow-dir", str(store))
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert "Traceback" not in proc.stderr
    return {"out": out, "store": store, "proc": proc}


@pytest.mark.slow
def test_design_writes_every_file(designed):
    out = designed["out"]
    for name in ("solutions.parquet", "solutions.csv", "all_solves.parquet", "summary.json", "README.txt",
                 "trajectories.png"):
        assert (out / name).stat().st_size > 0, name
    selected = pd.read_parquet(out / "solutions.parquet")
    assert list(selected["rank"]) == [1, 2]
    assert selected["converged"].all() and (selected["m_f"] >= 415.0).all()
    assert selected["m_f"].is_monotonic_decreasing
    csv = pd.read_csv(out / "solutions.csv")
    np.testing.assert_allclose(csv["m_f"], selected["m_f"], rtol=1e-12)
    for rank in (1, 2):
        history = pd.read_csv(out / "trajectories" / f"rank-{rank:02d}.csv")
        assert {"t_tu", "epoch_tdb", "x_du", "x_rot_km", "x_emi_km", "vz_emi_km_s", "fuel_kg", "mass_kg",
                "throttle", "thrust_n", "ux_rot", "ux_emi"} <= set(history.columns)
        assert history["t_tu"].is_monotonic_increasing
        assert (history["throttle"].between(0, 1)).all()
        assert (history.loc[history["segment"] == 0, "throttle"] == 0).all()
        np.testing.assert_allclose(history["mass_kg"] - history["fuel_kg"], 300.0)
        thrusting = history["segment"] > 0
        norms = np.linalg.norm(history.loc[thrusting, ["ux_emi", "uy_emi", "uz_emi"]].to_numpy(), axis=1)
        np.testing.assert_allclose(norms, 1.0, atol=1e-12)
    summary = json.loads((out / "summary.json").read_text())
    assert summary["found"] >= 2 and summary["returned"] == 2 and summary["stop_reason"] == "found"
    assert summary["nearest_training_alpha"] == 0.4 and summary["sampler"] == "nearest_alpha"  # the library has α = 0.4
    assert summary["starts"] <= 12
    print(f"\ndesign α={ALPHA} n=2: starts {summary['starts']}, found {summary['found']}, CPU {summary['cpu_s']:.1f} s, "
          f"solver CPU {summary['solver_cpu_s']:.1f} s, wall {summary['wall_s']:.1f} s")


@pytest.mark.slow
def test_oem_read_back_matches_propagate_and_solutions_verify(designed):
    from astropy.time import Time
    from oem import OrbitEphemerisMessage

    from amorgs.config import load_config
    from amorgs.problems import get_problem
    from amorgs.problems.cr3bp import frames
    from amorgs.problems.cr3bp.propagation import independent_defect, propagate

    problem = get_problem("cr3bp")
    names = list(problem.variable_names)
    selected = pd.read_parquet(designed["out"] / "solutions.parquet")
    verify_tol = load_config(REPO / "config/default.yaml").problems.cr3bp.solver.verify_tol
    for _, row in selected.iterrows():
        x = row[names].to_numpy(dtype=float)
        assert independent_defect(x, ALPHA, problem.initial_state, problem.terminal_state) <= verify_tol

        message = OrbitEphemerisMessage.open(str(designed["out"] / "trajectories" / f"rank-{int(row['rank']):02d}.oem"))
        (segment,) = list(message)
        assert segment.metadata["REF_FRAME"] == frames.INERTIAL_FRAME_NAME
        assert segment.metadata["CENTER_NAME"] == "EARTH" and segment.metadata["TIME_SYSTEM"] == "TDB"
        states = message.states
        t_oem = frames.tu_after_epoch(Time([s.epoch for s in states]))
        emi_km = np.array([np.r_[s.position, s.velocity] for s in states])
        rot = frames.inertial_to_rotating(t_oem, frames.from_km(emi_km))

        traj = propagate(x, ALPHA, problem.initial_state, problem.terminal_state)
        first = np.r_[True, np.diff(traj.t) > 0]  # the OEM keeps the first sample of a repeated epoch
        # an epoch that appears twice is the match point: forward and backward arcs meet there and differ by
        # the match defect (≤ the verification tolerance), so it is checked against that bound only
        repeated = np.abs(traj.t - traj.match_time) < 1e-9
        t_ref, s_ref = traj.t[first], traj.states[:6, first].T
        idx = np.searchsorted(t_oem, t_ref - 1e-9)
        assert np.all(np.abs(t_oem[idx] - t_ref) * frames.TU_S < 1e-6), "every propagate epoch is in the OEM (to 1 µs)"
        err = np.abs(rot[idx] - s_ref)
        smooth = ~repeated[first]
        pos_err_km = err[smooth, :3].max() * frames.DU_KM
        vel_err_km_s = err[smooth, 3:].max() * frames.VU_KM_S
        assert pos_err_km < 1e-3, pos_err_km
        assert vel_err_km_s < 1e-8, vel_err_km_s
        assert err[~smooth].max(initial=0.0) <= verify_tol
        # the OEM also agrees with the CSV history at its own epochs (same frame, km)
        history = pd.read_csv(designed["out"] / "trajectories" / f"rank-{int(row['rank']):02d}.csv")
        assert len(states) <= len(history) and t_oem[-1] == pytest.approx(history["t_tu"].iloc[-1], abs=1e-11)


@pytest.mark.slow
def test_design_returns_the_best_known_trajectory_with_its_provenance(designed):
    """The best-known record holds α = 0.42's best known m_f (a trajectory lifted from another α; 12 starts do not
    reach it): the design writes it — best_known.csv, the vector at α that the independent check passes, with
    its provenance; what every returned solution is measured from; its history and OEM — and says so."""
    from amorgs.data import best_known as bk
    from amorgs.problems import get_problem

    out = designed["out"]
    summary = json.loads((out / "summary.json").read_text())
    expected = bk.best_entry_lifted(bk.read_record(REPO / bk.DEFAULT_PATH), ALPHA)
    assert summary["best_known_source"] == "best-known record"
    assert summary["best_known_m_f_kg"] == pytest.approx(expected["m_f_kg"], abs=1e-9)
    row = pd.read_csv(out / "best_known.csv").iloc[0]
    x = row[list(get_problem("cr3bp").variable_names)].to_numpy(float)
    np.testing.assert_allclose(x, expected["x"], rtol=1e-15, atol=0)
    assert bk.verify(x, ALPHA) <= 1e-5 and row["m_f"] == pytest.approx(summary["best_known_m_f_kg"], abs=1e-9)
    assert row["from_alpha"] == expected["source"]["from_alpha"] != ALPHA and row["where"] == expected["source"]["where"]
    selected = pd.read_parquet(out / "solutions.parquet")
    np.testing.assert_allclose(selected["below_best_known_kg"], row["m_f"] - selected["m_f"], atol=1e-9)
    assert (selected["below_best_known_kg"] > 0).all()
    history = pd.read_csv(out / "trajectories" / "best-known.csv")
    assert history["t_tu"].is_monotonic_increasing and history["fuel_kg"].iloc[-1] == pytest.approx(row["m_f"], abs=1e-6)
    assert (out / "trajectories" / "best-known.oem").stat().st_size > 0
    assert summary["best_known_trajectory"]["source"] == expected["source"]
    assert "best known trajectory" in designed["proc"].stdout and "best_known.csv" in (out / "README.txt").read_text()


@pytest.mark.slow
def test_design_is_one_mlflow_run_with_metrics_and_artifacts(designed):
    from mlflow.tracking import MlflowClient

    from amorgs import tracking

    client = MlflowClient(tracking.tracking_uri(designed["store"]))
    exp = client.get_experiment_by_name("amorgs-design")
    runs = client.search_runs([exp.experiment_id], filter_string="tags.rule = 'design'")
    assert len(runs) == 1
    assert len(client.search_runs([exp.experiment_id])) == 1  # one run per call, no parent
    assert runs[0].data.tags["git_commit"] and "version.casadi" in runs[0].data.tags
    run = runs[0]
    assert run.info.status == "FINISHED"
    assert run.data.metrics["found"] >= 2 and run.data.metrics["complete"] == 1.0
    assert {"starts", "cpu_s", "wall_s", "solver_cpu_s"} <= set(run.data.metrics)
    assert run.data.params["alpha"] == str(ALPHA) and run.data.params["sampler"] == "nearest_alpha"
    artifacts = {a.path for kind in ("tables", "figures", "reports", "trajectories")
                 for a in client.list_artifacts(run.info.run_id, kind)}
    assert {"tables/solutions.parquet", "figures/trajectories.png", "trajectories/rank-01.oem"} <= artifacts


@pytest.mark.slow
def test_same_seed_same_solutions_with_one_worker(designed):
    """Determinism: the in-process search with 1 worker reproduces the CLI's 2-worker table."""
    from amorgs.design import DesignRequest, design

    with pytest.MonkeyPatch.context() as mp:
        mp.chdir(REPO)
        result = design(DesignRequest(alpha=ALPHA, n=2, round_size=4, max_starts=12, workers=1, seed=SEED))
    cli = pd.read_parquet(designed["out"] / "all_solves.parquet")
    cols = ["start", "status", "converged", "iterations", "m_f", "tau_s", "tau_i", "tau_f", "theta_05", "rho_20"]
    pd.testing.assert_frame_equal(result.solves[cols].reset_index(drop=True), cli[cols], check_exact=False, rtol=1e-12)
    assert list(result.selected["start"]) == list(pd.read_parquet(designed["out"] / "solutions.parquet")["start"])


def test_basin_hopping_spends_its_budget_and_says_how_far_from_the_best_known(tmp_path):
    """`--strategy mbh`: chains hop from their best solutions (kind 'hop'), the whole budget is spent though n were
    found in the first round, a kept hop improved its chain, and every returned solution says how far below the
    best known m_f at α it is (≥ 0); the same seed gives the same solves with one worker."""
    from amorgs.design import DesignRequest, design

    request = DesignRequest(alpha=ALPHA, n=2, round_size=4, max_starts=16, workers=1, seed=SEED, strategy="mbh",
                            patience=2)
    with pytest.MonkeyPatch.context() as mp:
        mp.chdir(REPO)
        result, again = design(request), design(request)
    solves = result.solves
    assert result.starts == 16 and result.stop_reason == "max_starts"
    assert set(solves["kind"]) == {"start", "hop"} and (solves["kind"].iloc[:4] == "start").all()
    assert (result.selected["below_best_known_kg"] >= 0).all() and result.info["best_known_m_f_kg"] >= solves.loc[
        solves["converged"], "m_f"].max()
    pd.testing.assert_frame_equal(result.solves[["kind", "iterations", "m_f"]], again.solves[["kind", "iterations", "m_f"]])


@pytest.mark.parametrize(
    "args, names",
    [
        (["--alpha", "0.05", "-n", "3"], "--alpha"),
        (["--alpha", "0.42", "-n", "0"], "-n"),
        (["--alpha", "0.42", "-n", "3", "--max-starts", "0"], "--max-starts"),
        (["--alpha", "0.42", "-n", "3", "--max-cpu-s", "-5"], "--max-cpu-s"),
        (["--alpha", "0.42", "-n", "3", "--library-dir", "no/such/library"], "no/such/library/cr3bp/provenance.json"),
        (["--alpha", "0.42", "-n", "3", "--sampler", "amorgs", "--models-dir", "no/such/models"], "no/such/models/"),
        (["--alpha", "0.42", "-n", "3", "--beta", "1e6", "--max-starts", "1"], "--beta 1e+06: above the largest final mass"),
        (["--alpha", "0.42", "-n", "3", "--beta", "452", "--max-starts", "1"], "m_f ≤ 451.9 kg"),
        (["--alpha", "0.42", "-n", "3", "--seed", "-1", "--max-starts", "1"], "--seed -1"),
        # issue 39: a frontier file named but missing, an output inside the library, an arm without shipped models
        (["--alpha", "0.42", "-n", "3", "--frontier", "nope.csv"], "--frontier nope.csv: no such file"),
        (["--alpha", "0.42", "-n", "3", "--output", "data/library/cr3bp/x"], "inside the solution library"),
        (["--alpha", "0.42", "-n", "3", "--sampler", "reuse_cvae"], "reuse_cvae.pt: model checkpoint not found"),
        # issue 41: the basin-hopping strategy's settings
        (["--alpha", "0.42", "-n", "3", "--strategy", "mbh", "--hop", "levy"], "--hop/--hop-scale"),
        (["--alpha", "0.42", "-n", "3", "--strategy", "mbh", "--hop-scale", "0"], "--hop/--hop-scale"),
        (["--alpha", "0.42", "-n", "3", "--strategy", "mbh", "--hop-variables", "tau_q"], "--hop-variables: hop vari"),
    ],
)
def test_bad_input_is_one_line_without_traceback(args, names, tmp_path):
    output = [] if "--output" in args else ["--output", str(tmp_path / "out")]
    proc = amorgs("design", *args, *output, "--no-mlflow", timeout=300)
    assert proc.returncode not in (0, 3)
    assert "Traceback" not in proc.stderr
    lines = [line for line in proc.stderr.splitlines() if line.strip()]
    assert len(lines) == 1, proc.stderr
    assert lines[0].startswith("amorgs design:") and names in lines[0], lines[0]
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("where", ["below a file", "a file"])
def test_an_unwritable_output_folder_is_one_line_before_any_solve(where, tmp_path):
    """`--output <unwritable>` used to solve for minutes, then end in a 36-line traceback."""
    blocker = tmp_path / "blocker"
    blocker.write_text("a file, not a folder")
    out = blocker / "design" if where == "below a file" else blocker
    proc = amorgs("design", "--alpha", "0.42", "-n", "1", "--max-starts", "1", "--output", str(out), "--no-mlflow",
                  timeout=120)
    assert proc.returncode == 1 and "Traceback" not in proc.stderr
    lines = [line for line in proc.stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and lines[0].startswith(f"amorgs design: {out}"), proc.stderr
    assert blocker.read_text() == "a file, not a folder"


@pytest.mark.slow
@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="reads the process table from /proc")
def test_ctrl_c_ends_design_with_one_line_and_no_process_left(tmp_path):
    """Ctrl-C used to print a 26-line KeyboardInterrupt traceback."""
    import os
    import signal
    import time

    proc = subprocess.Popen(
        [sys.executable, "-m", "amorgs", "design", "--alpha", str(ALPHA), "-n", "50", "--workers", "2", "--quiet",
         "--output", str(tmp_path / "out"), "--no-mlflow"],
        cwd=REPO, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True,
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),  # as in a terminal
    )
    try:
        deadline = time.monotonic() + 300
        while len(session_pids(proc.pid)) < 3:  # the command and its two solver workers: solving has begun
            assert proc.poll() is None, proc.stderr.read()
            assert time.monotonic() < deadline, "no solver worker started"
            time.sleep(0.2)
        time.sleep(2)
        os.killpg(proc.pid, signal.SIGINT)  # Ctrl-C: the terminal signals the foreground process group
        _, err = proc.communicate(timeout=60)
        left = session_left_after(proc.pid)  # before the clean-up below, which would hide a survivor
    finally:
        for pid in session_pids(proc.pid):
            os.kill(pid, signal.SIGKILL)
    assert proc.returncode == 130
    assert [line for line in err.splitlines() if line.strip()] == ["amorgs design: interrupted"], err
    assert left == [], f"processes of the interrupted design still alive 10 s after it ended: {left}"


def test_an_unlisted_library_file_stops_design_naming_it(tmp_path):
    import shutil

    from amorgs.design import library_high_quality
    from amorgs.errors import InputError

    lib = tmp_path / "library"
    shutil.copytree(REPO / "data" / "library", lib)
    stray = lib / "cr3bp" / "alpha=0.400" / "extra.parquet"
    stray.write_bytes(b"not listed")
    with pytest.raises(InputError, match=rf"{stray}: not listed in"):
        library_high_quality(lib, (0.4,), 415.0)


def test_the_library_table_from_the_cache_is_the_table_read_afresh(tmp_path, monkeypatch):
    """The high-quality library table is kept in the cache by the manifest's digest: the cached table equals the
    fresh one exactly, another β is another entry, and a damaged entry is read afresh (and rewritten)."""
    from amorgs.design import library_high_quality

    monkeypatch.setenv("AMORGS_CACHE_DIR", str(tmp_path / "cache"))
    train = (0.1, 0.4, 0.5)
    fresh = library_high_quality(REPO / "data" / "library", train, 415.0, cache=False)
    assert not (tmp_path / "cache").exists()
    first = library_high_quality(REPO / "data" / "library", train, 415.0)
    (entry,) = (tmp_path / "cache").glob("design-library-hq-*.parquet")
    cached = library_high_quality(REPO / "data" / "library", train, 415.0)
    pd.testing.assert_frame_equal(first, fresh)
    pd.testing.assert_frame_equal(cached, fresh)
    library_high_quality(REPO / "data" / "library", train, 430.0)
    assert len(list((tmp_path / "cache").glob("design-library-hq-*.parquet"))) == 2
    entry.write_bytes(b"damaged")
    pd.testing.assert_frame_equal(library_high_quality(REPO / "data" / "library", train, 415.0), fresh)
    pd.testing.assert_frame_equal(pd.read_parquet(entry), fresh)


def test_preparing_a_design_with_the_reuse_sampler_loads_neither_torch_nor_mlflow():
    """Start-up (issue 24 §5): the default sampler is model-free and MLflow opens only once solving has begun."""
    code = ("import sys; from amorgs.design import DesignRequest, prepare; "
            "p = prepare(DesignRequest(alpha=0.42, n=1), start_workers=False); "
            "print(type(p.sampler).__name__, 'torch' in sys.modules, 'mlflow' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], cwd=REPO, capture_output=True, text=True, check=True).stdout
    assert out.split() == ["NearestAlphaSampler", "False", "False"]


def test_auto_follows_the_frontier_and_says_why(tmp_path):
    """--sampler auto (the default) picks the arm the frontier table measured significantly better than reuse at
    the requested α's relative gap to the config's training α, reuse otherwise; the shipped models say when the
    library they were trained on is not today's."""
    import pandas as pd

    from amorgs.config import load_config
    from amorgs.design.search import DesignRequest, resolve_sampler, stale_models_note
    from amorgs.errors import InputError

    cfg = load_config("config/default.yaml")
    train = cfg.problems.cr3bp.alphas.train_values()
    gap_alpha = 0.5 * (train[0] + train[1])  # halfway between the two smallest training α
    rel = (gap_alpha - train[0]) / gap_alpha
    table = pd.DataFrame([{"design": "sparse-3", "run": "sparse-3", "alpha": 0.3, "gap_relative": rel,
                           "sampler": "amorgs", "target": "high_quality", "unit": "iterations", "ratio_to_reuse": 0.5,
                           "ratio_to_reuse_ci95_low": 0.3, "ratio_to_reuse_ci95_high": 0.8}])
    frontier = tmp_path / "frontier.csv"
    table.to_csv(frontier, index=False)
    chosen, why = resolve_sampler(DesignRequest(alpha=gap_alpha, n=1, frontier=str(frontier)), cfg)
    assert chosen.sampler == "amorgs" and "--sampler auto" in why and "beat reuse significantly" in why
    chosen, why = resolve_sampler(DesignRequest(alpha=train[0], n=1, frontier=str(frontier)), cfg)
    assert chosen.sampler == "nearest_alpha" and "library α" in why
    with pytest.raises(InputError, match=r"--frontier .*none\.csv: no such file"):  # named, so it must exist
        resolve_sampler(DesignRequest(alpha=gap_alpha, n=1, frontier=str(tmp_path / "none.csv")), cfg)
    kept, why = resolve_sampler(DesignRequest(alpha=gap_alpha, n=1, sampler="uniform"), cfg)
    assert kept.sampler == "uniform" and why == "sampler uniform (--sampler)"
    frontier.write_text("not,a\nfrontier,table\n")
    with pytest.raises(InputError, match="frontier.csv: not a frontier table"):
        resolve_sampler(DesignRequest(alpha=gap_alpha, n=1, frontier=str(frontier)), cfg)
    # models trained on another library than the one read are named; on the same library nothing is said
    from amorgs.data.library import sha256_file
    from amorgs.models.shipped import verify_models

    shipped = verify_models("data/models/cr3bp")
    older = {**shipped, "library_manifest_sha256": "0" * 64, "library_rows": 828}
    note = stale_models_note(older, "data/library", "data/models/cr3bp")
    assert "older library (828 solves)" in note and "retrain" in note
    same = {**shipped, "library_manifest_sha256": sha256_file("data/library/cr3bp/provenance.json")}
    assert stale_models_note(same, "data/library", "data/models/cr3bp") == ""


def test_auto_reads_every_frontier_table_and_picks_a_transfer_arm_only_with_its_selector(tmp_path, monkeypatch):
    """--sampler auto reads several frontier tables together (the five arms' and the selector's), names the
    table of each measurement it rests on, and picks the selector where it measured significantly better than
    reuse — only when the models folder holds a selector; a default table that is missing is skipped."""
    import shutil

    import pandas as pd

    from amorgs.config import load_config
    from amorgs.design.search import DEFAULT_FRONTIERS, DesignRequest, resolve_sampler
    from amorgs.errors import InputError

    cfg = load_config("config/default.yaml")
    train = cfg.problems.cr3bp.alphas.train_values()
    gap_alpha = 0.5 * (train[0] + train[1])
    rel = (gap_alpha - train[0]) / gap_alpha
    row = {"design": "loo", "alpha": 0.3, "gap_relative": rel, "target": "high_quality", "unit": "iterations"}
    paths = []
    for folder, arm, ratio, high in (("arms", "amorgs", 1.4, 2.5), ("selection", "selector", 0.4, 0.6)):
        (tmp_path / folder).mkdir()
        paths.append(str(tmp_path / folder / "frontier.csv"))
        pd.DataFrame([{**row, "run": "loo-0.300", "sampler": arm, "ratio_to_reuse": ratio,
                       "ratio_to_reuse_ci95_low": ratio / 2, "ratio_to_reuse_ci95_high": high}]).to_csv(paths[-1])
    models = tmp_path / "models"
    shutil.copytree("data/models/cr3bp", models)
    (models / "selector.joblib").unlink(missing_ok=True)
    chosen, why = resolve_sampler(DesignRequest(alpha=gap_alpha, n=1, frontier=tuple(paths), models_dir=str(models)), cfg)
    assert chosen.sampler == "nearest_alpha" and "selector" not in why  # no selector shipped: not available
    (models / "selector.joblib").write_bytes(b"")
    chosen, why = resolve_sampler(DesignRequest(alpha=gap_alpha, n=1, frontier=tuple(paths), models_dir=str(models)), cfg)
    assert chosen.sampler == "selector" and "beat reuse significantly" in why
    assert "in selection/loo-0.300" in why and "in arms/loo-0.300" in why  # each measurement's table named
    assert DesignRequest(alpha=0.5, n=1).frontier == DEFAULT_FRONTIERS
    import amorgs.design.search as search

    absent = str(tmp_path / "not-yet" / "frontier.csv")
    monkeypatch.setattr(search, "DEFAULT_FRONTIERS", (paths[0], absent))  # a default not yet made is skipped
    chosen, _ = resolve_sampler(DesignRequest(alpha=gap_alpha, n=1, frontier=(paths[0], absent), models_dir=str(models)), cfg)
    assert chosen.sampler == "nearest_alpha"
    monkeypatch.undo()
    with pytest.raises(InputError, match="--frontier .*not-yet/frontier.csv: no such file"):  # named: refused
        resolve_sampler(DesignRequest(alpha=gap_alpha, n=1, frontier=(paths[0], absent)), cfg)
