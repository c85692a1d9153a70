"""The workflow on a real SLURM cluster, through the cluster profile and the pinned executor plugin.

``scripts/local-slurm start`` runs a one-node cluster on this machine (Debian's slurmctld, slurmd and munge,
no accounting database); cluster jobs log to a real ``mlflow server`` on 127.0.0.1 through config
``mlflow.tracking_uri``.  The smoke config must give the tables of a local run; a job cancelled with
``scancel`` and a node set DOWN then RESUMEd must lose and duplicate no rows.

Opt-in with ``AMORGS_SLURM_TESTS=1``, which ``.ci/run`` sets (they install and start system daemons).  Starting
SLURM needs root (and apt-get when it is not installed): without them every test here skips and says why.  Under
pytest-xdist, tests/conftest.py runs them on one worker after the local smoke test, one at a time, so that in CI
the local smoke run they compare with (``AMORGS_SMOKE_WORKDIR``) has finished, and no test sets the node DOWN
under another's jobs.
"""

from __future__ import annotations

import getpass
import json
import os
import re
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pandas as pd
import pytest
import yaml

from mlflow_serving import free_port, serving
from test_workflow import ROOT, SMOKE_WORKDIR, SNAKEMAKE, _interrupt_config, _tables, smoke_config, workdir

pytestmark = pytest.mark.slow  # and on one xdist worker, after the local smoke run, one at a time: tests/conftest.py

ENV = {k: v for k, v in os.environ.items() if k not in ("PYTEST_CURRENT_TEST", "MLFLOW_TRACKING_URI")}
LOCAL_SLURM = str(ROOT / "scripts" / "local-slurm")
#: The cluster profile, plus what a cluster without an accounting database needs: job states from squeue
#: (slurm.conf keeps finished jobs for MinJobAge), no account; and a first status check after 10 s, not 40.
SLURM = ["--workflow-profile", "workflow/profiles/slurm", "--slurm-status-command", "squeue", "--slurm-no-account",
         "--slurm-init-seconds-before-status-checks", "10"]


def _slurm_missing_reason() -> str | None:
    if os.environ.get("AMORGS_SLURM_TESTS") != "1":
        # They install (apt-get) and start system daemons as root: .ci/run turns them on, a developer opts in.
        return "the cluster tests are opt-in (.ci/run turns them on): AMORGS_SLURM_TESTS=1 (root, Debian; scripts/local-slurm)"
    if shutil.which("sbatch") and shutil.which("slurmctld") and shutil.which("slurmd"):
        return None if os.geteuid() == 0 else "starting the SLURM daemons needs root"
    if os.geteuid() != 0 or not shutil.which("apt-get"):
        return "SLURM is not installed, and installing it needs root and apt-get"
    return None


@pytest.fixture(scope="module")
def cluster():
    """The local cluster: left running if it already was (CI starts it), else started here and stopped after."""
    reason = _slurm_missing_reason()
    if reason:
        pytest.skip(reason)
    was_up = subprocess.run([LOCAL_SLURM, "status"], capture_output=True).returncode == 0
    res = subprocess.run([LOCAL_SLURM, "start"], capture_output=True, text=True, timeout=600)
    assert res.returncode == 0, res.stdout + res.stderr
    yield
    if not was_up:
        subprocess.run([LOCAL_SLURM, "stop"], check=True, timeout=120)


@pytest.fixture(scope="module")
def mlflow_server(tmp_path_factory):
    """A real ``mlflow server`` on 127.0.0.1 (free port, own SQLite store), stopped afterwards."""
    where = tmp_path_factory.mktemp("mlflow-server")
    port = free_port()
    cmd = [sys.executable, "-m", "mlflow", "server", "--host", "127.0.0.1", "--port", str(port), "--workers", "2",
           "--backend-store-uri", f"sqlite:///{where / 'server.db'}", "--artifacts-destination", str(where / "artifacts")]
    with serving(cmd, port, where, where / "server.log", {**ENV, "MLFLOW_DISABLE_TELEMETRY": "true", "MLFLOW_SERVER_ENABLE_JOB_EXECUTION": "false"}, "mlflow server") as url:
        yield url


def snakemake(wd: Path, *args: str, timeout: float = 3600) -> subprocess.CompletedProcess:
    """Run Snakemake in ``wd``; past ``timeout`` it is killed and the SLURM jobs it left are cancelled."""
    try:
        return subprocess.run([SNAKEMAKE, *args], cwd=wd, capture_output=True, text=True, timeout=timeout, env=ENV)
    except subprocess.TimeoutExpired:
        subprocess.run(["scancel", "--user", getpass.getuser()], check=False)
        raise


def slurm_jobs(out: str) -> dict[str, dict[str, str]]:
    """SLURM job id → its ``scontrol show job`` fields, for every job the plugin reports submitting in ``out``."""
    jobs = {}
    for jobid in re.findall(r"has been submitted with SLURM jobid (\d+)", out):
        line = subprocess.run(["scontrol", "-o", "show", "job", jobid], capture_output=True, text=True).stdout
        jobs[jobid] = dict(f.split("=", 1) for f in line.split() if "=" in f)
    return jobs


def submitted_job(cfg, remote, comment: str):
    """(rule, resources) of the expected job whose SLURM comment (set by the plugin) is ``comment``:
    ``rule_<rule>`` or ``rule_<rule>_wildcards_<values joined by _>``, e.g. ``rule_generate_wildcards_cr3bp_0.150_0``.
    The resources are the workflow's own (:func:`amorgs.steps.job_resources`), so a new rule needs no entry here."""
    from itertools import permutations

    from amorgs.steps import job_resources

    for rule, w in remote:
        for values in permutations(w.values()) if w else [()]:
            if comment == (f"rule_{rule}_wildcards_{'_'.join(values)}" if values else f"rule_{rule}"):
                return rule, job_resources(rule, cfg, w)
    raise AssertionError(f"no expected job has the SLURM comment {comment!r}")


def dry_run(wd: Path) -> str:
    """What ``snakemake -n`` says about the smoke config in ``wd``."""
    res = snakemake(wd, "-n", "--configfile", "config/smoke.yaml")
    return res.stdout + res.stderr


def local_run(tmp_path: Path, cfg: dict, *targets: str) -> Path:
    """A local run of ``cfg`` (MLflow off: tracking never changes a table) in ``tmp_path/local``."""
    wd = workdir(tmp_path, {**cfg, "mlflow": {**cfg["mlflow"], "enabled": False}}, name="local")
    res = snakemake(wd, *targets, "--configfile", "config/test.yaml")
    assert res.returncode == 0, res.stdout[-3000:] + res.stderr[-3000:]
    return wd


def assert_same_tables(got: Path, want: Path) -> None:
    """Every Parquet table under results/ identical, timing columns aside (no row lost or duplicated)."""
    got_tables, want_tables = _tables(got), _tables(want)
    assert sorted(got_tables) == sorted(want_tables)
    for name, df in want_tables.items():
        pd.testing.assert_frame_equal(got_tables[name], df, check_exact=True, obj=name)


def test_smoke_workflow_on_slurm_matches_a_local_run(cluster, mlflow_server, tmp_path):
    from mlflow.tracking import MlflowClient

    from amorgs.config import load_config
    from amorgs.steps import expected_jobs

    cfg = smoke_config()
    cfg["mlflow"]["tracking_uri"] = mlflow_server
    wd = workdir(tmp_path, cfg)
    t0 = time.monotonic()
    res = snakemake(wd, *SLURM, "--configfile", "config/test.yaml")
    out = res.stdout + res.stderr
    assert res.returncode == 0, out[-5000:]
    print(f"smoke workflow on SLURM: {time.monotonic() - t0:.0f} s")

    # every job not in `localrules` went through sbatch, with the resources its config section gives
    typed = load_config(wd / "config" / "test.yaml")
    local = {"merge", "filter", "fig02_foxholes", "fig16_dejong_predictions", "ablation_report"}
    jobs = slurm_jobs(out)  # scontrol still knows finished jobs for an hour (MinJobAge)
    remote = [(rule, w) for rule, w in expected_jobs(typed) if rule not in local]
    assert len(jobs) == len(remote)
    for fields in jobs.values():
        assert fields["JobState"] == "COMPLETED", fields
        rule, job = submitted_job(typed, remote, fields["Comment"])
        assert (fields["MinMemoryNode"], fields["TimeLimit"], fields["NumCPUs"]) == (
            f"{job.mem_mb}M", f"00:{job.runtime_min:02d}:00", str(job.threads)), fields
    assert sorted(submitted_job(typed, remote, f["Comment"])[0] for f in jobs.values()) == sorted(
        rule for rule, _ in remote)

    check = [sys.executable, "-m", "amorgs", "check-outputs", "--config"]
    for config_file in ("config/test.yaml", "config/smoke.yaml"):  # the same outputs; runs on the server either way
        res = subprocess.run([*check, config_file], cwd=wd, capture_output=True, text=True, env=ENV)
        assert res.returncode == 0, res.stdout + res.stderr

    # every job is a FINISHED run on the server, under one FINISHED workflow run; no SQLite store beside the results
    client = MlflowClient(mlflow_server)
    exp = client.get_experiment_by_name(cfg["mlflow"]["experiment"])
    (parent,) = client.search_runs([exp.experiment_id], "tags.kind = 'workflow'")
    assert parent.info.status == "FINISHED"
    children = client.search_runs([exp.experiment_id], f"tags.mlflow.parentRunId = '{parent.info.run_id}'",
                                  max_results=1000)
    assert sorted((c.data.tags["rule"], c.data.tags["wildcards"]) for c in children) == sorted(
        (rule, json.dumps(w, sort_keys=True)) for rule, w in expected_jobs(typed))
    assert {c.info.status for c in children} == {"FINISHED"}
    assert not (wd / "results" / "mlflow" / "mlflow.db").exists()

    # the tables of a local run of the same config: the suite's smoke run (CI) or one made here
    reference = Path(SMOKE_WORKDIR) if SMOKE_WORKDIR else None
    if reference is None or not reference.is_dir() or "Nothing to be done" not in dry_run(reference):
        reference = local_run(tmp_path, smoke_config())
    assert_same_tables(wd, reference)


def squeue() -> dict[str, tuple[str, str]]:
    """SLURM job id → (state, comment) of every job slurmctld still holds (finished ones for MinJobAge)."""
    out = subprocess.run(["squeue", "--states=all", "--noheader", "--format=%i|%T|%k"], capture_output=True,
                         text=True, check=True).stdout
    return {i: (state, comment) for i, state, comment in (line.split("|", 2) for line in out.splitlines())}


def slurm_comment(run) -> str:
    """The comment the plugin gives the SLURM job of an MLflow job run (of generate, merge or filter: their
    wildcards in the order of their output paths)."""
    values = [run.data.tags[f"wildcard.{k}"] for k in ("problem", "alpha", "shard") if f"wildcard.{k}" in run.data.tags]
    return f"rule_{run.data.tags['rule']}_wildcards_" + "_".join(values)


def running_tracked_job(client, experiment: str, proc: subprocess.Popen, exclude: set[str]) -> str:
    """The SLURM id of a job, not in ``exclude``, that is RUNNING in SLURM and whose MLflow run is RUNNING
    (so it is mid-solve, past its start-up); waits up to 5 min."""
    deadline = time.monotonic() + 300
    while True:
        assert proc.poll() is None, "the workflow ended before a job could be hit"
        assert time.monotonic() < deadline, "no tracked job was running"
        exp = client.get_experiment_by_name(experiment)
        runs = client.search_runs([exp.experiment_id], "tags.kind = 'job' and attributes.status = 'RUNNING'") if exp else []
        running = {slurm_comment(r) for r in runs}
        for jobid, (state, comment) in squeue().items():
            if state == "RUNNING" and comment in running and jobid not in exclude:
                return jobid
        time.sleep(1)


def test_a_cancelled_job_and_a_down_node_lose_and_duplicate_no_rows(cluster, mlflow_server, tmp_path):
    from mlflow.tracking import MlflowClient

    cfg = _interrupt_config()
    # ≈ 10 s of solving per job, so that each job is hit mid-solve: with 300 starts (1.6 s of solving, a 14-s job on
    # a quiet machine) the test caught a job in the few seconds its MLflow run was open only by luck
    cfg["problems"]["dejong"]["generate"].update(shards=3, starts_per_shard=2000)
    cfg["mlflow"].update(experiment="amorgs-slurm-faults", tracking_uri=mlflow_server)
    target = ["results/dejong/high_quality.parquet", "--configfile", "config/test.yaml"]
    reference = local_run(tmp_path, cfg, *target)

    wd = workdir(tmp_path, cfg, name="slurm")
    client = MlflowClient(mlflow_server)
    with open(wd / "snakemake.log", "w") as log:
        proc = subprocess.Popen([SNAKEMAKE, *SLURM, *target], cwd=wd, stdout=log, stderr=subprocess.STDOUT,
                                start_new_session=True, env=ENV)
    try:
        cancelled = running_tracked_job(client, "amorgs-slurm-faults", proc, set())
        subprocess.run(["scancel", cancelled], check=True)
        downed = running_tracked_job(client, "amorgs-slurm-faults", proc, {cancelled})
        subprocess.run(["scontrol", "update", "nodename=localhost", "state=down", "reason=amorgs-test"], check=True)
        try:
            deadline = time.monotonic() + 120
            while squeue()[downed][0] == "RUNNING":
                assert time.monotonic() < deadline, "the job on the DOWN node kept running"
                time.sleep(1)
            hit = {cancelled: squeue()[cancelled][0], downed: squeue()[downed][0]}
            assert "down" in subprocess.run(["sinfo", "-h", "-o", "%T"], capture_output=True, text=True).stdout
        finally:
            subprocess.run(["scontrol", "update", "nodename=localhost", "state=resume"], check=True)
        proc.wait(timeout=1200)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGTERM)
            proc.wait()
    # the cancelled job ended CANCELLED; the one on the DOWN node failed or went back to the queue (requeued)
    assert hit[cancelled] == "CANCELLED" and hit[downed] in ("NODE_FAIL", "PENDING", "REQUEUED", "REQUEUE_HOLD"), hit

    # whatever the first invocation made of it (the profile retries a failed job once), a rerun completes it
    assert snakemake(wd, "--unlock", "--configfile", "config/test.yaml").returncode == 0
    res = snakemake(wd, *SLURM, *target)
    assert res.returncode == 0, (wd / "snakemake.log").read_text()[-3000:] + res.stdout[-3000:] + res.stderr[-3000:]
    assert_same_tables(wd, reference)
    assert len(pd.read_parquet(wd / "results" / "dejong" / "solutions" / "alpha=0.200.parquet")) == 3 * 2000

    # the cancelled job's run ended KILLED; every job has a FINISHED run
    exp = client.get_experiment_by_name("amorgs-slurm-faults")
    runs = client.search_runs([exp.experiment_id], "tags.kind = 'job'", max_results=1000)
    comment = squeue()[cancelled][1]
    statuses = {}
    for r in runs:
        statuses.setdefault(slurm_comment(r), []).append(r.info.status)
    assert "KILLED" in statuses[comment], statuses
    assert all("FINISHED" in s for s in statuses.values()), statuses
    # and no process of any of these jobs is left behind (proctrack/pgid kills a cancelled job's whole group)
    assert subprocess.run(["pgrep", "-f", str(wd)], capture_output=True).returncode == 1


def test_library_grow_runs_its_batch_through_the_cluster_profile(cluster, tmp_path, monkeypatch):
    """``amorgs library-grow --profile workflow/profiles/slurm``: one batch of a tiny library config, each
    shard an sbatch job, then exported into the library."""
    from amorgs.data.library import read_manifest

    from config_files import mapping

    cfg = mapping("library")
    cfg["mlflow"]["enabled"] = False
    cfg["problems"]["dejong"]["enabled"] = cfg["dejong_cvae"]["enabled"] = False
    cfg["problems"]["cr3bp"]["alphas"] = {"train": [0.6], "test": [0.9]}
    cfg["problems"]["cr3bp"]["generate"].update(shards=1, starts_per_shard=1, workers=1)
    cfg["problems"]["cr3bp"]["solver"]["max_iter"] = 20
    (tmp_path / "library.yaml").write_text(yaml.safe_dump(cfg))
    monkeypatch.chdir(ROOT)
    before = set(squeue())
    res = subprocess.run(
        [sys.executable, "-m", "amorgs", "library-grow", "--config", str(tmp_path / "library.yaml"), "--library-dir",
         str(tmp_path / "library"), "--new-library", "--workdir", str(tmp_path / "work"), "--profile",
         "workflow/profiles/slurm", "--nice", "0"], capture_output=True, text=True, timeout=900, env=ENV)
    assert res.returncode == 0, res.stdout[-3000:] + res.stderr[-3000:]
    assert read_manifest(tmp_path / "library", "cr3bp")["totals"]["rows"] == 2
    submitted = {comment for jobid, (state, comment) in squeue().items() if jobid not in before and state == "COMPLETED"}
    assert submitted == {"rule_generate_wildcards_cr3bp_0.600_0", "rule_generate_wildcards_cr3bp_0.900_0"}
