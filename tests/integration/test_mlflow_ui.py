"""The MLflow UI, in a real headless Chromium, shows what the workflow tracks.

A tiny tracked job set (one workflow run, two job runs, one with a real PNG figure) goes into a SQLite store;
``amorgs``'s own UI command serves it on 127.0.0.1 (random free port); Chromium (the Debian package; `.ci/run`
installs it) renders the experiment page and the figure's artifact page, and the test reads the rendered DOM
and keeps screenshots under ``tmp_path``.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import urllib.request
from pathlib import Path

import pytest

from amorgs import tracking
from mlflow_serving import free_port, serving

pytestmark = pytest.mark.slow

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
ENV = {k: v for k, v in os.environ.items() if k not in ("PYTEST_CURRENT_TEST", tracking.TRACKING_URI_ENV)}
EXPERIMENT = "amorgs-ui-test"


@pytest.fixture(scope="module")
def tracked_store(tmp_path_factory):
    """A store with one workflow run and its two job runs; ``filter`` logged ``figures/fig99_test.png``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    root = tmp_path_factory.mktemp("ui")
    store = root / "mlflow"
    os.environ.pop(tracking.TRACKING_URI_ENV, None)
    config = {"seed": 1, "mlflow": {"enabled": True, "experiment": EXPERIMENT, "tracking_uri": None}}
    parent = tracking.start_invocation(config, "c0ffee000000", EXPERIMENT, ["config/test.yaml"], store)
    fig, ax = plt.subplots(figsize=(4, 3))
    ax.plot([0, 1, 2], [1, 0, 1])
    ax.set_title("fig99 test figure")
    fig.savefig(root / "fig99_test.png")
    with tracking.job_run("filter", {"problem": "dejong"}, store) as run:
        run.log_metrics({"high_quality": 42.0})
        run.log_artifact(root / "fig99_test.png", "figures")
    with tracking.job_run("generate", {"problem": "dejong", "alpha": "0.200", "shard": "0"}, store) as run:
        run.log_metrics({"converged_fraction": 0.9})
    tracking.finish_invocation("FINISHED", store)
    return {"store": store, "parent": parent, "root": root}


@pytest.fixture(scope="module")
def ui(tracked_store):
    """``amorgs``'s MLflow UI command on the store, on a free port; stopped with its process group."""
    port = free_port()
    log = tracked_store["root"] / "ui.log"
    cmd = tracking.ui_command(tracked_store["store"], port=port)
    with serving(cmd, port, tracked_store["root"], log, {**tracking.SERVER_ENV, **ENV}, "the MLflow UI") as url:
        yield url


def chromium(url: str, out: Path, expect: tuple[str, ...], attempts: int = 4) -> str:
    """Render ``url`` in headless Chromium and return its DOM; save a screenshot to ``out``.

    The single-page app fetches its data after loading, so the page gets 15 s of page time, and again with
    more until every string of ``expect`` is in the DOM (a cold UI answers its first requests slowly).
    """
    if CHROMIUM is None:
        pytest.skip("chromium is not installed (Debian: apt-get install chromium; .ci/run does it as root)")
    dom = ""
    for attempt in range(1, attempts + 1):
        base = [
            CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage", "--hide-scrollbars",
            f"--user-data-dir={out.parent / 'chromium-profile'}", "--window-size=1600,1000",
            f"--virtual-time-budget={15000 * attempt}", "--run-all-compositor-stages-before-draw",
        ]
        dom = subprocess.run([*base, "--dump-dom", url], capture_output=True, text=True, timeout=300).stdout
        if all(e in dom for e in expect):
            break
    subprocess.run([*base, f"--screenshot={out}", url], capture_output=True, timeout=300)
    assert out.is_file() and out.stat().st_size > 10_000, f"no screenshot of {url}"
    return dom


def test_experiment_lists_the_workflow_run_and_its_job_runs(tracked_store, ui, tmp_path):
    from mlflow.tracking import MlflowClient

    client = MlflowClient(tracking.tracking_uri(tracked_store["store"]))
    parent = client.get_run(tracked_store["parent"])
    exp_id = parent.info.experiment_id
    # the experiment's runs table: the workflow run, its job runs folded under it (3 runs in all)
    dom = chromium(f"{ui}/#/experiments/{exp_id}/runs", tmp_path / "experiment_runs.png", ("matching runs",))
    assert EXPERIMENT in dom
    assert parent.info.run_name in dom, "the workflow run is not listed"
    assert "<strong>3</strong> matching runs" in dom
    # the workflow run's page names its job runs
    dom = chromium(f"{ui}/#/experiments/{exp_id}/runs/{parent.info.run_id}", tmp_path / "workflow_run.png", ("Child runs",))
    assert parent.info.run_name in dom and "Finished" in dom
    assert "Child runs" in dom
    for child in ("filter problem=dejong", "generate problem=dejong alpha=0.200 shard=0"):
        assert child in dom, f"job run {child!r} is not shown under the workflow run"


def test_artifact_page_shows_the_figure(tracked_store, ui, tmp_path):
    from mlflow.tracking import MlflowClient

    client = MlflowClient(tracking.tracking_uri(tracked_store["store"]))
    exp_id = client.get_run(tracked_store["parent"]).info.experiment_id
    (job,) = client.search_runs([exp_id], "tags.rule = 'filter'")
    url = f"{ui}/#/experiments/{exp_id}/runs/{job.info.run_id}/artifacts/figures/fig99_test.png"
    dom = chromium(url, tmp_path / "artifact.png", ('alt="figures/fig99_test.png"',))
    assert "filter problem=dejong" in dom
    assert '<img alt="figures/fig99_test.png" src="blob:' in dom, "the figure is not displayed"
    # the image the page shows is the logged PNG
    with urllib.request.urlopen(f"{ui}/get-artifact?path=figures/fig99_test.png&run_uuid={job.info.run_id}") as r:
        assert r.read() == (tracked_store["root"] / "fig99_test.png").read_bytes()
