"""The MLflow mirror of the workflow — the only module that imports mlflow.

Files under ``results/`` are the source of truth; MLflow mirrors parameters, metrics and figures so runs
can be browsed and compared.  Layout of the store (``results/mlflow/``)::

    mlflow.db          SQLite tracking store, URI ``sqlite:///<absolute path>/mlflow.db?timeout=60``
    artifacts/         artifact root of the experiment (figures, configs)
    invocation.json    the current workflow invocation: experiment, parent run id, config hash, git commit
    pending/           the record of each deferred job, and of each job that finished while its tracking failed
                       (disk full, a lost database): params, metrics, artifact paths, times and status, written
                       into a run when the invocation ends (or by the next one)
    .lock              serialises every write (see below)

The tracking URI is config ``mlflow.tracking_uri`` (``null``: the SQLite store above), overridden by the
``MLFLOW_TRACKING_URI`` environment variable (:func:`resolve_tracking_uri`); ``invocation.json`` and ``.lock``
stay under ``results/mlflow/`` whichever server holds the runs.

One *parent* run per workflow invocation (:func:`start_invocation` in Snakemake's ``onstart``, closed by
:func:`finish_invocation` in ``onsuccess``/``onerror``) and one *child* run per job (:func:`job_run`), tagged
with the rule, its wildcards, the config hash, the git commit and the package versions.  A job that does
seconds of work (``job_run(..., deferred=True)``: a merge, a De Jong shard) does not open its run itself —
MLflow's import and a run in the SQLite store cost ≈ 4.5 s wall of a 1.5 s job — but keeps the same record
(params, metrics, artifact paths, start and end times, status) under ``pending/``; :func:`finish_invocation`
writes every record into a child run of the invocation, with the job's own times, and removes it.  Jobs log the tables
they read as MLflow datasets (:meth:`JobRun.log_dataset`: name, digest, schema and row count, not a copy) and
trained checkpoints as MLflow logged models whose metrics are linked to them (:meth:`JobRun.start_model`).

Killed runs: a job killed by SIGTERM or SIGINT ends its child run KILLED; a workflow stopped by the user
(Ctrl-C, or SIGTERM to Snakemake) ends its parent run KILLED (:func:`error_status`), any other failure FAILED;
a job whose Snakemake is killed outright ends too, its run KILLED (:mod:`amorgs.lifeline`); and a run still
left RUNNING (``kill -9`` of the job itself) is closed KILLED by the next invocation, so a rerun adds exactly
one FINISHED run per job.

Concurrency: SQLite returns "database is locked" without waiting when a read transaction must be promoted to
a write while another process writes, which MLflow's own busy timeout cannot prevent.  Every write to the
store therefore holds an exclusive ``flock`` on ``.lock``: writes take milliseconds, jobs minutes.

Failure policy: a job never fails because of tracking.  A missing store or an MLflow error prints one
warning to the job's log and the job goes on untracked — but a job of a tracked invocation keeps what it logged
(params, metrics, artifact paths) and, when it finishes while its tracking failed, leaves that record under
``pending/``; the next invocation writes each record into a FINISHED run under its own parent (tag
``recorded_late``) and removes it, so ``amorgs check-outputs`` sees the job without a rerun of its work.  Where
not even that record can be written (the disk is full), the job fails, so Snakemake removes its outputs and the
next invocation reruns it.

MLflow is imported where it is used, not with this module (≈ 2–3 s): an untracked job never loads it, and
:func:`standalone_run` can open its run in the background while the caller works (``amorgs design``).
"""

from __future__ import annotations

import datetime as _dt
import fcntl
import json
import os
import shutil
import signal
import socket
import tempfile
import threading
import subprocess
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from importlib import metadata
from pathlib import Path
from typing import TYPE_CHECKING

from amorgs.data.io import read_json, write_json

if TYPE_CHECKING:
    from mlflow.tracking import MlflowClient

os.environ.setdefault("MLFLOW_DISABLE_TELEMETRY", "true")

#: The store, relative to the repository root (the workflow's working directory).
STORE_DIR = Path("results/mlflow")
DB_NAME = "mlflow.db"
INVOCATION_FILE = "invocation.json"
#: Records of jobs that finished while their tracking failed (:meth:`JobRun.close`, :func:`_record_pending`).
PENDING_DIR = "pending"

#: Distributions whose versions tag every run.
VERSIONED_PACKAGES = ("amorgs", "numpy", "scipy", "pandas", "pyarrow", "torch", "casadi", "snakemake", "mlflow")

#: The experiment tag by which the MLflow UI tells model training from GenAI experiments.
EXPERIMENT_KIND_TAG = "mlflow.experimentKind"

_MAX_BATCH = 900  # MLflow's log_batch accepts at most 1000 metrics


#: The environment variable that overrides config ``mlflow.tracking_uri`` (MLflow's own name for it).
TRACKING_URI_ENV = "MLFLOW_TRACKING_URI"


def tracking_uri(store_dir: str | Path = STORE_DIR) -> str:
    """The explicit SQLite URI of the store (absolute path; pysqlite waits up to 60 s on a busy file)."""
    return f"sqlite:///{(Path(store_dir) / DB_NAME).resolve()}?timeout=60"


def resolve_tracking_uri(configured: str | None = None, store_dir: str | Path = STORE_DIR) -> str:
    """``$MLFLOW_TRACKING_URI`` if set, else ``configured`` (config ``mlflow.tracking_uri``), else the SQLite store."""
    return os.environ.get(TRACKING_URI_ENV) or configured or tracking_uri(store_dir)


def error_status(snakemake_log: str | Path | list | None) -> str:
    """The parent run's status for Snakemake's ``onerror``: KILLED if the user stopped the workflow, else FAILED.

    Snakemake logs "Terminating processes on user request" after Ctrl-C and "Will exit after finishing currently
    running jobs" after SIGTERM; ``snakemake_log`` is what ``onerror`` receives as ``log`` (a log file or a list
    of them).  Never raises.
    """
    paths = snakemake_log if isinstance(snakemake_log, (list, tuple)) else [snakemake_log]
    text = ""
    for path in paths:
        try:
            text += Path(path).read_text(errors="replace") if path else ""
        except (OSError, TypeError):
            pass
    user_stop = ("Terminating processes on user request", "Will exit after finishing currently running jobs")
    return "KILLED" if any(marker in text for marker in user_stop) else "FAILED"


def package_versions() -> dict[str, str]:
    """``version.<package>`` → installed version (``python`` included) for every versioned package."""
    out = {"version.python": sys.version.split()[0]}
    for name in VERSIONED_PACKAGES:
        try:
            out[f"version.{name}"] = metadata.version(name)
        except metadata.PackageNotFoundError:
            out[f"version.{name}"] = "not installed"
    return out


def git_state(repo: str | Path = ".") -> dict[str, str]:
    """``git_commit`` (HEAD, or ``unknown`` outside a checkout) and ``git_dirty`` (``true``/``false``)."""

    def git(*args: str) -> str:
        return subprocess.run(["git", *args], cwd=repo, capture_output=True, text=True, check=True).stdout.strip()

    try:
        commit = git("rev-parse", "HEAD")
        dirty = bool(git("status", "--porcelain", "--untracked-files=no"))
    except (OSError, subprocess.CalledProcessError):
        return {"git_commit": "unknown", "git_dirty": "unknown"}
    return {"git_commit": commit, "git_dirty": str(dirty).lower()}


@contextmanager
def _locked(store_dir: Path) -> Iterator[None]:
    """Hold the store's exclusive write lock."""
    store_dir.mkdir(parents=True, exist_ok=True)
    with open(store_dir / ".lock", "a") as fh:
        fcntl.flock(fh, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(fh, fcntl.LOCK_UN)


def _client(uri: str) -> MlflowClient:
    """An MLflow client of ``uri`` (MLflow imported here, on first use)."""
    from mlflow.tracking import MlflowClient

    return MlflowClient(uri)


def _params(flat: dict[str, str]) -> list:
    """MLflow ``Param`` entities of a flat mapping, values cut to MLflow's 6000 characters."""
    from mlflow.entities import Param

    return [Param(k, v[:6000]) for k, v in flat.items()]


def _flatten(mapping: dict, prefix: str = "") -> dict[str, str]:
    out: dict[str, str] = {}
    for key, value in mapping.items():
        name = f"{prefix}{key}"
        if isinstance(value, dict):
            out.update(_flatten(value, f"{name}."))
        else:
            out[name] = json.dumps(value) if isinstance(value, (list, tuple)) else str(value)
    return out


def _warn(what: str, exc: BaseException) -> None:
    print(f"amorgs.tracking: {what} failed, continuing untracked: {type(exc).__name__}: {exc}", file=sys.stderr)


# ---------------------------------------------------------------------------------------- invocations


def start_invocation(
    config: dict,
    config_hash: str,
    experiment: str,
    sources: list[str],
    store_dir: str | Path = STORE_DIR,
    uri: str | None = None,
) -> str | None:
    """Create the store and experiment if needed, open this invocation's parent run, write ``invocation.json``.

    A parent run left RUNNING by a killed earlier invocation, and its RUNNING job runs, are closed as KILLED
    first.  ``config`` is the validated mapping (logged as flattened params and as ``config.yaml``); ``sources``
    are the config files.  The tracking URI is :func:`resolve_tracking_uri` of ``uri`` (default: the config's
    ``mlflow.tracking_uri``).  Returns the parent run id, or ``None`` (with a warning, jobs then run untracked)
    if MLflow fails.
    """
    store = Path(store_dir)
    path = store / INVOCATION_FILE
    previous = read_json(path) if path.exists() else None
    stop_tracking(store)  # until the new parent run exists, jobs would log nowhere
    if uri is None:
        uri = (config.get("mlflow") or {}).get("tracking_uri")
    try:
        with _locked(store):
            run_id = _open_parent_run(store, config, config_hash, experiment, sources, previous, uri)
    except Exception as exc:  # noqa: BLE001 — tracking never fails the workflow
        _warn("opening the workflow run", exc)
        return None
    return run_id


def _close_killed(previous: dict) -> None:
    """Close the previous invocation's parent run and its job runs that are still RUNNING as KILLED."""
    try:
        client = _client(previous["tracking_uri"])
        parent = previous["parent_run_id"]
        children = client.search_runs(
            [previous["experiment_id"]],
            filter_string=f"tags.mlflow.parentRunId = '{parent}' and attributes.status = 'RUNNING'",
            max_results=50000,
        )
        for run_id in [r.info.run_id for r in children] + [parent]:
            if client.get_run(run_id).info.status == "RUNNING":
                client.set_terminated(run_id, "KILLED")
    except Exception:  # noqa: BLE001 — a stale record from a lost store: nothing to close
        pass


def _open_parent_run(
    store: Path,
    config: dict,
    config_hash: str,
    experiment: str,
    sources: list[str],
    previous: dict | None,
    uri: str | None = None,
) -> str:
    uri = resolve_tracking_uri(uri, store)
    client = _client(uri)
    if previous is not None:
        _close_killed(previous)
    exp = client.get_experiment_by_name(experiment)
    # the local store keeps artifacts beside the database; a server decides where its artifacts go
    artifacts = (store / "artifacts").resolve().as_uri() if uri == tracking_uri(store) else None
    exp_id = exp.experiment_id if exp is not None else client.create_experiment(experiment, artifact_location=artifacts)
    if exp is None or exp.tags.get(EXPERIMENT_KIND_TAG) is None:  # the UI then opens on the runs table
        client.set_experiment_tag(exp_id, EXPERIMENT_KIND_TAG, "custom_model_development")
    now = _dt.datetime.now(_dt.timezone.utc).strftime("%Y-%m-%d %H:%M:%S UTC")
    tags = {
        "kind": "workflow",
        "config_hash": config_hash,
        "config_files": " ".join(sources),
        "host": socket.gethostname(),
        **git_state(),
        **package_versions(),
    }
    run_id = client.create_run(exp_id, run_name=f"workflow {now} config {config_hash}", tags=tags).info.run_id
    _record_pending(store, client, exp_id, run_id)
    params = _params(_flatten(config))
    for i in range(0, len(params), 100):
        client.log_batch(run_id, params=params[i : i + 100])
    client.log_dict(run_id, config, "config.yaml")
    invocation = {
        "tracking_uri": uri,
        "experiment_id": exp_id,
        "parent_run_id": run_id,
        "config_hash": config_hash,
        "git_commit": tags["git_commit"],
        "git_dirty": tags["git_dirty"],
    }
    write_json(invocation, store / INVOCATION_FILE)
    return run_id


def _record_pending(store: Path, client, experiment_id: str, parent_run_id: str) -> None:
    """Write each record left under ``pending/`` into a child run of ``parent_run_id`` and remove it: its params,
    metrics and the artifacts that still exist, the job's own start and end times and status, and the
    invocation's identity tags it ran under.  A deferred job's record (:meth:`JobRun.defer`) is tagged
    ``deferred``; the record of a job whose tracking failed ``recorded_late`` with when the job finished.
    Called with the store locked; a record that cannot be written stays for the next call."""
    from mlflow.entities import Metric

    folder = store / PENDING_DIR
    for path in sorted(folder.glob("*.json")) if folder.is_dir() else []:
        run_id = None
        try:
            j = read_json(path)
            wildcards = j["wildcards"]
            tags = {"mlflow.parentRunId": parent_run_id, "kind": "job", "rule": j["rule"],
                    "wildcards": json.dumps(wildcards, sort_keys=True),
                    **{f"wildcard.{k}": str(v) for k, v in wildcards.items()}, **j.get("tags", {})}
            if j.get("deferred"):
                tags["deferred"] = "true"
            else:
                tags["recorded_late"] = j["finished"]
            name = " ".join([j["rule"], *(f"{k}={v}" for k, v in wildcards.items())])
            run_id = client.create_run(experiment_id, start_time=j.get("start_ms"), run_name=name,
                                       tags=tags).info.run_id
            params = _params(j["params"])
            for i in range(0, len(params), 100):
                client.log_batch(run_id, params=params[i : i + 100])
            ts = j.get("end_ms") or int(time.time() * 1000)
            metrics = [Metric(k, v, ts, step) for k, v, step in j["metrics"]]
            for i in range(0, len(metrics), _MAX_BATCH):
                client.log_batch(run_id, metrics=metrics[i : i + _MAX_BATCH])
            for file, artifact_path in j["artifacts"]:
                if Path(file).is_file():
                    client.log_artifact(run_id, file, artifact_path)
            client.set_terminated(run_id, j.get("status", "FINISHED"), end_time=j.get("end_ms"))
            path.unlink()
        except Exception as exc:  # noqa: BLE001 — the record stays for the next invocation
            _warn(f"recording {path.name}", exc)
            if run_id is not None:  # no half-written run beside the one the next call writes
                try:
                    client.delete_run(run_id)
                except Exception:  # noqa: BLE001
                    pass


def stop_tracking(store_dir: str | Path = STORE_DIR) -> None:
    """Remove ``invocation.json`` so that jobs of this invocation run untracked (``mlflow.enabled: false``)."""
    (Path(store_dir) / INVOCATION_FILE).unlink(missing_ok=True)


def invocation_run(store_dir: str | Path = STORE_DIR) -> JobRun:
    """The current invocation's parent run as a :class:`JobRun`, to log what the workflow as a whole made (it is
    not closed here: :func:`finish_invocation` does); untracked when there is none or MLflow fails."""
    store = Path(store_dir)
    path = store / INVOCATION_FILE
    if not path.exists():
        return JobRun(store)
    try:
        inv = read_json(path)
        return JobRun(store, _client(inv["tracking_uri"]), inv["parent_run_id"], inv["experiment_id"])
    except Exception as exc:  # noqa: BLE001
        _warn("opening the workflow run", exc)
        return JobRun(store)


def finish_invocation(status: str, store_dir: str | Path = STORE_DIR) -> None:
    """Write the records under ``pending/`` (the deferred jobs', :func:`_record_pending`) into child runs, then
    close the current parent run with ``status`` (``FINISHED``, ``FAILED``, ``KILLED``); warn, never raise."""
    store = Path(store_dir)
    path = store / INVOCATION_FILE
    if not path.exists():
        return
    try:
        inv = read_json(path)
        with _locked(store):
            client = _client(inv["tracking_uri"])
            _record_pending(store, client, inv["experiment_id"], inv["parent_run_id"])  # the deferred jobs' runs
            client.set_terminated(inv["parent_run_id"], status)
    except Exception as exc:  # noqa: BLE001
        _warn("closing the workflow run", exc)


# ----------------------------------------------------------------------------------------------- jobs


class JobRun:
    """The MLflow child run of one job; every method is a no-op once tracking is off or has failed."""

    def __init__(
        self, store: Path, client: MlflowClient | None = None, run_id: str | None = None, experiment_id: str | None = None
    ):
        self._store = store
        self._client = client
        self.run_id = run_id
        self.experiment_id = experiment_id
        self._metrics: list = []  # mlflow.entities.Metric, queued
        self._model_id: str | None = None
        self._dataset: tuple[str, str] | None = None  # (name, digest) of the training data, linked to metrics
        self._opening: threading.Thread | None = None  # the run being opened in the background (standalone_run)
        #: What a job of a tracked invocation logged (:meth:`expect`), kept to be written later if tracking fails.
        self._journal: dict | None = None
        self._lost = False  # tracking was expected and failed
        self._deferred = False  # the run is written from the journal when the invocation ends

    def expect(self, rule: str, wildcards: dict[str, str], lost: bool = False) -> JobRun:
        """Keep a journal of what this job logs; ``lost``: its run could not even be opened."""
        self._journal = {"rule": rule, "wildcards": wildcards, "params": {}, "metrics": [], "artifacts": []}
        self._lost = lost
        return self

    def defer(self, rule: str, wildcards: dict[str, str], tags: dict[str, str]) -> JobRun:
        """Keep a journal instead of a run: :meth:`close` leaves it under ``pending/`` with the job's times,
        status and ``tags`` (the invocation's identity), and :func:`finish_invocation` writes the run."""
        self.expect(rule, wildcards)
        self._journal.update(tags=tags, deferred=True, start_ms=int(time.time() * 1000))
        self._deferred = True
        return self

    def _opened(self) -> None:
        """Wait until a run opened in the background (:func:`standalone_run`) exists, or failed to."""
        if self._opening is not None:
            self._opening.join()
            self._opening = None

    def _call(self, method: str, *args, **kwargs) -> None:
        self._opened()
        self._send(method, *args, **kwargs)

    def _send(self, method: str, *args, **kwargs) -> None:
        """Call the client's ``method`` on this run under the store's lock (no wait for the opening)."""
        if self._client is None:
            return
        try:
            with _locked(self._store):
                getattr(self._client, method)(self.run_id, *args, **kwargs)
        except Exception as exc:  # noqa: BLE001 — tracking never fails a job
            _warn(method, exc)
            self._client = None
            self._lost = True

    def log_params(self, params: dict) -> None:
        """Log parameters (nested dicts flattened with dots, lists as JSON)."""
        self._opened()
        if self._journal is not None:
            self._journal["params"].update(_flatten(params))
        self._write_params(params)

    def _write_params(self, params: dict) -> None:
        if self._client is None:
            return
        flat = _params(_flatten(params))
        for i in range(0, len(flat), 100):
            self._send("log_batch", params=flat[i : i + 100])

    def log_metrics(self, metrics: dict[str, float], step: int = 0) -> None:
        """Queue numeric metrics at ``step``; they are written in batches, and at the latest on exit.

        Between :meth:`start_model` and :meth:`finish_model` they are linked to that logged model (and to the
        last ``training`` dataset logged).
        """
        if self._journal is not None:
            self._journal["metrics"] += [[k, float(v), step] for k, v in metrics.items() if v is not None]
        if self._client is None and self._opening is None:  # untracked: nothing to write, ever
            return
        from mlflow.entities import Metric

        ts = int(time.time() * 1000)
        name, digest = self._dataset or (None, None)
        self._metrics.extend(
            Metric(k, float(v), ts, step, model_id=self._model_id, dataset_name=name, dataset_digest=digest)
            for k, v in metrics.items()
            if v is not None
        )
        if len(self._metrics) >= _MAX_BATCH:
            self.flush()

    def flush(self) -> None:
        """Write the queued metrics."""
        while self._metrics:
            batch, self._metrics = self._metrics[:_MAX_BATCH], self._metrics[_MAX_BATCH:]
            self._call("log_batch", metrics=batch)

    def log_artifact(self, path: str | Path, artifact_path: str | None = None) -> None:
        """Copy a file (a figure, a report) into the run's artifacts."""
        if self._journal is not None:
            self._journal["artifacts"].append([str(Path(path).resolve()), artifact_path])
        self._call("log_artifact", str(path), artifact_path)

    def log_dataset(self, df, path: str | Path, context: str) -> None:
        """Record a table this job read as an MLflow dataset input with ``context`` (``training``, ``evaluation``).

        Only metadata is stored: the file's name and URI, a digest of the content, the schema and the row
        count, never a copy of the table.
        """
        self._opened()
        if self._client is None:
            return
        try:
            import warnings

            import mlflow.data
            from mlflow.entities import DatasetInput, InputTag

            with warnings.catch_warnings():  # MLflow's own notes on source resolution and pandas deprecations
                warnings.simplefilter("ignore")
                ds = mlflow.data.from_pandas(df, source=Path(path).resolve().as_uri(), name=Path(path).name)
                entity = DatasetInput(ds._to_mlflow_entity(), tags=[InputTag("mlflow.data.context", context)])
        except Exception as exc:  # noqa: BLE001 — tracking never fails a job
            _warn("describing a dataset", exc)
            return
        self._call("log_inputs", datasets=[entity])
        if context == "training":
            self._dataset = (ds.name, ds.digest)

    def start_model(self, name: str, params: dict | None = None) -> None:
        """Create the MLflow logged model ``name`` of this run; metrics logged until :meth:`finish_model` link to it."""
        self._opened()
        if self._client is None:
            return
        try:
            with _locked(self._store):
                model = self._client.create_logged_model(
                    self.experiment_id,
                    name=name,
                    source_run_id=self.run_id,
                    params={k: v[:6000] for k, v in _flatten(params or {}).items()},
                    model_type="pytorch-checkpoint",
                )
            self._model_id = model.model_id
        except Exception as exc:  # noqa: BLE001
            _warn("create_logged_model", exc)

    def finish_model(self, checkpoint: str | Path, step: int) -> None:
        """Upload ``checkpoint`` as the logged model's artifact, mark it READY and record it as this run's output
        at ``step``; also copy it under the run's ``models/`` artifacts."""
        self.flush()
        model_id, self._model_id = self._model_id, None
        self.log_artifact(checkpoint, "models")
        if self._client is None or model_id is None:
            return
        from mlflow.entities import LoggedModelOutput

        try:
            with tempfile.TemporaryDirectory() as tmp:
                shutil.copy(checkpoint, tmp)
                with _locked(self._store):
                    self._client.log_model_artifacts(model_id, tmp)
            with _locked(self._store):
                self._client.finalize_logged_model(model_id, "READY")
                self._client.log_outputs(self.run_id, [LoggedModelOutput(model_id, step)])
        except Exception as exc:  # noqa: BLE001
            _warn("logging the model", exc)

    def close(self, status: str) -> None:
        """Flush the metrics and end the run with ``status`` (``FINISHED``, ``FAILED``, ``KILLED``)."""
        self._opened()
        self.flush()
        if self._model_id is not None and self._client is not None:  # a model whose training never finished
            try:
                with _locked(self._store):
                    self._client.finalize_logged_model(self._model_id, "FAILED")
            except Exception as exc:  # noqa: BLE001
                _warn("finalize_logged_model", exc)
            self._model_id = None
        self._call("set_terminated", status)
        if self._deferred or (self._lost and self._journal is not None and status == "FINISHED"):
            self._leave_pending(status)

    def _leave_pending(self, status: str) -> None:
        """Write this job's journal under ``pending/`` (:func:`_record_pending`)."""
        j = self._journal
        key = _dt.datetime.now(_dt.timezone.utc).strftime("%Y%m%dT%H%M%S%f")
        name = f"{j['rule']}-{'-'.join(f'{k}={v}' for k, v in sorted(j['wildcards'].items()))}-{key}.json"
        try:
            write_json({**j, "finished": key, "status": status, "end_ms": int(time.time() * 1000)},
                       self._store / PENDING_DIR / name.replace("/", "_"))
            if not self._deferred:
                print(f"amorgs.tracking: {j['rule']} finished untracked; its record waits in "
                      f"{self._store / PENDING_DIR} for the next invocation", file=sys.stderr)
        except Exception as exc:  # noqa: BLE001 — without a record the job would stay untracked for good
            raise SystemExit(f"amorgs.tracking: {j['rule']} finished, but neither MLflow nor {self._store / PENDING_DIR} "
                             f"could record it ({type(exc).__name__}: {exc}); the job fails so that the next "
                             "invocation reruns it") from None


def _open_job_run(rule: str, wildcards: dict[str, str], store: Path, deferred: bool = False) -> JobRun:
    """A child run under the current invocation (``deferred``: its journal, :meth:`JobRun.defer`), or an
    untracked :class:`JobRun`."""
    inv = read_json(store / INVOCATION_FILE) if (store / INVOCATION_FILE).exists() else None
    if inv is None:
        print(f"amorgs.tracking: no MLflow invocation under {store}; {rule} runs untracked", file=sys.stderr)
        return JobRun(store)
    identity = {
        "config_hash": inv["config_hash"],
        "git_commit": inv["git_commit"],
        "git_dirty": inv["git_dirty"],
        "host": socket.gethostname(),
        **package_versions(),
    }
    if deferred:
        return JobRun(store).defer(rule, wildcards, identity)
    if inv["tracking_uri"] == tracking_uri(store) and not (store / DB_NAME).exists():
        print(f"amorgs.tracking: the MLflow store under {store} is gone; {rule} runs untracked", file=sys.stderr)
        return JobRun(store).expect(rule, wildcards, lost=True)
    try:
        client = _client(inv["tracking_uri"])
        tags = {
            "mlflow.parentRunId": inv["parent_run_id"],
            "kind": "job",
            "rule": rule,
            "wildcards": json.dumps(wildcards, sort_keys=True),
            **{f"wildcard.{k}": str(v) for k, v in wildcards.items()},
            **identity,
        }
        name = " ".join([rule, *(f"{k}={v}" for k, v in wildcards.items())])
        with _locked(store):
            run = client.create_run(inv["experiment_id"], run_name=name, tags=tags)
        return JobRun(store, client, run.info.run_id, inv["experiment_id"]).expect(rule, wildcards)
    except Exception as exc:  # noqa: BLE001 — tracking never fails a job
        _warn("opening the job run", exc)
        return JobRun(store).expect(rule, wildcards, lost=True)


@contextmanager
def job_run(rule: str, wildcards: dict[str, str], store_dir: str | Path = STORE_DIR,
            deferred: bool = False) -> Iterator[JobRun]:
    """The child run of one job under the current invocation's parent run (``deferred``: written from the job's
    journal when the invocation ends, :meth:`JobRun.defer` — for jobs of seconds, which MLflow would slow 4×).

    Untracked (every :class:`JobRun` method a no-op) when there is no ``invocation.json`` (tracking disabled)
    or no database (the store was removed), or when MLflow fails.  The run ends FINISHED; KILLED if the job is
    interrupted (SIGINT, or SIGTERM, which raises :class:`Killed` here; the process exits 128 + signal); FAILED
    if it raises anything else.
    """
    with _closing(_open_job_run(rule, wildcards, Path(store_dir), deferred)) as job:
        yield job


@contextmanager
def _closing(job: JobRun) -> Iterator[JobRun]:
    """End ``job`` FINISHED, KILLED (SIGINT, or SIGTERM turned into :class:`Killed`) or FAILED."""
    previous = _catch_sigterm()
    try:
        yield job
    except (KeyboardInterrupt, Killed):
        job.close("KILLED")
        raise
    except BaseException:
        job.close("FAILED")
        raise
    finally:
        if previous is not None:
            signal.signal(signal.SIGTERM, previous)
    job.close("FINISHED")


@contextmanager
def standalone_run(
    name: str,
    experiment: str,
    store_dir: str | Path = STORE_DIR,
    uri: str | None = None,
    tags: dict | None = None,
    background: bool = False,
    params: dict | None = None,
) -> Iterator[JobRun]:
    """One top-level MLflow run outside any workflow invocation (e.g. ``amorgs design``), with the same
    :class:`JobRun` API and end states as :func:`job_run`; tagged with the git state and package versions.

    It never reads or writes ``invocation.json``, so it can run beside a workflow on the same store.  The
    tracking URI is :func:`resolve_tracking_uri` of ``uri``.  Untracked (with a warning) if MLflow fails.
    ``params``: logged as the run is created (:meth:`JobRun.log_params`).  ``background``: MLflow is loaded and
    the run created (with its params) in a thread, and the caller goes on at once; every method of the run
    waits for it first — metrics are queued meanwhile — so nothing is lost and the end states are the same.
    """
    store = Path(store_dir)
    job = JobRun(store)

    def open_run() -> None:
        try:
            resolved = resolve_tracking_uri(uri, store)
            client = _client(resolved)
            with _locked(store):
                exp = client.get_experiment_by_name(experiment)
                artifacts = (store / "artifacts").resolve().as_uri() if resolved == tracking_uri(store) else None
                exp_id = (exp.experiment_id if exp is not None
                          else client.create_experiment(experiment, artifact_location=artifacts))
                run_tags = {"kind": "standalone", "host": socket.gethostname(), **git_state(), **package_versions(),
                            **(tags or {})}
                run = client.create_run(exp_id, run_name=name, tags=run_tags)
            job._client, job.run_id, job.experiment_id = client, run.info.run_id, exp_id
        except Exception as exc:  # noqa: BLE001 — tracking never fails the command
            _warn(f"opening the {name} run", exc)
            return
        job._write_params(params or {})

    if background:
        job._opening = threading.Thread(target=open_run, name="amorgs-mlflow-open", daemon=True)
        job._opening.start()
    else:
        open_run()
    with _closing(job) as opened:
        yield opened


class Killed(SystemExit):
    """Raised in a tracked job by SIGTERM, so that its run can be closed; exits with status 128 + signal."""

    def __init__(self, signum: int):
        super().__init__(128 + signum)
        self.signum = signum


def _raise_killed(signum: int, frame: object) -> None:
    raise Killed(signum)


def _catch_sigterm():
    """Turn SIGTERM into :class:`Killed` (main thread only); return the previous handler, or ``None``."""
    if threading.current_thread() is not threading.main_thread():
        return None
    try:
        return signal.signal(signal.SIGTERM, _raise_killed)
    except ValueError:
        return None


# ------------------------------------------------------------------------------------------- queries


def tracked_jobs(store_dir: str | Path = STORE_DIR) -> dict:
    """What the store holds for the current invocation's experiment, for checks::

        {"parent_status": status of the current parent run,
         "jobs": [{"rule", "wildcards", "status", "metrics", "artifacts"}, ...]}   # every job run, any invocation

    Raises ``FileNotFoundError`` if there is no invocation or the local database is gone.
    """
    store = Path(store_dir)
    inv = read_json(store / INVOCATION_FILE)
    if inv["tracking_uri"] == tracking_uri(store) and not (store / DB_NAME).exists():
        raise FileNotFoundError(store / DB_NAME)
    client = _client(inv["tracking_uri"])
    with _locked(store):
        parent = client.get_run(inv["parent_run_id"])
        runs = client.search_runs([inv["experiment_id"]], filter_string="tags.kind = 'job'", max_results=50000)
        jobs = [
            {
                "rule": r.data.tags.get("rule"),
                "wildcards": json.loads(r.data.tags.get("wildcards", "{}")),
                "status": r.info.status,
                "metrics": dict(r.data.metrics),
                "artifacts": [a.path for a in client.list_artifacts(r.info.run_id, "figures")],
            }
            for r in runs
        ]
    return {"parent_status": parent.info.status, "jobs": jobs}


#: Environment defaults of the MLflow UI this project starts (:func:`ui_command`): MLflow's job-execution engine
#: (GenAI jobs; nothing here submits any) stays off — 7 processes instead of 15 and ≈ 5 CPU-s less at start.
#: A variable already set in the environment wins.
SERVER_ENV = {"MLFLOW_SERVER_ENABLE_JOB_EXECUTION": "false"}


def ui_command(store_dir: str | Path = STORE_DIR, host: str = "127.0.0.1", port: int = 5000) -> list[str]:
    """The command line of the MLflow UI on this store (run it with :data:`SERVER_ENV` under the environment)."""
    return [sys.executable, "-m", "mlflow", "ui", "--backend-store-uri", tracking_uri(store_dir), "--host", host, "--port", str(port)]
