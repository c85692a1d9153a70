"""The versioned solution library: export checks, manifest integrity, fixed slices, batches of growth.

Real data: the shards come from the committed library (real IPOPT solves of the library config), split back
into per-shard tables as the generate rule writes them.
"""

from __future__ import annotations

import atexit
import json
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from config_files import mapping

from amorgs.config import load_config
from amorgs.data.library import (
    CLIP_TOLERANCE,
    compact_library,
    library_files,
    manifest_identity,
    read_library,
    read_library_file,
    read_manifest,
    seeded_guesses,
)
from amorgs.library_grow import batch_targets, next_batch
from amorgs.errors import ConfigError, InputError

from amorgs.data.library import export_library as export_verified

ROOT = Path(__file__).resolve().parents[2]


def export_library(*args, **kwargs):
    """Export without the gate's re-solve: the committed rows these tests split back into shards were solved by
    generation 1's code (before 645f351, issue 37), which today's code does not reproduce bit for bit; the gate's
    tests below (``test_the_gate_*``) re-solve shards that today's code made."""
    return export_verified(*args, **{"resolve_sample": 0, **kwargs})
LIBRARY = ROOT / "data" / "library"
LIBRARY_CONFIG = ROOT / "config" / "library.yaml"


def _generation_1_config() -> Path:
    """The library config with the solver of library generation 1 (RK8 coasts, Sherman–Morrison L-BFGS with
    history 30), so
    that the committed generation-1 shards are this config's shards."""
    import yaml

    cfg = mapping("library")
    cfg["problems"]["cr3bp"]["solver"].update(lbfgs_aug_solver="sherman-morrison", lbfgs_memory=30,
                                              transcription={"coast": "rk8"})
    folder = tempfile.mkdtemp(prefix="amorgs-test-library-")
    atexit.register(shutil.rmtree, folder, ignore_errors=True)  # built at import, so no tmp_path to hold it
    path = Path(folder) / "library.yaml"
    path.write_text(yaml.safe_dump(cfg))
    return path


CONFIG = _generation_1_config()
CFG = load_config(CONFIG)


def real_shards(tmp_path: Path, label: str = "0.500", n: int = 2, options_hash: str | None = None) -> Path:
    """The first ``n`` library shards of one α solved with ``options_hash`` (default: generation 1's solver
    options, :data:`CFG`; shards 8, 9, …; batch 0 predates them), written as generate-rule shard tables under
    tmp/solutions."""
    df = read_library(LIBRARY, "cr3bp", label)
    df = df[df["options_hash"] == (options_hash or CFG.problems.cr3bp.solver.digest())]
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
    summary = export_library(solutions, lib, "cr3bp", CFG, CONFIG)
    assert summary["files_added"] == 1 and summary["shards"] == 2
    files = library_files(lib, "cr3bp", "0.500")
    assert [f.name for f in files] == ["shards-00008-00009.parquet"]
    again = export_library(solutions, lib, "cr3bp", CFG, CONFIG)
    assert again["files_added"] == 0 and again["rows"] == summary["rows"]
    manifest = read_manifest(lib, "cr3bp")
    entry = manifest["files"][0]
    assert entry["shards"] == [8, 9] and len(entry["sha256"]) == 64 and entry["options_hashes"]
    # the config recorded as written and as it took effect (merged over the defaults), with its hash
    assert manifest["config"] == CONFIG.read_text() and manifest["config_hash"] == CFG.hash
    assert manifest["effective_config"] == CFG.model_dump(mode="json")


def test_export_refuses_a_shard_of_another_config(tmp_path):
    solutions = real_shards(tmp_path, n=1)
    shard = next(solutions.glob("alpha=*/shard-*.parquet"))
    df = pd.read_parquet(shard)
    df["seed"] = 12345  # what a smoke or default run would have made
    df.to_parquet(shard, index=False)
    with pytest.raises(InputError, match=r"shard-8\.parquet: seed \[12345\] is not the library config's seed"):
        export_library(solutions, tmp_path / "library", "cr3bp", CFG, CONFIG)
    assert not (tmp_path / "library").exists()


def test_export_refuses_a_short_shard_and_a_truncated_one(tmp_path):
    solutions = real_shards(tmp_path, n=2)
    first, second = sorted(solutions.glob("alpha=*/shard-*.parquet"))
    original = pd.read_parquet(first)
    original.head(3).to_parquet(first, index=False)
    with pytest.raises(InputError, match=r"shard-8\.parquet: 3 rows, the library config makes 12 per shard"):
        export_library(solutions, tmp_path / "library", "cr3bp", CFG, CONFIG)
    original.to_parquet(first, index=False)
    data = second.read_bytes()
    second.write_bytes(data[: len(data) // 2])
    with pytest.raises(InputError, match=r"shard-9\.parquet: not a readable Parquet table"):
        export_library(solutions, tmp_path / "library", "cr3bp", CFG, CONFIG)


def test_export_clips_tiny_bound_violations_and_refuses_large_ones(tmp_path):
    solutions = real_shards(tmp_path, n=1)
    shard = next(solutions.glob("alpha=*/shard-*.parquet"))
    df = pd.read_parquet(shard)
    rho = [c for c in df if c.startswith("rho_")]
    row, column = next((r, c) for r in np.flatnonzero(df["converged"]) for c in rho if df.loc[r, c] == 1.0)
    df.loc[row, column] = 1.0 + 9e-9  # full throttle, a few 1e-9 past its bound (IPOPT's bound relaxation)
    df.to_parquet(shard, index=False)
    export_verified(solutions, tmp_path / "lib1", "cr3bp", CFG, CONFIG, resolve_sample=0)  # rows re-verified
    stored = read_library(tmp_path / "lib1", "cr3bp", "0.500")
    assert stored.loc[row, column] == 1.0
    df.loc[row, "m_f"] = 999.0  # the fuel bound is the initial fuel, ≈ 452 kg
    df.to_parquet(shard, index=False)
    with pytest.raises(InputError, match=r"column 'm_f' lies .* outside its bounds"):
        export_library(solutions, tmp_path / "lib2", "cr3bp", CFG, CONFIG)
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
    from amorgs.library_grow import snakemake_command

    monkeypatch.chdir(ROOT)
    cmd = snakemake_command(CONFIG, "results/library-grow", 2, ["a.parquet"], profile="workflow/profiles/slurm")
    assert cmd[cmd.index("--profile") + 1] == str(ROOT / "workflow" / "profiles" / "slurm")
    assert "--profile" not in snakemake_command(CONFIG, "results/library-grow", 2, ["a.parquet"])


def test_grow_until_converged_picks_the_short_alphas_and_stops_when_none_is_left(tmp_path):
    from amorgs.library_grow import grow, short_alphas

    per_alpha = {e["alpha"]: e["converged"] for e in read_manifest(LIBRARY, "cr3bp")["per_alpha"]}
    target = sorted(per_alpha.values())[len(per_alpha) // 2]  # about half the α lie below it
    short = short_alphas(CONFIG, LIBRARY, "cr3bp", target)
    assert sorted(short) == [a for a in sorted(per_alpha) if per_alpha[a] < target] and 0 < len(short) < len(per_alpha)
    assert short_alphas(CONFIG, LIBRARY, "cr3bp", target, alphas=[1.0, short[0]]) == [short[0]]
    assert sorted(short_alphas(CONFIG, tmp_path / "none", "cr3bp", 1)) == sorted(per_alpha)  # an empty library: all
    said = []
    # every α already holds ≥ 1 converged solution: nothing to grow, no Snakemake started
    assert grow(LIBRARY_CONFIG, LIBRARY, "cr3bp", tmp_path / "work", batches=3, niceness=0, log=said.append,
                until_converged=1) == []
    assert said == ["library-grow: every α holds ≥ 1 converged solutions, stopping"]
    assert not (tmp_path / "work").exists()


@pytest.mark.parametrize("option, kwargs", [
    ("--batches 0", {"batches": 0}),
    ("--hours -1", {"hours": -1.0}),
    ("--hours nan", {"hours": float("nan")}),
    ("--cores 0", {"cores": 0}),
    ("--nice 20", {"niceness": 20}),
    ("--until-converged 0", {"until_converged": 0}),
])
def test_grow_refuses_counts_that_would_do_nothing_naming_the_option(tmp_path, option, kwargs):
    from amorgs.library_grow import grow

    with pytest.raises(ConfigError, match=f"^{option.split()[0]} "):
        grow(CONFIG, LIBRARY, "cr3bp", tmp_path / "work", **{"niceness": 0, **kwargs})
    assert not (tmp_path / "work").exists()


def test_grow_cli_says_which_option_is_wrong_in_one_line(tmp_path):
    res = amorgs("library-grow", "--config", str(CONFIG), "--library-dir", str(LIBRARY),
                 "--workdir", str(tmp_path / "work"), "--batches", "0")
    assert res.returncode != 0 and "Traceback" not in res.stderr
    assert res.stderr.strip() == "amorgs library-grow: --batches 0: run at least 1 batch"


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


def other_config(tmp_path: Path, change: str) -> Path:
    """A copy of the library config with one change: its ``seed`` or its solver's ``max_iter``."""
    import yaml

    cfg = yaml.safe_load(CONFIG.read_text())
    if change == "seed":
        cfg["seed"] = 5
    else:
        cfg["problems"]["cr3bp"]["solver"]["max_iter"] = 50
    path = tmp_path / "mine.yaml"
    path.write_text(yaml.safe_dump(cfg))
    return path


@pytest.mark.parametrize("change", ["seed", "max_iter"])
def test_export_takes_only_the_library_configs_shards_whatever_config_it_is_given(tmp_path, change):
    """`library-export --config config/mine.yaml` used to let that config's shards in and rewrite the
    manifest's seed and config for every solve held: the library belongs to one config identity."""
    from amorgs.data.library import library_identity
    from amorgs.data.seeds import shard_seed

    lib = tmp_path / "library"
    export_library(real_shards(tmp_path, n=1), lib, "cr3bp", CFG, CONFIG)
    manifest_before = (lib / "cr3bp" / "provenance.json").read_bytes()
    mine = other_config(tmp_path, change)
    identity = library_identity(load_config(mine), "cr3bp")
    # a shard exactly as config/mine.yaml makes it, at an index the library does not hold
    theirs = tmp_path / "theirs" / "alpha=0.500" / "shard-7.parquet"
    theirs.parent.mkdir(parents=True)
    df = read_library(LIBRARY, "cr3bp", "0.500").query("shard == 8").drop(columns="source", errors="ignore")
    df = df.assign(shard=7, seed=shard_seed(identity["seed"], "cr3bp", 0.5, 7), options_hash=identity["options_hash"])
    guess_columns = [c for c in df.columns if c.startswith("guess_")]
    df[guess_columns] = seeded_guesses(df, "cr3bp")  # the guesses that seed draws, as the generate rule would
    df.to_parquet(theirs, index=False)
    with pytest.raises(InputError, match=rf"mine\.yaml: not the config of the library .*{change if change == 'seed' else 'options_hash'}"):
        export_library(theirs.parent.parent, lib, "cr3bp", load_config(mine), mine)
    assert (lib / "cr3bp" / "provenance.json").read_bytes() == manifest_before
    res = amorgs("library-export", "--solutions-dir", str(theirs.parent.parent), "--library-dir", str(lib),
                 "--config", str(mine))
    assert res.returncode == 1 and "Traceback" not in res.stderr and len(res.stderr.strip().splitlines()) == 1
    assert str(mine) in res.stderr and "--library-dir" in res.stderr
    # a different library is its own directory and manifest
    summary = export_library(theirs.parent.parent, tmp_path / "mine-library", "cr3bp", load_config(mine), mine)
    assert summary["rows_added"] == 12
    assert read_manifest(tmp_path / "mine-library", "cr3bp")["identity"] == identity


def test_export_refuses_a_shard_solved_with_other_solver_options(tmp_path):
    solutions = real_shards(tmp_path, n=1)
    shard = next(solutions.glob("alpha=*/shard-*.parquet"))
    pd.read_parquet(shard).assign(options_hash="0123456789ab").to_parquet(shard, index=False)
    with pytest.raises(InputError, match=r"shard-8\.parquet: solver-option hash 0123456789ab, the library config's"):
        export_library(solutions, tmp_path / "library", "cr3bp", CFG, CONFIG)


def test_export_refuses_a_held_shard_with_different_solves_naming_it(tmp_path):
    """A shard index the library holds, with other content, used to be skipped silently with exit 0."""
    solutions = real_shards(tmp_path, n=2)
    lib = tmp_path / "library"
    export_library(solutions, lib, "cr3bp", CFG, CONFIG)
    manifest_before = (lib / "cr3bp" / "provenance.json").read_bytes()
    shard = sorted(solutions.glob("alpha=*/shard-*.parquet"))[1]
    df = pd.read_parquet(shard)
    row = int(np.flatnonzero(df["converged"])[0])
    df.loc[row, "m_f"] -= 0.5  # one solve differs
    df.to_parquet(shard, index=False)
    with pytest.raises(InputError, match=r"shard-9\.parquet: the library already holds shard 9 .* different solves"):
        export_library(solutions, lib, "cr3bp", CFG, CONFIG)
    res = amorgs("library-export", "--solutions-dir", str(solutions), "--library-dir", str(lib), "--config", str(CONFIG))
    assert res.returncode == 1 and str(shard) in res.stderr and len(res.stderr.strip().splitlines()) == 1
    assert (lib / "cr3bp" / "provenance.json").read_bytes() == manifest_before


def test_export_of_identical_held_shards_is_a_no_op_with_one_line(tmp_path):
    solutions = real_shards(tmp_path, n=2)
    lib = tmp_path / "library"
    export_library(solutions, lib, "cr3bp", CFG, CONFIG)
    before = {p: p.read_bytes() for p in (lib / "cr3bp").rglob("*") if p.is_file()}
    for shard in solutions.glob("alpha=*/shard-*.parquet"):  # rerun timings differ: still the same solves
        pd.read_parquet(shard).assign(wall_s=1.0, cpu_s=1.0).to_parquet(shard, index=False)
    res = amorgs("library-export", "--solutions-dir", str(solutions), "--library-dir", str(lib), "--config", str(CONFIG))
    assert res.returncode == 0, res.stderr
    assert res.stdout.strip().splitlines() == [
        f"{lib}/cr3bp: nothing new: the 2 shard(s) under {solutions} are already in the library, identical"]
    assert {p: p.read_bytes() for p in (lib / "cr3bp").rglob("*") if p.is_file()} == before


def test_verify_library_names_an_unlisted_a_truncated_and_a_missing_file(tmp_path):
    from amorgs.data.library import verify_library

    assert verify_library(LIBRARY, "cr3bp")["totals"]["rows"] > 0
    lib = tmp_path / "library"
    export_library(real_shards(tmp_path, n=2), lib, "cr3bp", CFG, CONFIG)
    target = library_files(lib, "cr3bp", "0.500")[0]
    stray = lib / "cr3bp" / "alpha=0.500" / "notes.parquet"
    stray.write_bytes(b"x")
    with pytest.raises(InputError, match=rf"{stray}: not listed in"):
        verify_library(lib, "cr3bp")
    stray.unlink()
    data = target.read_bytes()
    target.write_bytes(data[:-100])
    with pytest.raises(InputError, match=rf"{target}: differs from .*provenance\.json"):
        verify_library(lib, "cr3bp")
    target.unlink()
    with pytest.raises(InputError, match=rf"{target}: listed in .* but missing"):
        verify_library(lib, "cr3bp")
    assert verify_library(tmp_path / "none", "cr3bp") is None


@pytest.mark.slow
def test_grow_runs_a_real_batch_and_exports_it(tmp_path, monkeypatch):
    """One batch of a tiny library config through the real Snakemake workflow, then its export; a second
    call starts the next batch and never regenerates or duplicates a held shard."""
    import yaml

    from amorgs.library_grow import grow

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
    with pytest.raises(InputError, match=r"--library-dir .*library: no library there .* --new-library starts one"):
        grow(config, lib, "cr3bp", tmp_path / "work", cores=1, batches=2, niceness=0, log=lambda *_: None)
    first = grow(config, lib, "cr3bp", tmp_path / "work", cores=1, batches=2, niceness=0, log=lambda *_: None,
                 new_library=True)
    assert [s["batch"] for s in first] == [0, 1] and all(s["snakemake_exit"] == 0 for s in first)
    manifest = read_manifest(lib, "cr3bp")
    assert manifest["totals"]["rows"] == 4 and manifest["totals"]["shards"] == 4
    assert sorted((e["alpha"], e["shards"][0]) for e in manifest["files"]) == [(0.6, 0), (0.6, 1), (0.9, 0), (0.9, 1)]
    table = read_library(lib, "cr3bp", "0.600")
    assert sorted(table["shard"]) == [0, 1] and (table["iterations"] <= 20).all()


def test_export_stores_guesses_by_seed_and_reads_them_back_bit_for_bit(tmp_path):
    import pyarrow.parquet as pq

    solutions = real_shards(tmp_path, n=2)
    original = pd.concat([pd.read_parquet(p) for p in sorted(solutions.glob("alpha=*/shard-*.parquet"))],
                         ignore_index=True)
    lib = tmp_path / "library"
    export_library(solutions, lib, "cr3bp", CFG, CONFIG)
    (path,) = library_files(lib, "cr3bp", "0.500")
    stored_columns = pq.ParquetFile(path).schema_arrow.names
    assert not [c for c in stored_columns if c.startswith("guess_")]  # compact: 64 columns fewer on disk
    back = read_library(lib, "cr3bp", "0.500").drop(columns=["source"], errors="ignore")
    assert list(back.columns) == list(original.columns)
    pd.testing.assert_frame_equal(back, original, check_exact=True)
    manifest = read_manifest(lib, "cr3bp")
    assert manifest["files"][0]["guesses"] == "seeded"
    # exported under the generation-1 solver: generation 1, with its totals
    (generation,) = manifest["generations"]
    assert generation["generation"] == manifest["files"][0]["generation"] == 1
    assert generation["rows"] == len(original) and generation["options_hashes"] == sorted(set(original["options_hash"]))


def test_export_refuses_guesses_that_are_not_the_seeded_draw(tmp_path):
    solutions = real_shards(tmp_path, n=1)
    shard = next(solutions.glob("alpha=*/shard-*.parquet"))
    df = pd.read_parquet(shard)
    df.loc[3, "guess_tau_s"] += 1e-12
    df.to_parquet(shard, index=False)
    with pytest.raises(InputError, match=r"initial guesses are not the seeded uniform draw"):
        export_library(solutions, tmp_path / "library", "cr3bp", CFG, CONFIG)


def test_a_later_solver_generation_starts_a_generation_and_nothing_else_gets_in(tmp_path):
    """Generation 1 rows held (RK8 coasts, L-BFGS history 30): the library config with today's solver (generation
    2) may start generation 2; the generation-1 solver with another option (another hash, same generation) is
    refused naming the key."""
    from amorgs.data.library import _check_same_library, library_identity, solver_generation
    import yaml

    def config_with(name, **solver):
        cfg = mapping("library")
        cfg["problems"]["cr3bp"].setdefault("solver", {}).update(solver)
        (tmp_path / name).write_text(yaml.safe_dump(cfg))
        return load_config(tmp_path / name)

    rk8 = {"lbfgs_memory": 30, "transcription": {"coast": "rk8"}}
    generation_1 = config_with("rk8.yaml", **rk8).problems.cr3bp.solver.digest()
    assert generation_1 == "42bf7b6dd566"  # the hash of every generation-1 row in data/library
    manifest = {"files": [{"options_hashes": [generation_1], "generation": 1,
                           "exported": "2026-01-01", "file": "alpha=0.500/x.parquet"}],
                "seed": CFG.seed, "starts_per_shard": 12, "config_file": str(LIBRARY_CONFIG)}
    today = load_config(LIBRARY_CONFIG)
    assert today.problems.cr3bp.solver.transcription.coast == "interpolant"
    _check_same_library(manifest, library_identity(today, "cr3bp"), today.problems.cr3bp.solver, LIBRARY_CONFIG,
                        tmp_path)
    other = config_with("other.yaml", max_iter=50, **rk8)
    with pytest.raises(InputError, match="options_hash"):
        _check_same_library(manifest, library_identity(other, "cr3bp"), other.problems.cr3bp.solver,
                            tmp_path / "other.yaml", tmp_path)
    # Generation 2 held (interpolated coasts, history 6): Cartesian controls start generation 3; generation 2's
    # solver with another option is refused.
    generation_2 = config_with("g2.yaml", lbfgs_memory=6, transcription={"controls": "spherical"})
    assert solver_generation(generation_2.problems.cr3bp.solver) == 2
    assert generation_2.problems.cr3bp.solver.digest() == "e2d640cc3c36"  # every generation-2 row's hash
    manifest["files"][0].update(options_hashes=["e2d640cc3c36"], generation=2)
    cartesian = config_with("g3.yaml", lbfgs_memory=6, transcription={"controls": "cartesian",
                                                                      "controls_switch_alpha": 0.5})
    assert solver_generation(cartesian.problems.cr3bp.solver) == 3
    _check_same_library(manifest, library_identity(cartesian, "cr3bp"), cartesian.problems.cr3bp.solver,
                        tmp_path / "g3.yaml", tmp_path)
    other = config_with("other2.yaml", lbfgs_memory=7, transcription={"controls": "spherical"})
    with pytest.raises(InputError, match="options_hash"):
        _check_same_library(manifest, library_identity(other, "cr3bp"), other.problems.cr3bp.solver,
                            tmp_path / "other2.yaml", tmp_path)


def test_the_shipped_library_config_is_the_committed_librarys(tmp_path):
    """config/library.yaml holds only overrides of the typed defaults: merged over them it still has the
    identity the committed manifest records (seed, starts per shard, solver-option hash), and `library-export
    --config config/library.yaml` accepts the committed library with its own shards, leaving every byte as it
    was."""
    from amorgs.data.library import library_identity

    identity = library_identity(load_config(LIBRARY_CONFIG), "cr3bp")
    assert identity == manifest_identity(read_manifest(LIBRARY, "cr3bp"))
    lib = tmp_path / "library"
    shutil.copytree(LIBRARY / "cr3bp", lib / "cr3bp")
    before = {p: p.read_bytes() for p in (lib / "cr3bp").rglob("*") if p.is_file()}
    manifest = read_manifest(LIBRARY, "cr3bp")
    label = next(e["file"].split("/")[0].removeprefix("alpha=") for e in manifest["files"]
                 if identity["options_hash"] in e["options_hashes"])
    solutions = real_shards(tmp_path, label, n=1, options_hash=identity["options_hash"])
    res = amorgs("library-export", "--solutions-dir", str(solutions), "--library-dir", str(lib),
                 "--config", str(LIBRARY_CONFIG))
    assert res.returncode == 0, res.stderr
    assert "nothing new: the 1 shard(s)" in res.stdout and "identical" in res.stdout
    assert {p: p.read_bytes() for p in (lib / "cr3bp").rglob("*") if p.is_file()} == before


def test_compaction_keeps_every_row_bit_for_bit_and_exports_still_find_held_shards(tmp_path):
    """Two exports (two files) plus a file stored the generation-1 way (guess columns on disk) become one compact
    file: the same table read back, the manifest's totals and shard provenance kept, a second compaction a
    no-op, and a re-export of the same shards finds them held and identical."""
    import pyarrow.parquet as pq

    from amorgs.data.library import restore_seeded_guesses, sha256_file, verify_library
    from amorgs.data.io import write_json

    solutions = real_shards(tmp_path, n=3)
    lib = tmp_path / "library"
    first, second, third = sorted(solutions.glob("alpha=*/shard-*.parquet"))
    for i, shard in enumerate((first, second, third)):  # one export per shard: three files
        one = tmp_path / f"batch{i}" / shard.parent.name
        one.mkdir(parents=True)
        shutil.copy(shard, one / shard.name)
        export_library(one.parent, lib, "cr3bp", CFG, CONFIG)
    manifest = read_manifest(lib, "cr3bp")
    root = lib / "cr3bp"
    legacy = manifest["files"][0]  # rewrite one file as generation 1 stored it: guesses on disk
    path = root / legacy["file"]
    restore_seeded_guesses(pd.read_parquet(path), "cr3bp").to_parquet(path, index=False)
    legacy.update(sha256=sha256_file(path), bytes=path.stat().st_size)
    del legacy["guesses"]
    write_json(manifest, root / "provenance.json")
    before = read_library(lib, "cr3bp", "0.500")
    totals = {k: manifest["totals"][k] for k in ("rows", "converged", "shards")}

    summary = compact_library(lib, "cr3bp")
    assert summary["before"]["files"] == 3 and summary["after"]["files"] == 1
    assert summary["after"]["bytes"] < summary["before"]["bytes"]
    verify_library(lib, "cr3bp")  # every file listed, hashes right, nothing left over
    (path,) = library_files(lib, "cr3bp", "0.500")
    assert not [c for c in pq.ParquetFile(path).schema_arrow.names if c.startswith("guess_")]
    pd.testing.assert_frame_equal(read_library(lib, "cr3bp", "0.500"), before, check_exact=True)
    manifest = read_manifest(lib, "cr3bp")
    assert {k: manifest["totals"][k] for k in ("rows", "converged", "shards")} == totals
    (entry,) = manifest["files"]
    assert len(entry["sources"]) == 3 and sorted(k for s in entry["sources"] for k in s["shards"]) == entry["shards"]
    assert manifest["compactions"][-1]["files_before"] == 3
    assert compact_library(lib, "cr3bp")["files_rewritten"] == 0
    assert export_library(solutions, lib, "cr3bp", CFG, CONFIG)["held_identical"] == 3


def test_a_generation_never_mixes_codes():
    """Rows with a fingerprint start a generation of their own beside the unfingerprinted ones, join it while
    their code is the same at their α, and start the next one when it differs (issue 37)."""
    from amorgs.data.library import assign_generation

    manifest = {"files": [{"generation": 3, "options_hashes": ["h"]}]}
    assert assign_generation(manifest, 3, "h", "0.500", "", "c0") == 3  # no fingerprint: the solver's generation
    assert assign_generation(manifest, 3, "h", "0.500", "aaa", "c1") == 4  # the first fingerprinted rows
    assert assign_generation(manifest, 3, "h", "0.700", "bbb", "c1") == 4  # another α of the same code
    assert assign_generation(manifest, 3, "h", "0.500", "aaa", "c2") == 4  # the same code again
    assert assign_generation(manifest, 3, "h", "0.500", "zzz", "c3") == 5  # one bit moved at α = 0.5
    assert assign_generation(manifest, 3, "g", "0.700", "bbb", "c3") == 6  # other options
    codes = manifest["generation_codes"]
    assert codes["4"]["nlp_fingerprints"] == {"0.500": "aaa", "0.700": "bbb"} and codes["4"]["first_commit"] == "c1"
    assert codes["5"]["nlp_fingerprints"] == {"0.500": "zzz"} and codes["5"]["based_on"] == 3
    assert assign_generation(manifest, 3, "h", "0.700", "bbb", "c4") == 4  # old code's rows find their generation


# ------------------------------------------------------------------------------------------- the gate (issue 39)


def _small_library_config(tmp_path: Path) -> Path:
    """A library config whose shards are cheap (2 starts, at most 60 uncompiled IPOPT iterations)."""
    import yaml

    cfg = mapping("library")
    cfg["problems"]["cr3bp"]["generate"]["starts_per_shard"] = 2
    cfg["problems"]["cr3bp"]["solver"].update(max_iter=60, compile="none")
    cfg["ablation"]["iteration_caps"] = [30, 60]
    path = tmp_path / "library.yaml"
    path.write_text(yaml.safe_dump(cfg))
    return path


def _fresh_shard(solutions: Path, config: Path, shard: int, alpha: float = 0.5) -> Path:
    """One shard of ``config`` at α solved now, with today's code, as the generate rule writes it."""
    from amorgs.data.seeds import shard_seed
    from amorgs.problems import get_problem
    from amorgs.solvers.multistart import run_multistart

    cfg = load_config(config)
    section = cfg.problems.cr3bp
    table = run_multistart(get_problem("cr3bp"), alpha, shard_seed(cfg.seed, "cr3bp", alpha, shard),
                           section.generate.starts_per_shard, options=section.solver, progress=False)
    path = solutions / f"alpha={alpha:.3f}" / f"shard-{shard}.parquet"
    path.parent.mkdir(parents=True, exist_ok=True)
    table.insert(3, "shard", shard)
    table.to_parquet(path, index=False)
    return path


def test_the_gate_re_solves_a_seeded_start_and_refuses_what_this_code_did_not_solve(tmp_path):
    config = _small_library_config(tmp_path)
    cfg = load_config(config)
    lib, solutions = tmp_path / "library", tmp_path / "solutions"
    first = _fresh_shard(solutions, config, 0)
    assert export_verified(solutions, lib, "cr3bp", cfg, config)["rows_added"] == 2  # today's code reproduces it
    held = pd.read_parquet(first)
    shutil.rmtree(solutions)
    path = _fresh_shard(solutions, config, 1)
    honest = pd.read_parquet(path)
    for column, value, message in [("iterations", 1, r"re-solves to .* the shard says"),
                                   ("nlp_fingerprint", "0123456789ab", r"solved by code with NLP fingerprint "
                                                                       r"0123456789ab; this code's is")]:
        forged = honest.copy()
        forged[column] = forged[column] + value if column == "iterations" else value
        forged.to_parquet(path, index=False)
        with pytest.raises(InputError, match=rf"shard-1\.parquet: .*{message}"):
            export_verified(solutions, lib, "cr3bp", cfg, config)
    # a shard whose solutions are copied from a held one (under its own seed, shard number and guesses)
    copied = honest.copy()
    names = [c for c in honest if c in get_variable_names()]
    copied[names] = held[names].to_numpy()
    for c in ("status", "converged", "solver_success", "objective", "iterations", "defect", "verify_defect"):
        copied[c] = held[c].to_numpy()
    copied.to_parquet(path, index=False)
    with pytest.raises(InputError, match=r"start \d's solution is already held \(.*shards-00000-00000\.parquet\)"):
        export_verified(solutions, lib, "cr3bp", cfg, config, resolve_sample=0)
    honest.to_parquet(path, index=False)
    assert export_verified(solutions, lib, "cr3bp", cfg, config)["rows_added"] == 2


def get_variable_names() -> tuple[str, ...]:
    from amorgs.problems import get_problem

    return get_problem("cr3bp").variable_names


@pytest.mark.parametrize("forgery", ["max_iter_marked_converged", "objective_nan", "objective_invented"])
def test_the_gate_recomputes_what_a_shard_says_about_its_rows(tmp_path, forgery):
    """Rows of a real shard re-labelled as issue 39 found them admitted: converged with solver_success False,
    status Max_Iter and a re-propagation defect of 1; an objective that is not −m_f."""
    solutions = real_shards(tmp_path, n=1)
    shard = next(solutions.glob("alpha=*/shard-*.parquet"))
    df = pd.read_parquet(shard)
    bad = int(np.flatnonzero(~df["converged"] & df[list(get_variable_names())].notna().all(axis=1))[0]) \
        if forgery == "max_iter_marked_converged" else int(np.flatnonzero(df["converged"])[0])
    if forgery == "max_iter_marked_converged":
        df.loc[bad, ["converged", "verify_defect"]] = [True, 1.0]
        match = r"converged True but|solver_success False but"
    else:
        df.loc[bad, "objective"] = np.nan if forgery == "objective_nan" else -1e6
        match = r"objective .* is not the solution's"
    df.to_parquet(shard, index=False)
    with pytest.raises(InputError, match=rf"shard-\d+\.parquet: start {df.loc[bad, 'start']}: {match}"):
        export_verified(solutions, tmp_path / "library", "cr3bp", CFG, CONFIG, resolve_sample=0)
    assert not (tmp_path / "library" / "cr3bp" / "provenance.json").exists()


def test_the_gate_refuses_bad_inputs_in_one_line(tmp_path):
    lib = tmp_path / "library"
    export_library(real_shards(tmp_path, n=1), lib, "cr3bp", CFG, CONFIG)
    import yaml

    other = yaml.safe_load(CONFIG.read_text())
    other["problems"]["cr3bp"]["alphas"]["train"] = [0.42, 1.0]  # same seed, starts and solver: same identity
    mine = tmp_path / "mine.yaml"
    mine.write_text(yaml.safe_dump(other))
    weird = tmp_path / "weird" / "alpha=0.500" / "shard-abc.parquet"
    weird.parent.mkdir(parents=True)
    weird.write_bytes(b"")
    cases = [(["--solutions-dir", str(tmp_path / "nonexistent"), "--config", str(CONFIG)], "no such directory"),
             (["--solutions-dir", str(weird.parent.parent), "--config", str(CONFIG)], "not a shard table name"),
             (["--solutions-dir", str(tmp_path / "solutions"), "--config", str(mine)],
              "is grown from .* only")]
    for args, message in cases:
        res = amorgs("library-export", "--library-dir", str(lib), *args)
        assert res.returncode != 0 and "Traceback" not in res.stderr, res.stderr
        assert len(res.stderr.strip().splitlines()) == 1 and __import__("re").search(message, res.stderr), res.stderr


def test_grow_refuses_bad_inputs_in_one_line_before_any_solve(tmp_path):
    """Issue 39: a missing library, another config, a missing profile, a folder that cannot be made — each one
    line and a non-zero exit, before Snakemake starts (no working directory made)."""
    smoke = ROOT / "config" / "smoke.yaml"
    cases = [
        (["--library-dir", str(tmp_path / "nope")], r"--library-dir .*nope: no library there"),
        (["--config", str(smoke)], r"smoke\.yaml: not the config of the library"),
        (["--profile", str(tmp_path / "nope")], r"--profile .*nope: no such profile directory"),
        (["--workdir", "/proc/x"], r"--workdir /proc/x: cannot be created"),
    ]
    for args, message in cases:
        base = {"--config": str(LIBRARY_CONFIG), "--library-dir": str(LIBRARY), "--workdir": str(tmp_path / "work")}
        base.update(dict(zip(args[::2], args[1::2])))
        res = amorgs("library-grow", *[x for kv in base.items() for x in kv], "--nice", "0")
        assert res.returncode != 0 and "Traceback" not in res.stderr, res.stderr
        assert len(res.stderr.strip().splitlines()) == 1 and __import__("re").search(message, res.stderr), res.stderr
        assert not (tmp_path / "work").exists()
