"""The main job on a library twice the size (issue 40): what grows, simulated by duplication.

The default config reads a fixed slice of each α's library rows (``problems.cr3bp.library.max_rows_per_alpha``:
the first rows in (shard, start) order), so a grown library changes no α table and no job after the merge; the
merge itself still reads and checks every file of its α.  This benchmark builds a copy of the library in which
every file has a twin (the same rows, shard numbers shifted past every real shard and seeds past every real one, listed in the manifest with
its own SHA-256 — what two more years of growth would add), then runs the workflow's own merge step for every
CR3BP α of ``--config`` on both libraries, paired and alternating, and reports:

- the merge's wall time per α on each library (median of ``--repeats``), and the total;
- whether every α table is identical (then every later job of the run is the same work: the run grows by the
  merges' difference only);
- the same for the typed defaults' unlimited read (``max_rows_per_alpha: null``): the rows an α table would carry
  into the filter, the analysis, training and the ablation.

Prints a table and writes it to ``docs/performance.md`` (section ``library-scaling``)::

    python benchmarks/library_scaling.py --config config/default.yaml
"""

from __future__ import annotations

import argparse
import copy
import os
import shutil
import statistics
import sys
import tempfile
import time
from pathlib import Path

import pandas as pd

from amorgs.config import from_mapping, load_config
from amorgs.data.io import write_json
from amorgs.data.library import MANIFEST, library_files, read_library_file, read_manifest, sha256_file
from amorgs.steps import run_step

sys.path.insert(0, str(Path(__file__).parent))
from solve import markdown, write_section  # noqa: E402

PROBLEM = "cr3bp"


def doubled_library(source: Path, dest: Path) -> int:
    """Copy the library at ``source`` to ``dest`` and give every file a listed twin with shard numbers shifted
    past the largest real one; returns the rows of the copy."""
    shutil.copytree(source, dest)
    root = dest / PROBLEM
    manifest = read_manifest(dest, PROBLEM)
    offset = 1 + max(max(e["shards"]) for e in manifest["files"])
    twins = []
    for entry in manifest["files"]:
        table = pd.read_parquet(root / entry["file"])  # as stored (seeded guesses stay dropped)
        table["shard"] = table["shard"] + offset
        table["seed"] = table["seed"] + 2**32  # a solve key no real row has
        name = entry["file"].replace(".parquet", "-twin.parquet")
        table.to_parquet(root / name, index=False)
        twin = copy.deepcopy(entry)
        twin.update(file=name, sha256=sha256_file(root / name), bytes=(root / name).stat().st_size,
                    shards=[s + offset for s in entry["shards"]])
        twin.pop("sources", None)
        twins.append(twin)
    manifest["files"] += twins
    manifest["totals"]["rows"] *= 2
    write_json(manifest, root / MANIFEST)
    return manifest["totals"]["rows"]


def with_library(cfg, library: Path, max_rows: int | None):
    """``cfg`` reading the library at ``library``, ``max_rows`` rows per α (``None``: every row)."""
    data = cfg.model_dump(mode="json")
    data["problems"][PROBLEM]["library"].update(path=str(library), max_rows_per_alpha=max_rows)
    return from_mapping(data)


def merge_once(cfg, library: Path, label: str, fresh: Path, out: Path) -> tuple[float, pd.DataFrame]:
    """Wall seconds of the workflow's merge step for one α on ``library``, and the α table it wrote."""
    cfg = with_library(cfg, library, cfg.problems.cr3bp.library.max_rows_per_alpha)
    files = [str(p) for p in library_files(library, PROBLEM, label)]
    t0 = time.perf_counter()
    run_step("merge", cfg, {"problem": PROBLEM, "alpha": label}, {"fresh": [str(fresh)], "library": files},
             {"table": str(out)})
    return time.perf_counter() - t0, pd.read_parquet(out)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--config", type=Path, default=Path("config/default.yaml"))
    ap.add_argument("--library-dir", type=Path, default=Path("data/library"))
    ap.add_argument("--repeats", type=int, default=3)
    args = ap.parse_args()
    cfg = load_config(args.config)
    library_dir = args.library_dir.resolve()
    labels = sorted(cfg.problems.cr3bp.alpha_values())
    rows, totals = [], {}
    here = Path.cwd()
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        os.chdir(tmp)  # the steps run untracked here (no results/mlflow/invocation.json)
        doubled = tmp / "doubled"
        n_doubled = doubled_library(library_dir, doubled)
        n_rows = read_manifest(library_dir, PROBLEM)["totals"]["rows"]
        for cap in (cfg.problems.cr3bp.library.max_rows_per_alpha, None):
            c = with_library(cfg, library_dir, cap)
            for label in labels:
                first = library_files(library_dir, PROBLEM, label)[0]
                fresh = tmp / f"fresh-{label}.parquet"  # a stand-in fresh shard: 8 of the library's rows
                stand_in = read_library_file(first, library_dir, PROBLEM).head(8)
                stand_in.assign(seed=1).to_parquet(fresh, index=False)  # seed 1: no library solve's
                times = {"1×": [], "2×": []}
                tables = {}
                for _ in range(args.repeats):  # alternating, paired
                    for name, lib in (("1×", library_dir), ("2×", doubled)):
                        s, tables[name] = merge_once(c, lib, label, fresh, tmp / f"{name}-{label}.parquet")
                        times[name].append(s)
                same = tables["1×"].drop(columns=["source"], errors="ignore").equals(
                    tables["2×"].drop(columns=["source"], errors="ignore"))
                med = {k: statistics.median(v) for k, v in times.items()}
                for k in med:
                    totals[(cap, k)] = totals.get((cap, k), 0.0) + med[k]
                rows.append({"library read": f"≤ {cap} rows per α" if cap else "every row", "α": label,
                             "rows 1× / 2×": f"{len(tables['1×'])} / {len(tables['2×'])}",
                             "identical α table": "yes" if same else "no",
                             "merge s 1×": f"{med['1×']:.2f}", "merge s 2×": f"{med['2×']:.2f}"})
                print(rows[-1], flush=True)
    summary = "; ".join(f"{'≤ ' + str(cap) + ' per α' if cap else 'every row'}: merges {totals[(cap, '1×')]:.1f} s "
                        f"on 1×, {totals[(cap, '2×')]:.1f} s on 2×"
                        for cap in (cfg.problems.cr3bp.library.max_rows_per_alpha, None))
    cmd = " ".join(["python benchmarks/library_scaling.py", *sys.argv[1:]])
    text = (f"Command: `{cmd}` — the library of {n_rows} rows (1×) and a copy in which every file has a twin "
            f"({n_doubled} rows, 2×); the workflow's merge step for each CR3BP α of `{args.config}`, median of "
            f"{args.repeats} paired, alternating runs, MLflow off. Totals: {summary}.\n\n" + markdown(rows))
    print(text)
    os.chdir(here)
    write_section("library-scaling", text)


if __name__ == "__main__":
    main()
