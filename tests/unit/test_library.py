"""The versioned solution library: export checks, manifest integrity, fixed slices, batches of growth.

Real data: the shards come from the committed library (real IPOPT solves of the library config), split back
into per-shard tables as the generate rule writes them.
"""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from amorgs.data.library import (
    CLIP_TOLERANCE,
    export_library,
    library_files,
    read_library,
    read_library_file,
    read_manifest,
)
from amorgs.data.library_grow import batch_targets, next_batch
from amorgs.errors import InputError

ROOT = Path(__file__).resolve().parents[2]
LIBRARY = ROOT / "data" / "library"
CONFIG = ROOT / "config" / "library.yaml"


def real_shards(tmp_path: Path, label: str = "0.500", n: int = 2) -> Path:
    """The first ``n`` library shards of one α, written as generate-rule shard tables under tmp/solutions."""
    df = read_library(LIBRARY, "cr3bp", label)
    out = tmp_path / "solutions"
    for k in sorted(df["shard"].unique())[:n]:
        path = out / f"alpha={label}" / f"shard-{k}.parquet"
        path.parent.mkdir(parents=True, exist_ok=True)
        df[df["shard"] == k].drop(columns=["source"], errors="ignore").to_parquet(path, index=False)
    return out


def amorgs(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "amorgs", *args], capture_output=True, text=True, timeout=120)


def merge_job(fresh: str, library: list[str], library_dir, output, max_rows: int | None = None) -> str:
    """The --job JSON of one merge job at α = 0.500, as the merge rule writes it."""
    return json.dumps({
        "rule": "merge", "wildcards": {"problem": "cr3bp", "alpha": "0.500"},
        "input": {"fresh": [str(fresh)], "library": [str(p) for p in library]}, "output": {"table": str(output)},
        "threads": 1,
        "settings": {"problem": "cr3bp", "library_enabled": True, "library_path": str(library_dir),
                     "library_max_rows": max_rows},
    })


def test_committed_library_matches_its_manifest():
    manifest = read_manifest(LIBRARY, "cr3bp")
    assert manifest is not None and manifest["format"] == 2
    for entry in manifest["files"]:
        df = read_library_file(LIBRARY / "cr3bp" / entry["file"], LIBRARY, "cr3bp")  # hash and rows checked
        assert sorted(df["shard"].unique()) == entry["shards"]
    assert manifest["totals"]["rows"] == sum(e["rows"] for e in manifest["files"])


def test_export_consolidates_shards_and_skips_held_ones(tmp_path):
    solutions = real_shards(tmp_path, n=2)
    lib = tmp_path / "library"
    summary = export_library(solutions, lib, "cr3bp", CONFIG)
    assert summary["files_added"] == 1 and summary["shards"] == 2
    files = library_files(lib, "cr3bp", "0.500")
    assert [f.name for f in files] == [f"shards-{k:05d}-{k2:05d}.parquet" for k, k2 in [(0, 1)]]
    again = export_library(solutions, lib, "cr3bp", CONFIG)
    assert again["files_added"] == 0 and again["rows"] == summary["rows"]
    entry = read_manifest(lib, "cr3bp")["files"][0]
    assert entry["shards"] == [0, 1] and len(entry["sha256"]) == 64 and entry["options_hashes"]


def test_export_refuses_a_shard_of_another_config(tmp_path):
    solutions = real_shards(tmp_path, n=1)
    shard = next(solutions.glob("alpha=*/shard-*.parquet"))
    df = pd.read_parquet(shard)
    df["seed"] = 12345  # what a smoke or default run would have made
    df.to_parquet(shard, index=False)
    with pytest.raises(InputError, match=r"shard-0\.parquet: seed \[12345\] is not the library config's seed"):
        export_library(solutions, tmp_path / "library", "cr3bp", CONFIG)
    assert not (tmp_path / "library").exists()


def test_export_refuses_a_short_shard_and_a_truncated_one(tmp_path):
    solutions = real_shards(tmp_path, n=2)
    first, second = sorted(solutions.glob("alpha=*/shard-*.parquet"))
    original = pd.read_parquet(first)
    original.head(3).to_parquet(first, index=False)
    with pytest.raises(InputError, match=r"shard-0\.parquet: 3 rows, the library config makes 12 per shard"):
        export_library(solutions, tmp_path / "library", "cr3bp", CONFIG)
    original.to_parquet(first, index=False)
    data = second.read_bytes()
    second.write_bytes(data[: len(data) // 2])
    with pytest.raises(InputError, match=r"shard-1\.parquet: not a readable Parquet table"):
        export_library(solutions, tmp_path / "library", "cr3bp", CONFIG)


def test_export_clips_tiny_bound_violations_and_refuses_large_ones(tmp_path):
    solutions = real_shards(tmp_path, n=1)
    shard = next(solutions.glob("alpha=*/shard-*.parquet"))
    df = pd.read_parquet(shard)
    row = int(np.flatnonzero(df["converged"])[0])
    df.loc[row, "tau_i"] = -9e-9
    df.to_parquet(shard, index=False)
    export_library(solutions, tmp_path / "lib1", "cr3bp", CONFIG)
    stored = read_library(tmp_path / "lib1", "cr3bp", "0.500")
    assert stored.loc[row, "tau_i"] == 0.0
    df.loc[row, "m_f"] = 999.0  # the fuel bound is the initial fuel, ≈ 452 kg
    df.to_parquet(shard, index=False)
    with pytest.raises(InputError, match=r"column 'm_f' lies .* outside its bounds"):
        export_library(solutions, tmp_path / "lib2", "cr3bp", CONFIG)
    assert CLIP_TOLERANCE < 1e-3


def test_merge_refuses_an_edited_library_file_naming_it(tmp_path):
    lib = tmp_path / "library"
    shutil.copytree(LIBRARY, lib)
    target = library_files(lib, "cr3bp", "0.500")[0]
    df = pd.read_parquet(target)
    df.loc[0, "m_f"] = 999.0
    df.to_parquet(target, index=False)
    fresh = real_shards(tmp_path, n=1)
    res = amorgs("step", "--job", merge_job(next(fresh.glob("alpha=*/shard-*.parquet")), [target], lib,
                                            tmp_path / "merged.parquet"))
    assert res.returncode != 0
    assert "SHA-256" in res.stderr and str(target) in res.stderr and "Traceback" not in res.stderr
    assert not (tmp_path / "merged.parquet").exists()


def test_merge_refuses_a_truncated_library_file_and_an_unlisted_one(tmp_path):
    lib = tmp_path / "library"
    shutil.copytree(LIBRARY, lib)
    target = library_files(lib, "cr3bp", "0.500")[0]
    data = target.read_bytes()
    target.write_bytes(data[:-100])
    with pytest.raises(InputError, match="SHA-256"):
        read_library_file(target, lib, "cr3bp")
    stray = target.with_name("shards-99999-99999.parquet")
    shutil.copyfile(library_files(lib, "cr3bp", "0.100")[0], stray)
    with pytest.raises(InputError, match="not listed in"):
        read_library_file(stray, lib, "cr3bp")


def test_merge_takes_a_fixed_slice_of_the_library(tmp_path):
    fresh = real_shards(tmp_path, label="0.500", n=1)
    shard = next(fresh.glob("alpha=*/shard-*.parquet"))
    df = pd.read_parquet(shard)
    df["seed"] = 7  # a fresh shard of some other run: its keys differ from the library's
    df.to_parquet(shard, index=False)
    files = [str(p) for p in library_files(LIBRARY, "cr3bp", "0.500")]
    out = tmp_path / "merged.parquet"
    res = amorgs("step", "--job", merge_job(shard, files, LIBRARY, out, max_rows=5))
    assert res.returncode == 0, res.stderr
    merged = pd.read_parquet(out)
    library = read_library(LIBRARY, "cr3bp", "0.500")
    assert (merged["source"] == "library").sum() == 5
    pd.testing.assert_frame_equal(
        merged[merged["source"] == "library"].drop(columns="source").reset_index(drop=True),
        library.head(5).reset_index(drop=True),
    )


def test_batches_skip_held_shards_and_cover_every_alpha(tmp_path):
    manifest = read_manifest(LIBRARY, "cr3bp")
    held = {(e["file"].split("/")[0].removeprefix("alpha="), k) for e in manifest["files"] for k in e["shards"]}
    b = next_batch(CONFIG, LIBRARY, "cr3bp")
    targets = batch_targets(CONFIG, LIBRARY, "cr3bp", b)
    assert targets
    pairs = {(Path(t).parent.name.removeprefix("alpha="), int(Path(t).stem.removeprefix("shard-"))) for t in targets}
    assert not pairs & held
    assert all(8 * b <= k < 8 * (b + 1) for _, k in pairs)
    # an empty library: batch 0 asks for every α × 8 shards, 14 α in the library config
    assert len(batch_targets(CONFIG, tmp_path / "none", "cr3bp", 0)) == 14 * 8
    assert next_batch(CONFIG, tmp_path / "none", "cr3bp") == 0


def test_focused_batches_grow_only_the_chosen_alpha(tmp_path):
    from amorgs.errors import ConfigError

    focus = batch_targets(CONFIG, tmp_path / "none", "cr3bp", 2, alphas=[1.0])
    assert focus == [f"results/cr3bp/solutions/alpha=1.000/shard-{k}.parquet" for k in range(16, 24)]
    # the same shard indices (hence seeds) as the balanced batch 2 at α = 1.0: the two never collide
    assert set(focus) <= set(batch_targets(CONFIG, tmp_path / "none", "cr3bp", 2))
    manifest = read_manifest(LIBRARY, "cr3bp")
    held = {k for e in manifest["files"] if e["file"].startswith("alpha=1.000/") for k in e["shards"]}
    b = next_batch(CONFIG, LIBRARY, "cr3bp", [1.0])  # the first batch with an α = 1.0 shard missing
    assert set(range(8 * b)) <= held and not set(range(8 * b, 8 * (b + 1))) <= held
    with pytest.raises(ConfigError, match=r"α 0\.33 is not one of the library α"):
        batch_targets(CONFIG, LIBRARY, "cr3bp", 0, alphas=[0.33])


def test_grow_batches_go_through_a_snakemake_profile(monkeypatch):
    """`library-grow --profile workflow/profiles/slurm`: each batch's Snakemake call takes that profile (absolute,
    since the batch runs in its own directory); without it, none (this machine, --cores)."""
    from amorgs.data.library_grow import snakemake_command

    monkeypatch.chdir(ROOT)
    cmd = snakemake_command(CONFIG, "results/library-grow", 2, ["a.parquet"], profile="workflow/profiles/slurm")
    assert cmd[cmd.index("--profile") + 1] == str(ROOT / "workflow" / "profiles" / "slurm")
    assert "--profile" not in snakemake_command(CONFIG, "results/library-grow", 2, ["a.parquet"])


def test_grow_until_converged_picks_the_short_alphas_and_stops_when_none_is_left(tmp_path):
    from amorgs.data.library_grow import grow, short_alphas

    per_alpha = {e["alpha"]: e["converged"] for e in read_manifest(LIBRARY, "cr3bp")["per_alpha"]}
    target = sorted(per_alpha.values())[len(per_alpha) // 2]  # about half the α lie below it
    short = short_alphas(CONFIG, LIBRARY, "cr3bp", target)
    assert sorted(short) == [a for a in sorted(per_alpha) if per_alpha[a] < target] and 0 < len(short) < len(per_alpha)
    assert short_alphas(CONFIG, LIBRARY, "cr3bp", target, alphas=[1.0, short[0]]) == [short[0]]
    assert sorted(short_alphas(CONFIG, tmp_path / "none", "cr3bp", 1)) == sorted(per_alpha)  # an empty library: all
    said = []
    # every α already holds ≥ 1 converged solution: nothing to grow, no Snakemake started
    assert grow(CONFIG, LIBRARY, "cr3bp", tmp_path / "work", batches=3, niceness=0, log=said.append,
                until_converged=1) == []
    assert said == ["library-grow: every α holds ≥ 1 converged solutions, stopping"]
    assert not (tmp_path / "work").exists()


def test_library_export_cli_prints_one_line_for_a_foreign_shard(tmp_path):
    solutions = real_shards(tmp_path, n=1)
    shard = next(solutions.glob("alpha=*/shard-*.parquet"))
    df = pd.read_parquet(shard)
    df["seed"] = 1
    df.to_parquet(shard, index=False)
    res = amorgs("library-export", "--solutions-dir", str(solutions), "--library-dir", str(tmp_path / "lib"),
                 "--config", str(CONFIG))
    assert res.returncode != 0 and "Traceback" not in res.stderr
    assert str(shard) in res.stderr and len(res.stderr.strip().splitlines()) == 1


@pytest.mark.slow
def test_grow_runs_a_real_batch_and_exports_it(tmp_path, monkeypatch):
    """One batch of a tiny library config through the real Snakemake workflow, then its export; a second
    call starts the next batch and never regenerates or duplicates a held shard."""
    import yaml

    from amorgs.data.library_grow import grow

    cfg = yaml.safe_load(CONFIG.read_text())
    cfg["mlflow"]["enabled"] = False
    cfg["problems"]["dejong"]["enabled"] = False
    cfg["dejong_cvae"]["enabled"] = False
    cr3bp = cfg["problems"]["cr3bp"]
    cr3bp["alphas"] = {"train": [0.6], "test": [0.9]}
    cr3bp["generate"].update(shards=1, starts_per_shard=1, workers=1)
    cr3bp["solver"]["max_iter"] = 20
    config = tmp_path / "library.yaml"
    config.write_text(yaml.safe_dump(cfg))
    lib = tmp_path / "library"
    monkeypatch.chdir(ROOT)
    first = grow(config, lib, "cr3bp", tmp_path / "work", cores=1, batches=2, niceness=0, log=lambda *_: None)
    assert [s["batch"] for s in first] == [0, 1] and all(s["snakemake_exit"] == 0 for s in first)
    manifest = read_manifest(lib, "cr3bp")
    assert manifest["totals"]["rows"] == 4 and manifest["totals"]["shards"] == 4
    assert sorted((e["alpha"], e["shards"][0]) for e in manifest["files"]) == [(0.6, 0), (0.6, 1), (0.9, 0), (0.9, 1)]
    table = read_library(lib, "cr3bp", "0.600")
    assert sorted(table["shard"]) == [0, 1] and (table["iterations"] <= 20).all()
