"""``amorgs design``, the command: check every option, prepare, search, write the outputs, mirror it to MLflow
(:func:`run_design`), with a progress line on stderr (:class:`ProgressLine`).
"""

from __future__ import annotations

from contextlib import ExitStack
from dataclasses import asdict
from pathlib import Path

from amorgs.alphas import alpha_label
from amorgs.design.outputs import check_output_dir, default_output_dir, write_outputs
from amorgs.design.search import DesignRequest, DesignResult, design, prepare
from amorgs.design.tracking import DESIGN_STORE_DIR, design_run, log_result, log_round


class ProgressLine:
    """Progress on stderr after every round: tqdm if it is installed, else one updating line (a new line per
    round when stderr is not a terminal).  A context manager; :meth:`close` ends the line, once."""

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
        self._closed = False

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
        if self._closed:
            return
        self._closed = True
        if self._bar is not None:
            self._bar.close()
        elif self._tty:
            self.stream.write("\n")
            self.stream.flush()

    def __enter__(self) -> ProgressLine:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def run_design(request: DesignRequest, output_dir: str | Path | None = None, track: bool = True,
               store_dir: str | Path = DESIGN_STORE_DIR, progress: bool = True) -> tuple[DesignResult, dict]:
    """``amorgs design``: check every option (the output folder included) and prepare — every user error
    before the first solve —, search, write the outputs, mirror it to MLflow.

    MLflow (unless ``track`` is false or the config's ``mlflow.enabled`` is false): one run per call in
    experiment ``amorgs-design`` of the store ``store_dir`` (:mod:`amorgs.design.tracking`), opened in the
    background once the first guess is with a solver worker, so that it delays no solve.  Returns the
    result and the written paths by kind.
    """
    request.check()
    out = Path(output_dir) if output_dir is not None else default_output_dir(request.alpha)
    check_output_dir(out, request.library_dir)
    with prepare(request) as prepared, ExitStack() as stack:
        if progress:  # which sampler, and why (auto: the frontier's evidence); stale shipped models
            import sys

            for line in (prepared.info["sampler_choice"], prepared.info.get("strategy_choice"),
                         prepared.info.get("models_note")):
                if line:
                    print(f"amorgs design: {line}", file=sys.stderr, flush=True)
        params = {**asdict(request), "output": str(out), **prepared.info}
        track = track and bool(prepared.cfg.mlflow.enabled)
        bar = stack.enter_context(ProgressLine(request)) if progress else None
        runs = []  # the MLflow run, once opened; it ends (FINISHED, KILLED, FAILED) with this block

        def open_run() -> None:
            runs.append(stack.enter_context(design_run(request.alpha, params, store_dir,
                                                       prepared.cfg.mlflow.tracking_uri, track)))

        def on_round(state: dict) -> None:
            log_round(runs[0], state)
            if bar is not None:
                bar(state)

        result = design(request, on_round, prepared, started=open_run)
        if bar is not None:
            bar.close()
        paths = write_outputs(result, out)
        log_result(runs[0], result.summary(), result.found >= request.n, paths)
    return result, paths
