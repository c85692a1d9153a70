"""The real workflow: lint, dry runs, config errors, the smoke run with MLflow, and an interrupted run.

Each test copies workflow/ (with the Snakefile and the default workflow profile), config/ and the solution
library (data/library) into a temporary directory and runs the real ``snakemake`` there, so the repository's own results/ are never touched.
"""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pandas as pd
import pytest
import yaml

from amorgs.data.tables import TIMING_COLUMNS
from processes import session_left_after, session_pids

ROOT = Path(__file__).resolve().parents[2]
SNAKEMAKE = str(Path(sys.executable).parent / "snakemake")
# pytest's marker variable switches MLflow into its own self-test mode; the jobs must run as in production.
ENV = {k: v for k, v in os.environ.items() if k != "PYTEST_CURRENT_TEST"}


def workdir(tmp_path: Path, config: dict | None = None, name: str = "wf") -> Path:
    """A copy of the workflow in ``tmp_path/name``; ``config`` (if given) is written to config/test.yaml."""
    wd = tmp_path / name
    wd.mkdir(parents=True)
    for d in ("workflow", "config", "data/library"):
        shutil.copytree(ROOT / d, wd / d)
    if config is not None:
        (wd / "config" / "test.yaml").write_text(yaml.safe_dump(config))
    return wd


def smoke_config() -> dict:
    """The effective smoke config, every key (config/smoke.yaml merged over the defaults), to edit."""
    from config_files import mapping

    return mapping("smoke")


def snakemake(wd: Path, *args: str, timeout: float = 600) -> subprocess.CompletedProcess:
    return subprocess.run([SNAKEMAKE, *args], cwd=wd, capture_output=True, text=True, timeout=timeout, env=ENV)


def test_lint_is_clean():
    res = snakemake(ROOT, "--lint")
    assert res.returncode == 0, res.stdout + res.stderr
    assert "Congratulations, your workflow is in a good condition" in res.stdout + res.stderr


@pytest.mark.parametrize("flag", ["--workflow-profile", "--profile"])
def test_slurm_profile_dry_run(tmp_path, flag):
    wd = workdir(tmp_path)
    res = snakemake(wd, "-n", flag, "workflow/profiles/slurm", "--configfile", "config/paper.yaml")
    out = res.stdout + res.stderr
    assert res.returncode == 0, out
    for rule in ("generate", "filter", "train_dejong_cvae", "analyze_cr3bp", "train_cr3bp", "train_cr3bp_fraction",
                 "predict_cr3bp", "ablation_cell", "ablation_report"):
        assert f"rule {rule}:" in out, rule
    # the paper's ablation: 200 starts per (test α, sampler), 16 workers each
    assert '"rule": "ablation_cell"' in out and '"starts": 200' in out
    # cr3bp generate jobs ask for the runtime and memory of config/paper.yaml
    assert "runtime=1440" in out and "mem_mb=16000" in out


def test_unknown_config_key_fails_at_start(tmp_path):
    cfg = smoke_config()
    cfg["problems"]["dejong"]["generate"]["startz_per_shard"] = 3
    wd = workdir(tmp_path, cfg)
    res = snakemake(wd, "-n", "--configfile", "config/test.yaml")
    out = res.stdout + res.stderr
    assert res.returncode != 0
    assert "config/test.yaml: problems.dejong.generate.startz_per_shard: unknown key" in out
    assert "Traceback" not in out
    assert not (wd / "results").exists()


@pytest.mark.parametrize("damage", ["truncated", "unlisted"])
def test_a_damaged_or_unlisted_library_file_stops_the_workflow_before_any_job(tmp_path, damage):
    """The library is checked against its manifest when the workflow starts (it used to be caught inside
    `merge`, after minutes of other jobs; an unlisted file was ignored)."""
    from amorgs.data.library import library_files

    wd = workdir(tmp_path, smoke_config())  # the smoke config reads the library
    target = library_files(wd / "data" / "library", "cr3bp", "0.500")[0]
    if damage == "truncated":
        target.write_bytes(target.read_bytes()[:-100])
    else:
        target = target.with_name("shards-99999-99999.parquet")
        shutil.copyfile(library_files(wd / "data" / "library", "cr3bp", "0.100")[0], target)
    res = snakemake(wd, "--configfile", "config/test.yaml")
    out = res.stdout + res.stderr
    assert res.returncode != 0
    line = next(x for x in out.splitlines() if x.startswith("amorgs: "))
    assert f"amorgs: {target.relative_to(wd)}: " in line and ("not listed in" if damage == "unlisted" else "differs from") in line
    assert "Traceback" not in out
    assert not (wd / "results").exists()


def test_config_override_is_validated(tmp_path):
    wd = workdir(tmp_path)
    res = snakemake(wd, "-n", "--configfile", "config/smoke.yaml", "--config", "seed=-1")
    assert res.returncode != 0
    out = res.stderr + res.stdout
    assert "amorgs: merged config (config/smoke.yaml + --config): seed: Input should be greater than or equal to 0 (got -1)" in out
    assert "Traceback" not in out and "File " not in out


def _tables(wd: Path) -> dict[str, pd.DataFrame]:
    """Every parquet table under results/, timing columns dropped."""
    out = {}
    for p in sorted((wd / "results").rglob("*.parquet")):
        df = pd.read_parquet(p)
        out[str(p.relative_to(wd))] = df.drop(columns=[c for c in TIMING_COLUMNS if c in df.columns])
    return out


#: Where the smoke test runs the workflow when set (CI: .ci/run then checks that same run — complete,
#: nothing left to do, every output tracked — instead of running the smoke workflow a second time).
SMOKE_WORKDIR = os.environ.get("AMORGS_SMOKE_WORKDIR")


@pytest.mark.slow
@pytest.mark.ci
def test_smoke_workflow_tracks_every_job(tmp_path):
    from mlflow.tracking import MlflowClient

    from amorgs.config import load_config
    from amorgs.steps import expected_jobs

    if SMOKE_WORKDIR:
        shutil.rmtree(SMOKE_WORKDIR, ignore_errors=True)
    wd = workdir(Path(SMOKE_WORKDIR).parent if SMOKE_WORKDIR else tmp_path, name=Path(SMOKE_WORKDIR).name if SMOKE_WORKDIR else "wf")
    res = snakemake(wd, "--configfile", "config/smoke.yaml", timeout=1800)  # the workflow profile applies itself; ≈ 6–15 min on 2 cores
    assert res.returncode == 0, res.stdout[-5000:] + res.stderr[-5000:]

    check = subprocess.run(
        [sys.executable, "-m", "amorgs", "check-outputs", "--config", "config/smoke.yaml"],
        cwd=wd, capture_output=True, text=True, env=ENV,
    )
    assert check.returncode == 0, check.stdout + check.stderr

    for log in (wd / "logs").rglob("*.log"):
        assert "database is locked" not in log.read_text(), log

    cfg = load_config(wd / "config" / "smoke.yaml")
    client = MlflowClient(f"sqlite:///{wd / 'results' / 'mlflow' / 'mlflow.db'}")
    exp = client.get_experiment_by_name(cfg.mlflow.experiment)
    parents = client.search_runs([exp.experiment_id], filter_string="tags.kind = 'workflow'")
    assert len(parents) == 1 and parents[0].info.status == "FINISHED"
    parent = parents[0]
    assert parent.data.tags["config_hash"] == cfg.hash
    assert parent.data.params["problems.dejong.generate.starts_per_shard"] == "40"
    children = client.search_runs(
        [exp.experiment_id], filter_string=f"tags.mlflow.parentRunId = '{parent.info.run_id}'", max_results=1000
    )
    expected = sorted((rule, json.dumps(w, sort_keys=True)) for rule, w in expected_jobs(cfg))
    assert sorted((c.data.tags["rule"], c.data.tags["wildcards"]) for c in children) == expected
    # the runtime report (issue 40 §1): every job's benchmark, per rule, written and logged to the parent run
    runtime = pd.read_csv(wd / "results" / "tables" / "runtime_by_rule.csv").set_index("rule")
    per_rule = pd.Series([rule for rule, _ in expected_jobs(cfg)]).value_counts()
    assert runtime["jobs"].sort_index().to_dict() == per_rule.sort_index().to_dict()
    assert (runtime["cpu_min"] > 0).all() and (runtime["wall_min"] > 0).all() and runtime["cpu_share"].sum() == pytest.approx(1)
    assert (wd / "results" / "figures" / "runtime_by_rule.png").stat().st_size > 0
    assert parent.data.metrics["runtime/jobs"] == len(expected)
    assert {a.path for a in client.list_artifacts(parent.info.run_id, "runtime")} >= {
        "runtime/runtime_by_rule.csv", "runtime/runtime_by_rule.png"}
    for child in children:
        tags = child.data.tags
        assert child.info.status == "FINISHED"
        assert tags["config_hash"] == cfg.hash
        assert {"git_commit", "version.torch", "version.casadi", "version.numpy", "version.snakemake", "version.mlflow"} <= set(tags)
    def child(rule, **wildcards):
        tags = {"rule": rule, **{f"wildcard.{k}": v for k, v in wildcards.items()}}
        return next(c for c in children if tags.items() <= c.data.tags.items())

    assert 0 < child("generate", problem="dejong", alpha="0.000", shard="0").data.metrics["converged_fraction"] <= 1
    assert child("generate", problem="cr3bp", alpha="0.700", shard="0").data.metrics["starts"] == 1
    merged = child("merge", problem="cr3bp", alpha="0.700").data.metrics
    assert merged["rows_library"] == 36 and merged["library_files"] > 0  # smoke: a fixed slice of the library
    alpha_table = pd.read_parquet(wd / "results" / "cr3bp" / "solutions" / "alpha=0.700.parquet")
    assert set(alpha_table["source"]) == {"library", "fresh"}
    assert child("filter", problem="dejong").data.metrics["high_quality"] > 0
    assert "converged_fraction/alpha_0.850" in child("filter", problem="cr3bp").data.metrics
    train = child("train_dejong_cvae")
    history = client.get_metric_history(train.info.run_id, "loss")
    assert [m.step for m in history] == list(range(1, cfg.dejong_cvae.epochs + 1))
    predict = child("predict_dejong_cvae").data.metrics
    for label in ("0.349", "1.047"):  # the smoke config's held-out De Jong α
        assert 0 <= predict[f"fraction_within_radius/alpha_{label}"] <= 1
        assert 0 <= predict[f"minima_covered/alpha_{label}"] <= 8
    for name in ("fig02_foxholes", "fig16_dejong_predictions"):
        artifacts = [a.path for a in client.list_artifacts(child(name).info.run_id, "figures")]
        assert artifacts == [f"figures/{name}.png"]

    # CR3BP: analysis, models (trained on the training α only), predictions, ablation
    from amorgs import layout
    from amorgs.steps.train import main_models

    analysis = child("analyze_cr3bp")
    assert analysis.data.metrics
    assert {a.path for a in client.list_artifacts(analysis.info.run_id, "figures")} == {
        f"figures/{n}.png" for n in layout.ANALYSIS_FIGURES
    }
    for model in main_models(cfg):
        train = child("train_cr3bp", model=model)
        history = client.get_metric_history(train.info.run_id, "loss")
        assert [m.step for m in history] == list(range(1, cfg.cr3bp_models.epochs + 1))
        assert [a.path for a in client.list_artifacts(train.info.run_id, "models")] == [f"models/{model}.pt"]
        # the checkpoint is a logged model, its metrics linked; the training table is a `training` dataset
        (output,) = train.outputs.model_outputs
        assert output.step == cfg.cr3bp_models.epochs
        logged = client.get_logged_model(output.model_id)
        assert logged.name == model and "loss" in {m.key for m in logged.metrics}
        contexts = {(d.dataset.name, {t.key: t.value for t in d.tags}["mlflow.data.context"]) for d in train.inputs.dataset_inputs}
        assert contexts == {("high_quality.parquet", "training")}
        assert json.loads(train.data.params["train_alphas"]) == [0.7, 0.8, 0.9]
    full_rows = int(child("train_cr3bp", model="cvae_gmm").data.params["rows"])
    assert int(child("train_cr3bp_fraction", fraction="0.1").data.params["rows"]) < full_rows
    predict = child("predict_cr3bp")
    assert "n_samples/alpha_0.850/amorgs_f1" in predict.data.metrics
    assert {a.path for a in client.list_artifacts(predict.info.run_id, "figures")} == {
        f"figures/{n}.png" for n in layout.PREDICTION_FIGURES
    }
    cell = child("ablation_cell", alpha="0.850", sampler="amorgs").data.metrics
    assert cell["starts"] == cfg.ablation.n_starts
    report_run = child("ablation_report")
    assert [d.dataset.name for d in report_run.inputs.dataset_inputs] == ["high_quality.parquet"]
    assert len(child("filter", problem="cr3bp").inputs.dataset_inputs) == len(cfg.problems.cr3bp.alpha_values())
    assert any(k.startswith("percent_hq/alpha_") for k in report_run.data.metrics)
    assert {a.path for a in client.list_artifacts(report_run.info.run_id, "figures")} == {
        f"figures/{n}.png" for n in layout.ABLATION_FIGURES
    }
    assert "AmorGS" in (wd / "results" / "tables" / "table6.md").read_text()
    # global search (issue 41): every (strategy, sampler) cell ran its searches; the report logged the ECDF figure
    assert child("global_search_cell", alpha="0.850", strategy="mbh", sampler="nearest_alpha").data.metrics["solves"] >= 1
    search_report = child("global_search_report")
    assert {a.path for a in client.list_artifacts(search_report.info.run_id, "figures")} == {
        f"figures/{layout.GLOBAL_SEARCH_FIGURE}.png"}
    assert {f"success_rate/alpha_0.850/{t}/{s}/delta_10kg" for t in ("mbh", "multistart")
            for s in ("uniform", "nearest_alpha")} <= set(search_report.data.metrics)

    res = snakemake(wd, "--report", "report.html", "--configfile", "config/smoke.yaml")
    assert res.returncode == 0, res.stderr[-3000:]
    report = (wd / "report.html").read_text()
    assert "fig02_foxholes.png" in report and "fig16_dejong_predictions.png" in report

    res = snakemake(wd, "-n", "--configfile", "config/smoke.yaml")
    assert "Nothing to be done" in res.stdout + res.stderr

    _check_reference_export(wd, tmp_path / "reference", cfg)


def _check_reference_export(wd: Path, ref: Path, cfg) -> None:
    """``amorgs reference-export`` on the finished smoke run: the ablation and prediction tables and figures
    with their hashes, the run's CPU per rule, the solve tables behind them; then ``--check`` catches an edit."""
    from amorgs.errors import InputError
    from amorgs.reference import export_reference, verify_reference

    (ref / "tables").mkdir(parents=True)
    (ref / "tables" / "stale.md").write_text("from another run")
    manifest = export_reference("config/smoke.yaml", ref, run_dir=wd)
    files = {f["file"] for f in manifest["files"]}
    assert {"tables/table6.md", "tables/ablation_ert.csv", "cr3bp/ablation/summary.json",
            "cr3bp/predictions/metrics.json", "figures/fig22_iteration_capped.png"} <= files
    assert files == {p.relative_to(ref).as_posix() for p in ref.rglob("*") if p.is_file()} - {
        "provenance.json", "README.md", "config.yaml"}
    assert (ref / "config.yaml").read_bytes() == (wd / "config" / "smoke.yaml").read_bytes()
    assert "config/smoke.yaml" in (ref / "README.md").read_text()
    assert (ref / "tables" / "table6.md").read_bytes() == (wd / "results" / "tables" / "table6.md").read_bytes()
    cpu = manifest["cpu_hours"]
    assert cpu["ablation_cell"] > 0 and cpu["train_cr3bp"] > 0 and cpu["generate"] > 0
    assert abs(cpu["total"] - sum(v for k, v in cpu.items() if k != "total")) < 1e-9
    cells = [t for t in manifest["solve_tables"] if t["file"].startswith("cr3bp/ablation/alpha=")]
    assert sum(t["rows"] for t in cells) == cfg.ablation.n_starts * len(cfg.ablation.samplers) * len(cfg.problems.cr3bp.alphas.test)
    assert manifest["config_hash"] == cfg.hash and manifest["library"]["rows"] > 0
    assert "torch" in manifest["packages"]
    starts = pd.read_parquet(ref / "starts.parquet")  # every ablation start, compact: guesses and outcomes
    assert len(starts) == sum(t["rows"] for t in manifest["solve_tables"] if t["file"].startswith("cr3bp/ablation/"))
    assert len([c for c in starts if c.startswith("guess_")]) == 64 and "theta_01" not in starts
    cert_file = ref.parent / "certificate.json"
    out = subprocess.run([sys.executable, "-m", "amorgs", "reference-certify", str(ref), "--sample", "2",
                          "--seed", "3", "--output", str(cert_file)], capture_output=True, text=True, env=ENV)
    assert out.returncode == 0 and "2 of 2 re-solved starts" in out.stdout, out.stdout + out.stderr
    cert = json.loads(cert_file.read_text())
    assert cert["exact"] and cert["max_abs_dm_f_kg"] == 0.0 and len(cert["rows"]) == 2
    bare = export_reference("config/smoke.yaml", ref.parent / "bare", run_dir=wd, figures=False)
    assert {f["file"] for f in bare["files"]} == files - {f for f in files if f.startswith("figures/")}

    out = subprocess.run([sys.executable, "-m", "amorgs", "reference-export", "--dest", str(ref), "--check"],
                         capture_output=True, text=True, env=ENV)
    assert out.returncode == 0 and f"{len(files)} files match" in out.stdout, out.stdout + out.stderr
    (ref / "tables" / "table6.md").write_text("edited")
    with pytest.raises(InputError, match=r"table6\.md: SHA-256 differs"):
        verify_reference(ref)
    with pytest.raises(InputError, match=r"output missing"):  # the default config was never run here
        export_reference("config/default.yaml", ref, run_dir=wd)


def _interrupt_config() -> dict:
    cfg = smoke_config()
    cfg["problems"]["dejong"]["alphas"] = {"train": [0.2], "test": []}
    cfg["problems"]["dejong"]["generate"].update(shards=3, starts_per_shard=30)
    cfg["problems"]["cr3bp"]["enabled"] = False
    for section in ("dejong_cvae", "cr3bp_analysis", "cr3bp_models", "ablation", "transfer", "global_search"):
        cfg[section]["enabled"] = False
    return cfg


def _planned(res: subprocess.CompletedProcess) -> dict[str, int]:
    """Jobs per rule in a dry run's "Job stats" table (empty when there is nothing to be done)."""
    assert res.returncode == 0, res.stdout[-3000:] + res.stderr[-3000:]
    lines = (res.stdout + res.stderr).splitlines()
    if "Job stats:" not in lines:
        assert "Nothing to be done" in res.stdout + res.stderr, res.stdout[-3000:] + res.stderr[-3000:]
        return {}
    table = lines[lines.index("Job stats:") + 3:]
    planned = {}
    for line in table:
        if not line.strip():
            break
        rule, count = line.split()
        planned[rule] = int(count)
    planned.pop("total", None)
    return planned


def test_a_changed_setting_reruns_exactly_the_jobs_it_reaches(tmp_path):
    """A config change reruns the jobs whose settings it changes, and only those (params.settings): the
    settings in params.job alone would not do it, since Snakemake ignores params derived from inputs."""
    cfg = _interrupt_config()
    cfg["problems"]["dejong"]["generate"].update(shards=2, starts_per_shard=5)
    cfg["mlflow"]["enabled"] = False
    wd = workdir(tmp_path, cfg)
    run = ["results/dejong/high_quality.parquet", "--configfile", "config/test.yaml"]
    assert snakemake(wd, *run).returncode == 0
    assert _planned(snakemake(wd, "-n", *run)) == {}

    cfg["problems"]["dejong"]["filter"]["max_objective"] = 5.0  # reaches the filter only
    (wd / "config" / "test.yaml").write_text(yaml.safe_dump(cfg))
    assert _planned(snakemake(wd, "-n", *run)) == {"filter": 1}

    cfg["problems"]["dejong"]["generate"]["starts_per_shard"] = 6  # every shard, then what reads them
    (wd / "config" / "test.yaml").write_text(yaml.safe_dump(cfg))
    assert _planned(snakemake(wd, "-n", *run)) == {"generate": 2, "merge": 1, "filter": 1}


@pytest.mark.slow
@pytest.mark.ci
def test_killed_run_resumes_without_losing_or_duplicating_rows(tmp_path):
    from mlflow.tracking import MlflowClient

    cfg = _interrupt_config()
    untracked = {**cfg, "mlflow": {**cfg["mlflow"], "enabled": False}}  # tracking never changes a table
    # the data stages, with the default profile (2 cores, --rerun-incomplete)
    run = ["results/dejong/high_quality.parquet", "--configfile", "config/test.yaml"]
    ref = workdir(tmp_path / "ref", untracked)
    res = snakemake(ref, *run)
    assert res.returncode == 0, res.stderr[-3000:]

    wd = workdir(tmp_path / "killed", cfg)
    proc = subprocess.Popen(
        [SNAKEMAKE, *run],
        cwd=wd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True, env=ENV,
    )
    deadline = time.monotonic() + 300
    solutions = wd / "results" / "dejong" / "solutions"
    while not list(solutions.glob("alpha=*/shard-*.parquet")) and time.monotonic() < deadline:
        assert proc.poll() is None, "the workflow ended before any shard landed"
        time.sleep(0.05)
    os.killpg(proc.pid, signal.SIGKILL)  # snakemake and every job it started
    proc.wait()
    assert not (wd / "results" / "dejong" / "high_quality.parquet").exists(), "killed too late to test anything"

    assert snakemake(wd, "--unlock", "--configfile", "config/test.yaml").returncode == 0
    res = snakemake(wd, *run)
    assert res.returncode == 0, res.stderr[-3000:]

    got, want = _tables(wd), _tables(ref)
    assert sorted(got) == sorted(want)
    for name, df in want.items():
        pd.testing.assert_frame_equal(got[name], df, check_exact=True, obj=name)
    assert len(want["results/dejong/solutions/alpha=0.200.parquet"]) == 90

    client = MlflowClient(f"sqlite:///{wd / 'results' / 'mlflow' / 'mlflow.db'}")
    exp = client.get_experiment_by_name(cfg["mlflow"]["experiment"])
    statuses = sorted(r.info.status for r in client.search_runs([exp.experiment_id], "tags.kind = 'workflow'"))
    assert statuses == ["FINISHED", "KILLED"]


@pytest.mark.slow
@pytest.mark.ci
@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="reads the process table from /proc")
def test_kill_9_of_snakemake_leaves_no_job_or_solver_and_the_rerun_one_finished_run_per_job(tmp_path):
    """`kill -9` of Snakemake alone (not its process group) used to leave the job and its solver worker
    running; they finished on their own and the rerun added a second FINISHED run of the same job."""
    cfg = _interrupt_config()
    cfg["problems"]["dejong"]["generate"].update(shards=1, starts_per_shard=50000)  # minutes of work
    wd = workdir(tmp_path, cfg)
    run = ["results/dejong/high_quality.parquet", "--configfile", "config/test.yaml"]
    proc = subprocess.Popen([SNAKEMAKE, *run], cwd=wd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                            start_new_session=True, env=ENV)
    try:
        deadline = time.monotonic() + 300
        invocation = wd / "results" / "mlflow" / "invocation.json"
        while not invocation.exists() or not any(
            r.info.status == "RUNNING" for r in _runs(wd, cfg["mlflow"]["experiment"])["job"]
        ) or len(session_pids(proc.pid)) < 4:  # snakemake, the job's shell, the job, its solver worker
            assert proc.poll() is None, "the workflow ended before its job started"
            assert time.monotonic() < deadline, "no job run appeared"
            time.sleep(0.5)
        os.kill(proc.pid, signal.SIGKILL)  # Snakemake alone: its jobs are re-parented, not signalled
        proc.wait()
        assert session_left_after(proc.pid, 60) == [], "a job or solver process outlived the killed workflow"
    finally:
        for pid in session_pids(proc.pid):
            os.kill(pid, signal.SIGKILL)
    runs = _runs(wd, cfg["mlflow"]["experiment"])
    assert [r.info.status for r in runs["job"]] == ["KILLED"]  # the job closed its own run as it ended

    cfg["problems"]["dejong"]["generate"].update(starts_per_shard=30)  # the rerun: a shard that ends soon
    (wd / "config" / "test.yaml").write_text(yaml.safe_dump(cfg))
    assert snakemake(wd, "--unlock", "--configfile", "config/test.yaml").returncode == 0
    res = snakemake(wd, *run)
    assert res.returncode == 0, res.stderr[-3000:]
    runs = _runs(wd, cfg["mlflow"]["experiment"])
    assert sorted(r.info.status for r in runs["workflow"]) == ["FINISHED", "KILLED"]
    by_job: dict[tuple, list[str]] = {}
    for r in runs["job"]:
        by_job.setdefault((r.data.tags["rule"], r.data.tags["wildcards"]), []).append(r.info.status)
    assert {job: statuses.count("FINISHED") for job, statuses in by_job.items()} == dict.fromkeys(by_job, 1)
    assert sorted(s for statuses in by_job.values() for s in statuses if s != "FINISHED") == ["KILLED"]


def test_boundary_conditions_check(tmp_path):
    """`amorgs boundary-conditions --check` accepts the stored resource and names a changed value."""
    amorgs = [sys.executable, "-m", "amorgs", "boundary-conditions", "--check", "--output"]
    stored = ROOT / "resources" / "boundary_conditions.json"
    res = subprocess.run([*amorgs, str(stored)], capture_output=True, text=True, env=ENV)
    assert res.returncode == 0, res.stderr
    bad = json.loads(stored.read_text())
    bad["mu"] *= 1.001
    (tmp_path / "bc.json").write_text(json.dumps(bad))
    res = subprocess.run([*amorgs, str(tmp_path / "bc.json")], capture_output=True, text=True, env=ENV)
    assert res.returncode != 0 and "mu:" in res.stderr


def _runs(wd: Path, experiment: str) -> dict[str, list]:
    """Workflow (parent) and job runs of ``experiment`` in the work directory's SQLite store."""
    from mlflow.tracking import MlflowClient

    client = MlflowClient(f"sqlite:///{wd / 'results' / 'mlflow' / 'mlflow.db'}")
    exp = client.get_experiment_by_name(experiment)
    if exp is None:
        return {"workflow": [], "job": []}
    return {kind: client.search_runs([exp.experiment_id], f"tags.kind = '{kind}'") for kind in ("workflow", "job")}


@pytest.mark.slow
def test_plain_snakemake_runs_with_the_profile_and_a_lost_store_is_reported(tmp_path):
    """`snakemake` alone (no --profile, no --cores) runs; outputs are group-readable; a deleted store is named."""
    cfg = _interrupt_config()
    cfg["problems"]["dejong"]["generate"]["shards"] = 1  # every rule of the config once: 4 jobs (3 shards: 6)
    wd = workdir(tmp_path, cfg)
    old = os.umask(0o022)
    try:
        res = snakemake(wd, "--configfile", "config/test.yaml")
    finally:
        os.umask(old)
    out = res.stdout + res.stderr
    assert res.returncode == 0, out[-5000:]
    assert "workflow specific profile workflow/profiles/default" in out
    outputs = [p for p in (wd / "results").rglob("*") if p.is_file() and "mlflow" not in p.parts]
    assert any(p.suffix == ".png" for p in outputs) and any(p.suffix == ".parquet" for p in outputs)
    for p in outputs:
        assert p.stat().st_mode & 0o777 == 0o644, p

    check = [sys.executable, "-m", "amorgs", "check-outputs", "--config", "config/test.yaml"]
    res = subprocess.run(check, cwd=wd, capture_output=True, text=True, env=ENV)
    assert res.returncode == 0, res.stdout + res.stderr

    shutil.rmtree(wd / "results" / "mlflow")
    res = snakemake(wd, "--configfile", "config/test.yaml")
    assert res.returncode == 0 and "Nothing to be done" in res.stdout + res.stderr
    res = subprocess.run(check, cwd=wd, capture_output=True, text=True, env=ENV)
    assert res.returncode == 3, res.stdout + res.stderr
    assert "untracked" in res.stderr and "--no-mlflow" in res.stderr
    res = subprocess.run([*check, "--no-mlflow"], cwd=wd, capture_output=True, text=True, env=ENV)
    assert res.returncode == 0, res.stdout + res.stderr

    # Losing the MLflow store never breaks a rebuild: it is recreated and the outputs come back.
    (wd / "results" / "figures" / "fig02_foxholes.png").unlink()
    res = snakemake(wd, "--configfile", "config/test.yaml")
    assert res.returncode == 0, res.stderr[-3000:]
    assert (wd / "results" / "figures" / "fig02_foxholes.png").stat().st_size > 0
    assert (wd / "results" / "mlflow" / "mlflow.db").is_file()


@pytest.mark.slow
def test_ctrl_c_ends_the_workflow_and_job_runs_killed(tmp_path):
    cfg = _interrupt_config()
    cfg["problems"]["dejong"]["generate"].update(shards=1, starts_per_shard=50000)  # minutes of work
    wd = workdir(tmp_path, cfg)
    proc = subprocess.Popen(
        [SNAKEMAKE, "results/dejong/high_quality.parquet", "--configfile", "config/test.yaml"],
        cwd=wd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True, env=ENV,
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),  # see test_tracking.default_sigint
    )
    deadline = time.monotonic() + 300
    invocation = wd / "results" / "mlflow" / "invocation.json"  # written once the store is created and migrated
    while not invocation.exists() or not any(
        r.info.status == "RUNNING" for r in _runs(wd, cfg["mlflow"]["experiment"])["job"]
    ):
        assert proc.poll() is None, "the workflow ended before its job started"
        assert time.monotonic() < deadline, "no job run appeared"
        time.sleep(0.5)
    os.killpg(proc.pid, signal.SIGINT)  # Ctrl-C in a terminal: Snakemake and its jobs
    # it ends in ≈ 20 s on an idle machine; a clean-clone CI beside the SLURM tests once needed > 120 s (every
    # workflow test ran 1.5–1.7× slower then), so the bound is generous: it catches a hang, not a slow shutdown
    assert proc.wait(timeout=300) != 0
    runs = _runs(wd, cfg["mlflow"]["experiment"])
    assert [r.info.status for r in runs["workflow"]] == ["KILLED"]
    assert [r.info.status for r in runs["job"]] == ["KILLED"]
    assert not (wd / "results" / "dejong" / "high_quality.parquet").exists()
