"""Start-up of ``amorgs design``: seconds from the command's start to the first solve, and the total wall time.

Runs ``amorgs design --alpha 0.42 -n 5`` (or the arguments after ``--``) as a fresh process, each run into a
new output folder, and reports per run the seconds until the first guess is handed to a solver worker (the
end of start-up: imports, config, library, sampler, MLflow, worker start and solver build) and the total
wall seconds.  ``--src`` compares checkouts (their ``src`` folders) *paired*: the runs alternate between them
(A B A B …), so that a machine's changing load hits both alike.  The MLflow store is one folder for all the
runs (``--mlflow-dir``; a design calls into an existing store, as beside the workflow's), created by an
untimed first run of each checkout.  Reproduce with::

    python benchmarks/design_startup.py --repeat 3
    python benchmarks/design_startup.py --repeat 4 --src ../before/src src      # before/after, paired
    python benchmarks/design_startup.py --repeat 3 -- --alpha 0.42 -n 5 --no-mlflow

Times are wall-clock seconds (``time.time`` across processes); they depend on the machine's load, which is
printed with the result.  Every run's ``all_solves.parquet`` is compared with the first run's (timing columns
aside): start-up work must never change a solve.
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import pandas as pd

ROOT = Path(__file__).resolve().parents[1]
DEFAULT_ARGS = ["--alpha", "0.42", "-n", "5"]

#: Run in the child: note the time of the first (index, guess, α) task sent to a solver worker, then the CLI.
CHILD = """
import sys, time
from multiprocessing import connection
MARK = sys.argv[1]
_send = connection.Connection.send
def send(self, obj):
    if isinstance(obj, tuple) and len(obj) == 3 and not getattr(send, "done", False):
        send.done = True
        with open(MARK, "w") as f:
            f.write(repr(time.time()))
    return _send(self, obj)
connection.Connection.send = send
sys.argv = ["amorgs", *sys.argv[2:]]
from amorgs.cli import main
main()
"""


def run_once(src: Path, args: list[str], out: Path, mlflow_dir: Path, mark: Path) -> dict:
    """One ``amorgs design`` process of the checkout ``src``; seconds to the first solve and in all (wall)."""
    cmd = [sys.executable, "-c", CHILD, str(mark), "design", *args, "--output", str(out), "--mlflow-dir",
           str(mlflow_dir), "--quiet"]
    env = {**os.environ, "PYTHONPATH": str(src)}
    t0 = time.time()
    proc = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, env=env)
    wall = time.time() - t0
    if proc.returncode not in (0, 3):
        raise SystemExit(f"amorgs design failed ({proc.returncode}):\n{proc.stderr[-3000:]}")
    first = float(mark.read_text()) - t0 if mark.exists() else float("nan")
    solves = pd.read_parquet(out / "all_solves.parquet").drop(columns=["wall_s", "cpu_s"])
    return {"first_solve_s": first, "wall_s": wall, "stdout": proc.stdout.strip(), "load": os.getloadavg()[0],
            "solves": solves}


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--repeat", type=int, default=3, help="timed runs per checkout")
    parser.add_argument("--src", nargs="+", type=Path, default=[ROOT / "src"],
                        help="the src folders of the checkouts to time, alternately (default: this one)")
    parser.add_argument("--mlflow-dir", type=Path, help="the MLflow store of the runs (default: a temporary folder)")
    parser.add_argument("design_args", nargs="*", help="arguments of amorgs design (after --)")
    opts = parser.parse_args(argv)
    args = opts.design_args or DEFAULT_ARGS
    srcs = [p.resolve() for p in opts.src]
    runs: dict[Path, list[dict]] = {src: [] for src in srcs}
    with tempfile.TemporaryDirectory(prefix="amorgs-design-bench-") as tmp:
        tmp = Path(tmp)
        store = opts.mlflow_dir or tmp / "mlflow"
        for i in range(opts.repeat + 1):
            for j, src in enumerate(srcs):
                res = run_once(src, args, tmp / f"out-{i}-{j}", store, tmp / f"first-{i}-{j}")
                kind = "warm-up" if i == 0 else f"run {i}"
                print(f"{src}: {kind}: first solve {res['first_solve_s']:.1f} s, wall {res['wall_s']:.1f} s, load "
                      f"{res['load']:.1f} | {res['stdout']}", flush=True)
                if i:
                    runs[src].append(res)
        reference = next(iter(runs.values()))[0]["solves"]
        same = all(r["solves"].equals(reference) for rs in runs.values() for r in rs)
    print(f"the same solves in every run (timing aside): {'yes' if same else 'NO'}")
    for src, rs in runs.items():
        first, wall = [r["first_solve_s"] for r in rs], [r["wall_s"] for r in rs]
        print(f"{src}: amorgs design {' '.join(args)}: first solve median {statistics.median(first):.1f} s "
              f"(range {min(first):.1f}–{max(first):.1f}), wall median {statistics.median(wall):.1f} s "
              f"(range {min(wall):.1f}–{max(wall):.1f}), {len(rs)} runs")


if __name__ == "__main__":
    main()
