"""The MLflow mirror of ``amorgs design``: one run per call, opened in the background while the search starts.

Every call to MLflow goes through :mod:`amorgs.tracking` (:func:`~amorgs.tracking.standalone_run`), the only
module that talks to it.  The run (experiment :data:`DESIGN_EXPERIMENT` of the store ``store_dir``) holds the
request and the sampler's provenance as parameters, the running counts of every round and the final summary
as metrics, and the written files as artifacts; it ends FINISHED, KILLED (Ctrl-C, SIGTERM) or FAILED.  MLflow
is loaded and the run created in a thread (≈ 3–6 s on a loaded 2-core machine) while the first round solves.
"""

from __future__ import annotations

import math
from contextlib import AbstractContextManager, nullcontext
from pathlib import Path

from amorgs.alphas import alpha_label

#: The MLflow store of ``amorgs design`` calls: the workflow's store, so that ``amorgs ui`` shows designs beside
#: workflow runs; a design is a standalone run and never touches a running workflow's invocation
#: (``results/mlflow/invocation.json``).
DESIGN_STORE_DIR = Path("results/mlflow")
DESIGN_EXPERIMENT = "amorgs-design"
#: The running counts logged after every round (step = round).
ROUND_METRICS = ("found", "starts", "cpu_s", "wall_s")


def design_run(alpha: float, params: dict, store_dir: str | Path = DESIGN_STORE_DIR, uri: str | None = None,
               track: bool = True) -> AbstractContextManager:
    """The run of one design at ``alpha`` (N) with ``params`` (the request, the output folder, the sampler's
    provenance), opened in the background; an untracked no-op run when ``track`` is false (MLflow never
    loaded).  Use as ``with design_run(...) as run:``."""
    from amorgs import tracking

    if not track:
        return nullcontext(tracking.JobRun(Path(store_dir)))
    label = alpha_label(alpha)
    return tracking.standalone_run(f"design alpha={label}", DESIGN_EXPERIMENT, store_dir=store_dir, uri=uri,
                                   tags={"rule": "design", "wildcard.alpha": label}, background=True, params=params)


def log_round(run, state: dict) -> None:
    """The running counts of one round (:data:`ROUND_METRICS`; found and starts as counts, CPU and wall in s)."""
    run.log_metrics({k: state[k] for k in ROUND_METRICS}, step=state["round"])


def log_result(run, summary: dict, complete: bool, paths: dict[str, list[Path]]) -> None:
    """The final numbers of :meth:`~amorgs.design.search.DesignResult.summary` (every finite number but the
    request), ``complete`` (1.0 when all N were found) and every written file, under its kind."""
    run.log_metrics({k: float(v) for k, v in summary.items()
                     if isinstance(v, (int, float)) and not isinstance(v, bool) and k != "request"
                     and math.isfinite(float(v))})
    run.log_metrics({"complete": float(complete)})
    for kind, files in paths.items():
        for path in files:
            run.log_artifact(path, kind)
