"""``amorgs design``, the command: check every option, prepare, search, write the outputs, mirror it to MLflow
(:func:`run_design`), with a progress line on stderr (:class:`ProgressLine`).
"""

from __future__ import annotations

import math
from dataclasses import asdict
from pathlib import Path

from amorgs.alphas import alpha_label
from amorgs.design.outputs import check_output_dir, default_output_dir, write_outputs
from amorgs.design.search import DesignRequest, DesignResult, design, prepare
from amorgs.design.tracking import DESIGN_EXPERIMENT, DESIGN_STORE_DIR




class ProgressLine:
    """Progress on stderr after every round: tqdm if it is installed, else one updating line (a new line per
    round when stderr is not a terminal)."""

    def __init__(self, request: DesignRequest, stream=None):
        import importlib.util
        import sys

        self.stream = stream or sys.stderr
        self.request = request
        self._bar = None
        if importlib.util.find_spec("tqdm") is not None:
            from tqdm import tqdm

            self._bar = tqdm(total=request.n, desc=f"design α={alpha_label(request.alpha)}", unit="sol",
                             file=self.stream)
        self._tty = hasattr(self.stream, "isatty") and self.stream.isatty()

    def __call__(self, state: dict) -> None:
        text = (f"starts {state['starts']}/{state['max_starts']} | CPU {state['cpu_s']:.0f}/{state['max_cpu_s']:.0f} s"
                f" | wall {state['wall_s']:.0f} s | round {state['round']}")
        if self._bar is not None:
            self._bar.n = min(state["found"], state["n"])
            self._bar.set_postfix_str(text)
            return
        n, found = state["n"], min(state["found"], state["n"])
        width = 20
        filled = int(round(width * found / n))
        line = f"design α={alpha_label(self.request.alpha)} [{'#' * filled}{'.' * (width - filled)}] {found}/{n} | {text}"
        self.stream.write(("\r" + line) if self._tty else line + "\n")
        self.stream.flush()

    def close(self) -> None:
        if self._bar is not None:
            self._bar.close()
        elif self._tty:
            self.stream.write("\n")
            self.stream.flush()


def run_design(request: DesignRequest, output_dir: str | Path | None = None, track: bool = True,
               store_dir: str | Path = DESIGN_STORE_DIR, progress: bool = True) -> tuple[DesignResult, dict]:
    """``amorgs design``: check every option (the output folder included) and prepare — every user error
    before the first solve —, search, write the outputs, mirror it to MLflow.

    MLflow (unless ``track`` is false or the config's ``mlflow.enabled`` is false): one run per call
    (:func:`amorgs.tracking.standalone_run`) in experiment :data:`DESIGN_EXPERIMENT` of the store
    ``store_dir``, holding the request as parameters, the metrics (per round and final: found, starts, CPU s,
    wall s …) and the artifacts (tables, plot, summary, trajectory CSV and OEM files); it ends FINISHED,
    KILLED (Ctrl-C) or FAILED.  Returns the result and the written paths by kind.
    """
    from contextlib import nullcontext

    request.check()
    out = Path(output_dir) if output_dir is not None else default_output_dir(request.alpha)
    check_output_dir(out)
    prepared = prepare(request)
    params = {**asdict(request), "output": str(out), **{k: v for k, v in prepared.info.items()}}
    track = track and bool(prepared.cfg.mlflow.enabled)
    from amorgs import tracking

    bar = ProgressLine(request) if progress else None
    if track:
        context = tracking.standalone_run(f"design alpha={alpha_label(request.alpha)}", DESIGN_EXPERIMENT,
                                          store_dir=store_dir, uri=prepared.cfg.mlflow.tracking_uri,
                                          tags={"rule": "design", "wildcard.alpha": alpha_label(request.alpha)})
    else:
        context = nullcontext(tracking.JobRun(Path(store_dir)))
    try:
        with context as run:
            run.log_params(params)

            def on_round(state: dict) -> None:
                run.log_metrics({k: state[k] for k in ("found", "starts", "cpu_s", "wall_s")}, step=state["round"])
                if bar is not None:
                    bar(state)

            result = design(request, on_round, prepared)
            if bar is not None:
                bar.close()
                bar = None
            paths = write_outputs(result, out)
            summary = result.summary()
            run.log_metrics({k: float(v) for k, v in summary.items()
                             if isinstance(v, (int, float)) and not isinstance(v, bool) and k != "request"
                             and math.isfinite(float(v))})
            run.log_metrics({"complete": float(result.found >= request.n)})
            for kind, files in paths.items():
                for path in files:
                    run.log_artifact(path, kind)
    finally:
        if bar is not None:
            bar.close()
    return result, paths
