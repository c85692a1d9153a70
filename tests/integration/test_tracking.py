"""amorgs.tracking against real MLflow: datasets, logged models, killed runs, the tracking URI, a lost store.

Every test works on its own store under ``tmp_path`` (a real SQLite database, or a real ``mlflow server`` on
127.0.0.1 for the URI tests); killed jobs are real processes stopped by real signals.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
from pathlib import Path

import pandas as pd
import pytest
from mlflow.tracking import MlflowClient

from amorgs import tracking
from mlflow_serving import free_port, serving

ROOT = Path(__file__).resolve().parents[2]
ENV = {k: v for k, v in os.environ.items() if k not in ("PYTEST_CURRENT_TEST", tracking.TRACKING_URI_ENV)}
CONFIG = {"seed": 1, "mlflow": {"enabled": True, "experiment": "t", "tracking_uri": None}}


@pytest.fixture(autouse=True)
def no_uri_from_the_environment(monkeypatch):
    monkeypatch.delenv(tracking.TRACKING_URI_ENV, raising=False)


def start(store: Path, uri: str | None = None, config: dict = CONFIG) -> str:
    run_id = tracking.start_invocation(config, "abc123", config["mlflow"]["experiment"], ["config/x.yaml"], store, uri=uri)
    assert run_id is not None
    return run_id


def children(client: MlflowClient, parent: str):
    exp = client.get_run(parent).info.experiment_id
    return client.search_runs([exp], filter_string=f"tags.mlflow.parentRunId = '{parent}'")


def test_job_logs_datasets_and_a_logged_model_with_linked_metrics(tmp_path):
    store = tmp_path / "mlflow"
    parent = start(store)
    table = pd.DataFrame({"alpha": [0.1, 0.2, 0.3], "m_f": [420.0, 418.0, 430.0]})
    table.to_parquet(tmp_path / "high_quality.parquet")
    (tmp_path / "model.pt").write_bytes(b"checkpoint")
    with tracking.job_run("train_cr3bp", {"model": "lstm"}, store) as run:
        run.log_dataset(table, tmp_path / "high_quality.parquet", "training")
        run.log_dataset(table.head(1), tmp_path / "high_quality.parquet", "evaluation")
        run.start_model("lstm", {"epochs": 3})
        for epoch in (1, 2, 3):
            run.log_metrics({"loss": 1.0 / epoch}, step=epoch)
        run.finish_model(tmp_path / "model.pt", step=3)
    tracking.finish_invocation("FINISHED", store)

    client = MlflowClient(tracking.tracking_uri(store))
    (job,) = children(client, parent)
    assert job.info.status == "FINISHED"
    inputs = {
        {t.key: t.value for t in d.tags}["mlflow.data.context"]: d.dataset for d in job.inputs.dataset_inputs
    }
    assert set(inputs) == {"training", "evaluation"}
    assert inputs["training"].name == "high_quality.parquet"
    assert '"num_rows": 3' in inputs["training"].profile and "m_f" in inputs["training"].schema
    assert (tmp_path / "high_quality.parquet").as_uri() in inputs["training"].source
    assert inputs["training"].digest != inputs["evaluation"].digest

    (output,) = job.outputs.model_outputs
    assert output.step == 3
    model = client.get_logged_model(output.model_id)
    assert model.name == "lstm" and str(model.status).endswith("READY")
    assert model.source_run_id == job.info.run_id and model.params["epochs"] == "3"
    linked = {(m.key, m.step): m for m in model.metrics}
    assert linked[("loss", 3)].value == pytest.approx(1 / 3)
    assert linked[("loss", 3)].dataset_name == "high_quality.parquet"
    assert linked[("loss", 3)].dataset_digest == inputs["training"].digest
    history = client.get_metric_history(job.info.run_id, "loss")
    assert [m.step for m in history] == [1, 2, 3]  # the run keeps its own history as well
    files = [a.path for a in client.list_logged_model_artifacts(output.model_id)]
    assert files == ["model.pt"]
    assert [a.path for a in client.list_artifacts(job.info.run_id, "models")] == ["models/model.pt"]


def default_sigint() -> None:
    """In the child: SIGINT back to its default.  A shell starts background jobs (``cmd &``, ``nohup``) with
    SIGINT ignored, and Python then installs no KeyboardInterrupt handler: Ctrl-C must be testable anyway."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


JOB = textwrap.dedent(
    """
    import sys, time
    from amorgs import tracking
    with tracking.job_run("train_cr3bp", {"model": "lstm"}, sys.argv[1]) as run:
        run.start_model("lstm")
        print("ready", flush=True)
        time.sleep(120)
    """
)


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT])
def test_a_killed_job_ends_its_run_killed(tmp_path, sig):
    store = tmp_path / "mlflow"
    parent = start(store)
    proc = subprocess.Popen(
        [sys.executable, "-c", JOB, str(store)], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=ENV,
        preexec_fn=default_sigint,
    )
    assert proc.stdout.readline().strip() == "ready", proc.stderr.read()
    proc.send_signal(sig)
    proc.wait(timeout=60)
    assert proc.returncode != 0
    if sig == signal.SIGTERM:
        assert proc.returncode == 128 + signal.SIGTERM
    client = MlflowClient(tracking.tracking_uri(store))
    (job,) = children(client, parent)
    assert job.info.status == "KILLED"
    models = client.search_logged_models([job.info.experiment_id])
    assert [str(m.status) for m in models] == [str(models[0].status)] and "FAILED" in str(models[0].status)


def test_a_job_whose_tracking_failed_is_recorded_by_the_next_invocation(tmp_path, monkeypatch):
    """MLflow fails mid-job (as on a full disk): the job finishes, leaves its record under pending/, and the next
    invocation writes it into a FINISHED run (params, every metric, the artifact) that tracked_jobs — what
    check-outputs reads — counts; where not even the record can be written, the job fails (Snakemake then
    removes its outputs and reruns it)."""
    store = tmp_path / "mlflow"
    start(store)
    figure = tmp_path / "fig.png"
    figure.write_bytes(b"png")
    real = MlflowClient.log_batch

    def disk_full(self, run_id, metrics=(), params=(), tags=()):
        if metrics:
            raise OSError(28, "No space left on device")
        return real(self, run_id, metrics=metrics, params=params, tags=tags)

    monkeypatch.setattr(MlflowClient, "log_batch", disk_full)
    with tracking.job_run("plot", {"alpha": "0.300"}, store) as run:
        run.log_params({"n": 3, "solver": {"tol": 1e-6}})
        run.log_metrics({"loss": 0.5}, step=1)
        run.log_metrics({"loss": 0.25}, step=2)  # the first flush fails: from here on the job runs untracked
        run.flush()
        run.log_artifact(figure, "figures")
    tracking.finish_invocation("FINISHED", store)
    monkeypatch.undo()
    (pending,) = (store / tracking.PENDING_DIR).glob("*.json")
    assert not [j for j in tracking.tracked_jobs(store)["jobs"] if j["status"] == "FINISHED"]
    second = start(store)  # the next invocation records it
    assert not pending.exists()
    client = MlflowClient(tracking.tracking_uri(store))
    (late,) = [r for r in children(client, second)]
    assert late.info.status == "FINISHED" and late.data.tags["rule"] == "plot" and late.data.tags["recorded_late"]
    assert late.data.params == {"n": "3", "solver.tol": "1e-06"}
    assert [(m.step, m.value) for m in client.get_metric_history(late.info.run_id, "loss")] == [(1, 0.5), (2, 0.25)]
    jobs = [j for j in tracking.tracked_jobs(store)["jobs"] if j["status"] == "FINISHED"]
    assert [(j["rule"], j["wildcards"], j["artifacts"]) for j in jobs] == [("plot", {"alpha": "0.300"}, ["figures/fig.png"])]

    (store / tracking.DB_NAME).unlink()  # the store is lost, and the record cannot be written either
    (store / tracking.PENDING_DIR).rmdir()
    (store / tracking.PENDING_DIR).write_text("a file where the folder should be")
    with pytest.raises(SystemExit, match="neither MLflow nor .* could record it.*reruns it"):
        with tracking.job_run("plot", {"alpha": "0.300"}, store) as run:
            run.log_metrics({"loss": 1.0})


DEFERRED_JOB = textwrap.dedent("""
    import sys
    from pathlib import Path
    from amorgs import tracking
    store, fail = Path(sys.argv[1]), sys.argv[2] == "fail"
    with tracking.job_run("merge", {"problem": "dejong", "alpha": "0.000"}, store, deferred=True) as run:
        run.log_params({"problem": "dejong", "library": {"enabled": False}})
        run.log_metrics({"rows": 200, "converged": 186})
        run.log_artifact(store.parent / "table.txt", "tables")
        assert "mlflow" not in sys.modules, "a deferred job imported mlflow"
        if fail:
            raise RuntimeError("boom")
""")


def test_a_deferred_job_never_loads_mlflow_and_its_run_is_written_when_the_invocation_ends(tmp_path):
    """A short job (deferred_tracking) keeps its record instead of opening a run — mlflow is never imported in
    its process — and finish_invocation writes one child run per record with the job's own times, status,
    params, metrics, artifacts and the invocation's identity tags; a failed job's run is FAILED."""
    store = tmp_path / "mlflow"
    parent = start(store)
    (tmp_path / "table.txt").write_text("rows")
    ok = subprocess.run([sys.executable, "-c", DEFERRED_JOB, str(store), "ok"], capture_output=True, text=True, env=ENV)
    assert ok.returncode == 0, ok.stderr
    failed = subprocess.run([sys.executable, "-c", DEFERRED_JOB, str(store), "fail"], capture_output=True, text=True,
                            env=ENV)
    assert failed.returncode != 0 and "boom" in failed.stderr
    records = sorted((store / tracking.PENDING_DIR).glob("*.json"))
    assert len(records) == 2
    client = MlflowClient(tracking.tracking_uri(store))
    assert children(client, parent) == []  # nothing written by the jobs themselves

    tracking.finish_invocation("FINISHED", store)
    assert not list((store / tracking.PENDING_DIR).glob("*.json"))
    runs = sorted(children(client, parent), key=lambda r: r.info.start_time)
    assert [r.info.status for r in runs] == ["FINISHED", "FAILED"]
    for run, record in zip(runs, records):
        assert run.data.tags["deferred"] == "true" and "recorded_late" not in run.data.tags
        assert run.data.tags["rule"] == "merge" and run.data.tags["wildcard.alpha"] == "0.000"
        assert run.data.tags["config_hash"] == "abc123" and "version.mlflow" in run.data.tags
        assert run.data.params == {"problem": "dejong", "library.enabled": "False"}
        assert run.data.metrics == {"rows": 200.0, "converged": 186.0}
        assert [a.path for a in client.list_artifacts(run.info.run_id, "tables")] == ["tables/table.txt"]
        assert 0 <= run.info.end_time - run.info.start_time < 60_000  # the job's own times, not the recording's
    assert client.get_run(parent).info.status == "FINISHED"
    assert [j["status"] for j in tracking.tracked_jobs(store)["jobs"]].count("FINISHED") == 1


def test_the_next_invocation_closes_runs_left_running_by_kill_9(tmp_path):
    store = tmp_path / "mlflow"
    parent = start(store)
    proc = subprocess.Popen(
        [sys.executable, "-c", JOB, str(store)], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=ENV
    )
    assert proc.stdout.readline().strip() == "ready", proc.stderr.read()
    proc.kill()  # SIGKILL: nothing in the job can react
    proc.wait(timeout=60)
    client = MlflowClient(tracking.tracking_uri(store))
    assert [r.info.status for r in children(client, parent)] == ["RUNNING"]
    second = start(store)
    assert client.get_run(parent).info.status == "KILLED"
    assert [r.info.status for r in children(client, parent)] == ["KILLED"]
    assert client.get_run(second).info.status == "RUNNING"


@pytest.mark.parametrize("background", [False, True])
def test_a_standalone_run_opened_in_the_background_logs_everything_and_ends_as_in_the_foreground(tmp_path, background):
    """`amorgs design` opens its run in a thread while it solves: params, metrics per step and artifacts all
    reach the run, which ends FINISHED, or KILLED on Ctrl-C, exactly as a run opened in the foreground."""
    store = tmp_path / "mlflow"
    (tmp_path / "a.txt").write_text("artifact")
    with tracking.standalone_run("design x", "exp", store_dir=store, tags={"rule": "design"}, background=background,
                                 params={"alpha": 0.42}) as run:
        run.log_params({"nested": {"k": [1, 2]}})
        for step in (1, 2):
            run.log_metrics({"found": float(step)}, step=step)
        run.log_artifact(tmp_path / "a.txt", "reports")
    with pytest.raises(KeyboardInterrupt):
        with tracking.standalone_run("design y", "exp", store_dir=store, background=background) as run:
            raise KeyboardInterrupt
    client = MlflowClient(tracking.tracking_uri(store))
    exp = client.get_experiment_by_name("exp")
    runs = {r.info.run_name: r for r in client.search_runs([exp.experiment_id])}
    done, stopped = runs["design x"], runs["design y"]
    assert done.info.status == "FINISHED" and stopped.info.status == "KILLED"
    assert done.data.params == {"alpha": "0.42", "nested.k": "[1, 2]"} and done.data.tags["rule"] == "design"
    assert [m.value for m in client.get_metric_history(done.info.run_id, "found")] == [1.0, 2.0]
    assert [a.path for a in client.list_artifacts(done.info.run_id, "reports")] == ["reports/a.txt"]


def test_importing_tracking_and_an_untracked_run_load_no_mlflow():
    code = ("import sys; from pathlib import Path; from amorgs import tracking; run = tracking.JobRun(Path('x')); "
            "run.log_params({'a': 1}); run.log_metrics({'b': 1.0}); run.close('FINISHED'); print('mlflow' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, env=ENV).stdout
    assert out.strip() == "False"


def test_error_status_tells_a_user_stop_from_a_failure(tmp_path):
    log = tmp_path / "snakemake.log"
    log.write_text("Error in rule generate:\n  jobid: 3\n")
    assert tracking.error_status(log) == "FAILED"
    log.write_text("...\nTerminating processes on user request, this might take some time.\n")
    assert tracking.error_status(log) == "KILLED"
    log.write_text("Will exit after finishing currently running jobs (scheduler).\n")
    assert tracking.error_status(log) == "KILLED"
    assert tracking.error_status(None) == "FAILED" and tracking.error_status(tmp_path / "missing.log") == "FAILED"
    assert tracking.error_status([str(tmp_path / "missing.log"), str(log)]) == "KILLED"  # Snakemake passes a list
    assert tracking.error_status([]) == "FAILED" and tracking.error_status(3) == "FAILED"


def test_resolve_tracking_uri_order(tmp_path, monkeypatch):
    local = tracking.tracking_uri(tmp_path)
    assert local.startswith("sqlite:///") and str(tmp_path) in local
    assert tracking.resolve_tracking_uri(None, tmp_path) == local
    assert tracking.resolve_tracking_uri("http://h:1", tmp_path) == "http://h:1"
    monkeypatch.setenv(tracking.TRACKING_URI_ENV, "http://env:2")
    assert tracking.resolve_tracking_uri("http://h:1", tmp_path) == "http://env:2"


def test_check_outputs_names_a_missing_store(tmp_path, monkeypatch):
    from amorgs.checks import UNTRACKED, _check_tracking
    from amorgs.config import load_config

    cfg = load_config(ROOT / "config" / "smoke.yaml")
    monkeypatch.chdir(tmp_path)  # no results/mlflow here
    assert _check_tracking(cfg) == [UNTRACKED]
    assert "untracked" in UNTRACKED and "--no-mlflow" in UNTRACKED


# ------------------------------------------------------------------------------- a real MLflow server


@pytest.fixture
def mlflow_server(tmp_path):
    """A real ``mlflow server`` on 127.0.0.1 (random free port), stopped with its process group afterwards."""
    port = free_port()
    workdir = tmp_path / "server"
    workdir.mkdir()
    cmd = [sys.executable, "-m", "mlflow", "server", "--host", "127.0.0.1", "--port", str(port), "--workers", "1",
           "--backend-store-uri", f"sqlite:///{workdir / 'server.db'}", "--artifacts-destination", str(workdir / "artifacts")]
    with serving(cmd, port, workdir, workdir / "server.log", {**ENV, "MLFLOW_DISABLE_TELEMETRY": "true", "MLFLOW_SERVER_ENABLE_JOB_EXECUTION": "false"}, "mlflow server") as url:
        yield url


def _tracked_job(store: Path, tmp_path: Path) -> None:
    (tmp_path / "fig.png").write_bytes(b"\x89PNG\r\n\x1a\n")
    with tracking.job_run("filter", {"problem": "dejong"}, store) as run:
        run.log_metrics({"rows": 7.0})
        run.log_artifact(tmp_path / "fig.png", "figures")


@pytest.mark.slow
def test_config_and_environment_tracking_uri_reach_a_real_server(tmp_path, mlflow_server, monkeypatch):
    # config mlflow.tracking_uri
    store = tmp_path / "a" / "mlflow"
    config = {**CONFIG, "mlflow": {**CONFIG["mlflow"], "tracking_uri": mlflow_server}}
    parent = start(store, config=config)
    _tracked_job(store, tmp_path)
    tracking.finish_invocation("FINISHED", store)
    assert not (store / tracking.DB_NAME).exists()  # nothing went to the local SQLite store
    client = MlflowClient(mlflow_server)
    assert client.get_run(parent).info.status == "FINISHED"
    (job,) = children(client, parent)
    assert job.data.metrics["rows"] == 7.0
    assert [a.path for a in client.list_artifacts(job.info.run_id, "figures")] == ["figures/fig.png"]
    assert tracking.tracked_jobs(store)["parent_status"] == "FINISHED"

    # MLFLOW_TRACKING_URI wins over the config (here: a bogus address that would fail)
    monkeypatch.setenv(tracking.TRACKING_URI_ENV, mlflow_server)
    store = tmp_path / "b" / "mlflow"
    config = {**CONFIG, "mlflow": {**CONFIG["mlflow"], "tracking_uri": "http://127.0.0.1:9"}}
    parent = start(store, config=config)
    _tracked_job(store, tmp_path)
    tracking.finish_invocation("FINISHED", store)
    assert client.get_run(parent).info.status == "FINISHED" and len(children(client, parent)) == 1
