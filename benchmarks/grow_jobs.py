"""How much of the machine a library-grow batch turns into solving: the generate job's workers and its MLflow run.

A library shard is 12 starts.  With ``generate.workers = 2`` (the library config until 2026-12-03) one job holds
both cores: its start-up (imports, the worker processes, loading the NLP) and the tail where one worker still
solves the shard's last start while the other idles are paid on both cores.  With 1 worker per job Snakemake
runs two jobs side by side and each core is busy with its own job.  And each tracked job opens, fills and
closes its own MLflow run in the SQLite store (``mlflow.enabled``), seconds of CPU per 12-start job.  Which solves a shard holds
does not depend on the workers (each start is an independent, deterministic solve; ``amorgs library-export``
checks a re-solved shard row by row), so the comparison is the machine's **utilisation** — solve CPU
(``cpu_s``, summed over the shard's rows) ÷ (cores × the batch's wall time) — and the verified solutions per
wall-hour of the whole machine.

The shards measured are real library shards (the library config's seed, the next shard indices the library
lacks), so nothing is wasted: export them afterwards with ``amorgs library-export --solutions-dir
<workdir>/results/cr3bp/solutions``.  Rounds alternate the order of the variants; each (round, variant) is one
Snakemake call over one new shard per α.  Reproduce with::

    python benchmarks/grow_jobs.py --rounds 2 --variants 2:on 1:off --workdir /tmp/grow-jobs   # nothing else running
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import time
from pathlib import Path

import pandas as pd
import yaml

from amorgs.config import deep_merge, read_yaml
from amorgs.data.library import held_shards
from amorgs.library_grow import grown_alphas, snakemake_command
from amorgs import layout

sys.path.insert(0, str(Path(__file__).resolve().parent))
from solve import machine, markdown, write_section  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]


def free_shards(library_dir: Path, labels: list[str], count: int, start: int) -> list[int]:
    """``count`` shard indices ≥ ``start`` that no α of ``labels`` holds yet in the library."""
    held = held_shards(library_dir, "cr3bp")
    out, k = [], start
    while len(out) < count:
        if all((label, k) not in held for label in labels):
            out.append(k)
        k += 1
    return out


def measures(solves: int, verified: int, cpu_s: float, wall_s: float, cores: int) -> dict:
    """The table's columns for ``solves`` (``verified`` of them) of ``cpu_s`` solve CPU in ``wall_s`` on ``cores``."""
    return {"solves": solves, "verified": verified, "solve CPU (s)": cpu_s, "wall (s)": wall_s,
            "utilisation %": 100 * cpu_s / (cores * wall_s), "verified per wall-hour": 3600 * verified / wall_s}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--config", default=str(ROOT / "config" / "library.yaml"))
    ap.add_argument("--library-dir", default=str(ROOT / "data" / "library"))
    ap.add_argument("--workdir", default="/tmp/grow-jobs")
    ap.add_argument("--variants", nargs="+", default=["2:on", "1:off"], metavar="WORKERS:MLFLOW",
                    help="solver processes per generate job and MLflow tracking (on/off), e.g. 2:on 1:off")
    ap.add_argument("--rounds", type=int, default=2)
    ap.add_argument("--cores", type=int, default=2)
    ap.add_argument("--first-shard", type=int, default=0, help="look for free shard indices from here")
    args = ap.parse_args()

    labels = grown_alphas(args.config, "cr3bp")
    variants = [(int(v.split(":")[0]), v.split(":")[1] == "on") for v in args.variants]
    n_cells = args.rounds * len(variants)
    shards = iter(free_shards(Path(args.library_dir), labels, n_cells, args.first_shard))
    workdir = Path(args.workdir)
    workdir.mkdir(parents=True, exist_ok=True)
    rows = []
    for r in range(args.rounds):
        order = variants if r % 2 == 0 else list(reversed(variants))
        for workers, tracked in order:
            name = f"{workers} worker{'s' * (workers > 1)} per job, MLflow {'on' if tracked else 'off'}"
            shard = next(shards)
            targets = [layout.SHARD.format(problem="cr3bp", alpha=label, shard=shard) for label in labels]
            variant_config = workdir.parent / f"{workdir.name}-w{workers}-mlflow-{tracked}.yaml"
            variant_config.write_text(yaml.safe_dump(deep_merge(read_yaml(args.config), {
                "problems": {"cr3bp": {"generate": {"workers": workers}}}, "mlflow": {"enabled": tracked}})))
            cmd = snakemake_command(variant_config, workdir, args.cores, targets)
            t0 = time.perf_counter()
            with open(workdir.parent / f"{workdir.name}-r{r + 1}-w{workers}-mlflow-{tracked}.log", "w") as log:
                done = subprocess.run(cmd, check=False, stdout=log, stderr=subprocess.STDOUT)
            wall = time.perf_counter() - t0
            df = pd.concat([pd.read_parquet(workdir / t) for t in targets if (workdir / t).is_file()])
            row = {"round": r + 1, "variant": name, "shard": shard, "jobs": len(targets),
                   "snakemake exit": done.returncode,
                   **measures(len(df), int(df.converged.sum()), df.cpu_s.sum(), wall, args.cores)}
            print(row, flush=True)
            rows.append(row)
    table = pd.DataFrame(rows)
    total = table.groupby("variant", sort=False)[["solves", "verified", "solve CPU (s)", "wall (s)"]].sum()
    summary = [{"variant": w, **measures(int(t["solves"]), int(t["verified"]), t["solve CPU (s)"], t["wall (s)"],
                                         args.cores)} for w, t in total.iterrows()]
    cmd = "python benchmarks/grow_jobs.py " + " ".join(sys.argv[1:])
    text = (f"Command: `{cmd}` — {machine()}; {args.cores} cores; shards of the library config, one per α per "
            f"(round, variant).\n\n" + markdown(rows) + "\nPer variant, all rounds:\n\n" + markdown(summary))
    print(text)
    write_section("grow_jobs", text)


if __name__ == "__main__":
    main()
