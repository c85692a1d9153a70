"""The versioned solution library: generated shards kept in the repository so that work accumulates.

Layout (committed)::

    data/library/{problem}/alpha={label}/shard-{k}.parquet     exactly the workflow's generate outputs
    data/library/{problem}/provenance.json                     how they were made (see export_library)

A workflow run whose config enables the library merges these shards with its own freshly generated ones;
the merged table's ``source`` column says ``library`` or ``fresh`` for every row.  The library is produced
by this workflow (``config/library.yaml``: generate/merge with the library's own base seed, so its seeds
never coincide with a default run's) and frozen with ``amorgs library-export``.
"""

from __future__ import annotations

import datetime as _dt
import json
import shutil
import subprocess
from pathlib import Path

import pandas as pd

from amorgs.data.io import atomic_path, write_json

SOURCE_LIBRARY = "library"
SOURCE_FRESH = "fresh"


def library_shards(library_dir: str | Path, problem: str, alpha_label: str) -> list[Path]:
    """The committed shard files of one (problem, α label), sorted; empty if there are none."""
    folder = Path(library_dir) / problem / f"alpha={alpha_label}"
    return sorted(folder.glob("shard-*.parquet"))


def tag_source(df: pd.DataFrame, source: str) -> pd.DataFrame:
    """Add (or overwrite) the ``source`` column."""
    return df.assign(source=source)


def _git_commit() -> str:
    try:
        return subprocess.run(["git", "rev-parse", "HEAD"], capture_output=True, text=True, check=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return "unknown"


def export_library(solutions_dir: str | Path, library_dir: str | Path, problem: str, config_file: str | Path) -> dict:
    """Copy every finished shard under ``solutions_dir/alpha=*/`` into the library and write provenance.

    Shards already in the library are kept (a shard is immutable: same path ⇒ same seed ⇒ same rows).
    Provenance: config file and its text, git commit, creation time, solver option hashes, CPU-hours, and
    rows / converged per α over the whole library.
    """
    src = Path(solutions_dir)
    dst = Path(library_dir) / problem
    copied = 0
    for shard in sorted(src.glob("alpha=*/shard-*.parquet")):
        target = dst / shard.parent.name / shard.name
        if not target.exists():
            target.parent.mkdir(parents=True, exist_ok=True)
            with atomic_path(target) as tmp:
                shutil.copyfile(shard, tmp)
            copied += 1
    frames = [pd.read_parquet(p) for p in sorted(dst.glob("alpha=*/shard-*.parquet"))]
    if not frames:
        raise FileNotFoundError(f"no shard tables under {src}/alpha=*/ to export")
    df = pd.concat(frames, ignore_index=True)
    per_alpha = [
        {"alpha": float(a), "rows": int(len(g)), "converged": int(g["converged"].sum()),
         "best_objective": float(g.loc[g["converged"], "objective"].min()) if g["converged"].any() else None}
        for a, g in df.groupby("alpha")
    ]
    provenance = {
        "problem": problem,
        "created": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"),
        "git_commit": _git_commit(),
        "config_file": str(config_file),
        "config": Path(config_file).read_text(),
        "options_hashes": sorted(df["options_hash"].astype(str).unique().tolist()),
        "shards": len(frames),
        "rows": int(len(df)),
        "converged": int(df["converged"].sum()),
        "cpu_hours": float(df["cpu_s"].fillna(0).sum() / 3600),
        "per_alpha": per_alpha,
    }
    write_json(provenance, dst / "provenance.json")
    return {"copied": copied, **{k: provenance[k] for k in ("shards", "rows", "converged", "cpu_hours")}}


def read_provenance(library_dir: str | Path, problem: str) -> dict | None:
    """The library's provenance record, or None if the problem has no library."""
    path = Path(library_dir) / problem / "provenance.json"
    return json.loads(path.read_text()) if path.is_file() else None
