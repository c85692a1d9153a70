"""Model checkpoints shipped in the repository (``data/models/cr3bp/``), so that ``amorgs design`` can use
the learned samplers on a fresh clone without a workflow run.

Layout::

    data/models/cr3bp/{cvae_gmm,vanilla_cvae,lstm}.pt     the checkpoints of one workflow run's train step
    data/models/cr3bp/selector.joblib                     the transfer selector of one run's train_selector
                                                          (issue 38 §5; ``export_selector``), optional, and
    data/models/cr3bp/selector.transfer.parquet           its training data: every transfer solve of that run
    data/models/cr3bp/provenance.json                     manifest: per file SHA-256 and bytes; the config
                                                          (file, hash), git commit, export time, and the
                                                          library manifest's SHA-256 + rows they were trained on,
                                                          and the code that solved those rows (per generation:
                                                          options hashes, NLP fingerprints)

:func:`verify_models` refuses (``InputError`` naming the file) a checkpoint that is missing, unlisted or whose
SHA-256 differs from the manifest.
"""

from __future__ import annotations

import datetime as _dt
import json
import shutil
from pathlib import Path

import pandas as pd

from amorgs.data.io import atomic_path, write_json
from amorgs.data.library import MANIFEST as LIBRARY_MANIFEST
from amorgs.data.library import git_commit, read_manifest, sha256_file
from amorgs.errors import InputError
from amorgs.models.names import CHECKPOINTS, PAPER_MODELS

MANIFEST = "provenance.json"
#: The transfer data the shipped selector was trained on (every transfer shard of its run, one table).
SELECTOR_DATA = "selector.transfer.parquet"
CHECKPOINT_FILES = tuple(CHECKPOINTS[name] for name in PAPER_MODELS)


def export_models(models_dir: str | Path, dest: str | Path, cfg, config_file: str | Path,
                  library_dir: str | Path = "data/library", problem: str = "cr3bp") -> dict:
    """Copy the checkpoints of ``models_dir`` (a workflow run's ``results/cr3bp/models``) to ``dest`` and write
    the manifest; returns it.  ``cfg``: the typed config of the run that trained them, read from
    ``config_file`` (:func:`amorgs.config.load_config`)."""
    src, dst = Path(models_dir), Path(dest)
    files = []
    for name in CHECKPOINT_FILES:
        if not (src / name).is_file():
            raise InputError(f"{src / name}: checkpoint not found (run the workflow's train step first)")
        with atomic_path(dst / name) as tmp:
            shutil.copyfile(src / name, tmp)
        files.append(_file_entry(dst / name))
    library = read_manifest(library_dir, problem)
    manifest = {
        "problem": problem,
        "files": files,
        "config_file": str(config_file),
        "config_hash": cfg.hash,
        "cr3bp_models": cfg.cr3bp_models.model_dump(mode="json"),
        "train_alphas": list(cfg.problems.cr3bp.alphas.train_values()),
        **_library_record(library, library_dir, problem),
        # the code that solved the training rows: each generation's options hashes and NLP fingerprints (issue 37)
        "library_identity": [{k: g.get(k) for k in ("generation", "options_hashes", "nlp_fingerprints")}
                             for g in (library or {}).get("generations", [])],
        "exported": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"),
        "git_commit": git_commit(),
    }
    kept = _shipped_selector(dst)  # a selector shipped earlier stays, with its own record
    if kept is not None:
        manifest["files"] += kept[0]
        manifest["selector"] = kept[1]
    write_json(manifest, dst / MANIFEST)
    return manifest


def _shipped_selector(dest: Path) -> tuple[list[dict], dict] | None:
    """(file entries, ``selector`` record) of the selector and its data shipped in ``dest`` when its manifest
    lists both and the files still match; otherwise None."""
    from amorgs.models.selector import SELECTOR_FILE

    path = dest / MANIFEST
    if not path.is_file():
        return None
    old = json.loads(path.read_text())
    entries = [f for f in old.get("files", []) if f["file"] in (SELECTOR_FILE, SELECTOR_DATA)]
    if len(entries) != 2 or "selector" not in old:
        return None
    intact = all((dest / f["file"]).is_file() and sha256_file(dest / f["file"]) == f["sha256"] for f in entries)
    return (entries, old["selector"]) if intact else None


def _file_entry(path: Path) -> dict:
    """A manifest's record of one shipped file: name, SHA-256, bytes."""
    return {"file": path.name, "sha256": sha256_file(path), "bytes": path.stat().st_size}


def _library_record(library: dict | None, library_dir: str | Path, problem: str) -> dict:
    """The library a model was trained on (``library``: its manifest, as read): the manifest's SHA-256 and rows."""
    library_path = Path(library_dir) / problem / LIBRARY_MANIFEST
    return {"library_manifest_sha256": sha256_file(library_path) if library is not None else None,
            "library_rows": library["totals"]["rows"] if library is not None else 0}


def export_selector(models_dir: str | Path, dest: str | Path, cfg, config_file: str | Path,
                    library_dir: str | Path = "data/library", problem: str = "cr3bp") -> dict:
    """Copy the transfer selector of ``models_dir`` (a run's ``results/cr3bp/models/selector.joblib``, trained by
    its ``train_selector`` on the transfer data of ``cfg``'s training α) beside the shipped checkpoints in
    ``dest`` and record it in their manifest (``files`` and a ``selector`` record: the run's config, its
    ``transfer`` section, training α, library, commit); returns the manifest.  ``dest`` must already hold a
    manifest of :func:`export_models` (the selector ranks the library's solutions for the same design)."""
    from amorgs.models.selector import SELECTOR_FILE

    src, dst = Path(models_dir), Path(dest)
    path = dst / MANIFEST
    if not path.is_file():
        raise InputError(f"{path}: no shipped models manifest (export the checkpoints first: amorgs models-export)")
    if not (src / SELECTOR_FILE).is_file():
        raise InputError(f"{src / SELECTOR_FILE}: selector not found (run the workflow's train_selector: "
                         "transfer.enabled, e.g. config/selector-model.yaml)")
    if not cfg.transfer.enabled:
        raise InputError(f"{config_file}: transfer.enabled is false — not the config of a run that trained a selector")
    shards = sorted((src.parent / "transfer").glob("alpha=*/from=*/shard-*.parquet"))  # layout.TRANSFER_SHARD
    if not shards:
        raise InputError(f"{src.parent / 'transfer'}: no transfer shards beside the selector (the run's training data)")
    manifest = json.loads(path.read_text())
    with atomic_path(dst / SELECTOR_FILE) as tmp:
        shutil.copyfile(src / SELECTOR_FILE, tmp)
    data = pd.concat([pd.read_parquet(f) for f in shards], ignore_index=True)
    with atomic_path(dst / SELECTOR_DATA) as tmp:
        data.to_parquet(tmp, index=False, compression="zstd")
    entries = [_file_entry(dst / name) for name in (SELECTOR_FILE, SELECTOR_DATA)]
    entries[1]["rows"] = len(data)
    manifest["files"] = [f for f in manifest["files"] if f["file"] not in (SELECTOR_FILE, SELECTOR_DATA)] + entries
    manifest["selector"] = {
        "config_file": str(config_file), "config_hash": cfg.hash,
        "transfer": cfg.transfer.model_dump(mode="json"),
        "train_alphas": list(cfg.problems.cr3bp.alphas.train_values()),
        **_library_record(read_manifest(library_dir, problem), library_dir, problem),
        "exported": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"),
        "git_commit": git_commit(),
    }
    write_json(manifest, path)
    return manifest


def verify_models(models_dir: str | Path, needed: tuple[str, ...] = CHECKPOINT_FILES) -> dict | None:
    """Check the ``needed`` checkpoints of a shipped models folder against its manifest; return the manifest,
    or None if the folder has no manifest (a workflow's own ``results/cr3bp/models``, trusted as is)."""
    root = Path(models_dir)
    path = root / MANIFEST
    if not path.is_file():
        return None
    try:
        manifest = json.loads(path.read_text())
    except ValueError as exc:
        raise InputError(f"{path}: not a readable models manifest ({exc})") from None
    listed = {e["file"]: e for e in manifest["files"]}
    for name in needed:
        if name not in listed:
            raise InputError(f"{root / name}: not listed in {path}")
        if not (root / name).is_file():
            raise InputError(f"{root / name}: listed in {path} but missing")
        digest = sha256_file(root / name)
        if digest != listed[name]["sha256"]:
            raise InputError(f"{root / name}: SHA-256 {digest[:12]}… differs from the manifest's "
                             f"{listed[name]['sha256'][:12]}… (modified after export; restore it with git)")
    return manifest
