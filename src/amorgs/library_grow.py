"""Growing the solution library in batches: Snakemake generates, :func:`export_library` consolidates.

A *batch* ``b`` is, for every α of the library config (its 12 training α and 2 test α), the shard indices
``b·S … b·S + S − 1`` with ``S = problems.<problem>.generate.shards``.  Shard seeds derive from (library seed,
problem, α, shard index), so batches never collide with each other or with shards the library already
holds, and every batch is balanced across α — or across the α of ``alphas`` only (e.g. the focus α of the
structure analysis first); batches are counted per α, so a focused batch never collides either.  :func:`grow` runs the lowest batch that still has shards
missing from the library, exports what finished, and repeats — each batch is one ordinary ``snakemake``
invocation (its own working directory, so it never touches a workflow run's ``results/``), and every shard
and every export is written atomically: stopping at any moment loses at most the solves in flight.
"""

from __future__ import annotations

import math
import os
import subprocess
import sys
import time
from pathlib import Path

from amorgs import layout
from amorgs.alphas import alpha_label
from amorgs.config import load_config
from amorgs.errors import ConfigError, InputError
from amorgs.data.library import MANIFEST, check_library_config, export_library, held_shards, read_manifest


def grown_alphas(config_file: str | Path, problem: str, alphas: list[float] | None = None) -> list[str]:
    """The α labels a grow covers: every α of the library config, or those of ``alphas`` (each must be one of
    them; a ``ConfigError`` names the one that is not)."""
    labels = list(getattr(load_config(config_file).problems, problem).alpha_values())
    if alphas is None:
        return labels
    unknown = [a for a in alphas if alpha_label(a) not in labels]
    if unknown:
        raise ConfigError(f"{config_file}: α {unknown[0]:g} is not one of the library α ({', '.join(labels)})")
    return [alpha_label(a) for a in alphas]


def batch_targets(config_file: str | Path, library_dir: str | Path, problem: str, batch: int,
                  alphas: list[float] | None = None) -> list[str]:
    """The shard paths (relative to the grow working directory) of ``batch`` that the library lacks, for every
    library α or only those of ``alphas``."""
    per_batch = getattr(load_config(config_file).problems, problem).generate.shards
    held = held_shards(library_dir, problem)
    return [
        layout.SHARD.format(problem=problem, alpha=label, shard=k)
        for k in range(batch * per_batch, (batch + 1) * per_batch)
        for label in grown_alphas(config_file, problem, alphas)
        if (label, k) not in held
    ]


def next_batch(config_file: str | Path, library_dir: str | Path, problem: str,
               alphas: list[float] | None = None) -> int:
    """The lowest batch with a shard (of ``alphas``, default every α) the library does not hold yet."""
    batch = 0
    while not batch_targets(config_file, library_dir, problem, batch, alphas):
        batch += 1
    return batch


def short_alphas(config_file: str | Path, library_dir: str | Path, problem: str, target: int,
                 alphas: list[float] | None = None) -> list[float]:
    """The α (of ``alphas``, default every library α) whose verified converged solutions in the library's
    manifest number fewer than ``target``, in the library config's order."""
    manifest = read_manifest(library_dir, problem) or {}
    held = {alpha_label(e["alpha"]): e["converged"] for e in manifest.get("per_alpha", [])}
    return [float(label) for label in grown_alphas(config_file, problem, alphas) if held.get(label, 0) < target]


def find_snakefile(root: str | Path = ".") -> Path:
    """The workflow's Snakefile in the repository at ``root`` (where Snakemake itself would look)."""
    for candidate in ("workflow/Snakefile", "Snakefile"):
        if (Path(root) / candidate).is_file():
            return (Path(root) / candidate).resolve()
    raise FileNotFoundError(f"no Snakefile under {Path(root).resolve()}: run library-grow from the repository root")


def snakemake_command(config_file: str | Path, workdir: str | Path, cores: int, targets: list[str],
                      profile: str | Path | None = None) -> list[str]:
    """The Snakemake call of one batch: the repository's workflow, run in ``workdir``; with ``profile`` (e.g.
    ``workflow/profiles/slurm``) its jobs go where that profile sends them."""
    return [
        sys.executable, "-m", "snakemake", *targets,
        "--snakefile", str(find_snakefile()),
        "--directory", str(Path(workdir).resolve()),
        "--configfile", str(Path(config_file).resolve()),
        "--cores", str(cores),
        "--rerun-incomplete",
        "--keep-going",
        *(["--profile", str(Path(profile).resolve())] if profile else []),
    ]


def check_grow_arguments(batches: int, hours: float | None, cores: int, niceness: int,
                         until_converged: int | None) -> None:
    """A ``ConfigError`` naming the option, for counts that would make :func:`grow` do nothing (or nonsense)."""
    if batches < 1:
        raise ConfigError(f"--batches {batches}: run at least 1 batch")
    if hours is not None and not (math.isfinite(hours) and hours > 0):
        raise ConfigError(f"--hours {hours}: give a positive number of hours (or leave it out: no time limit)")
    if cores < 1:
        raise ConfigError(f"--cores {cores}: Snakemake needs at least 1 core")
    if not 0 <= niceness <= 19:
        raise ConfigError(f"--nice {niceness}: the niceness added lies in 0–19 (0: none)")
    if until_converged is not None and until_converged < 1:
        raise ConfigError(f"--until-converged {until_converged}: give at least 1 converged solution per α")


def check_grow_inputs(config_file: str | Path, library_dir: str | Path, problem: str, workdir: str | Path,
                      profile: str | Path | None, new_library: bool) -> None:
    """Before any solve: the library exists (or ``new_library`` asks for one) and ``config_file`` may grow it
    (its identity and file: :func:`~amorgs.data.library.check_library_config`), the profile is a directory and the
    working directory can be made — else one ``InputError``/``ConfigError`` naming the option or file."""
    root = Path(library_dir) / problem
    manifest = read_manifest(library_dir, problem)
    if manifest is None and not new_library:
        raise InputError(f"--library-dir {library_dir}: no library there ({root / MANIFEST} missing); "
                         "--new-library starts one")
    if manifest is not None:
        check_library_config(manifest, load_config(config_file), config_file, root, problem)
    if profile is not None and not Path(profile).is_dir():
        raise ConfigError(f"--profile {profile}: no such profile directory (e.g. workflow/profiles/slurm)")
    existing = Path(workdir).resolve()
    while not existing.exists():  # the nearest existing folder must take the working directory
        existing = existing.parent
    if not existing.is_dir() or not os.access(existing, os.W_OK) or existing.is_relative_to("/proc"):
        raise ConfigError(f"--workdir {workdir}: cannot be created ({existing} is not a writable folder)")


def grow(config_file: str | Path, library_dir: str | Path = "data/library", problem: str = "cr3bp",
         workdir: str | Path = "results/library-grow", cores: int = 2, batches: int = 1,
         hours: float | None = None, niceness: int = 19, log=print, alphas: list[float] | None = None,
         until_converged: int | None = None, profile: str | Path | None = None,
         new_library: bool = False) -> list[dict]:
    """Run up to ``batches`` batches (stop starting new ones after ``hours``), exporting after each one;
    ``alphas`` restricts the batches to those library α.  With ``until_converged``, each batch covers only
    the α (of ``alphas``) that still hold fewer verified converged solutions than that, and growth stops
    once none does — so the slow, low-convergence α get the extra batches they need and the others none.
    ``profile`` is the Snakemake profile of every batch (e.g. ``workflow/profiles/slurm``: jobs on the cluster).
    Everything is checked before the first solve (:func:`check_grow_inputs`; ``new_library``: start a library
    where there is none).

    Returns one export summary per batch (see :func:`export_library`).  ``niceness`` is added to this
    process's priority (and so to Snakemake's and its jobs') before anything starts.
    """
    check_grow_arguments(batches, hours, cores, niceness, until_converged)
    grown_alphas(config_file, problem, alphas)  # a bad α fails before anything starts
    check_grow_inputs(config_file, library_dir, problem, workdir, profile, new_library)
    if niceness:
        os.nice(niceness)
    t0 = time.monotonic()
    solutions = Path(workdir) / "results" / problem / "solutions"
    summaries = []
    for _ in range(batches):
        if hours is not None and time.monotonic() - t0 > hours * 3600:
            log(f"library-grow: {hours} h elapsed, not starting another batch")
            break
        grown = alphas
        if until_converged is not None:
            grown = short_alphas(config_file, library_dir, problem, until_converged, alphas)
            if not grown:
                log(f"library-grow: every α holds ≥ {until_converged} converged solutions, stopping")
                break
        batch = next_batch(config_file, library_dir, problem, grown)
        targets = batch_targets(config_file, library_dir, problem, batch, grown)
        log(f"library-grow: batch {batch}: {len(targets)} shard job(s) in {workdir}"
            + (f" (α below {until_converged} converged: {', '.join(f'{a:g}' for a in grown)})" if until_converged else ""))
        done = subprocess.run(snakemake_command(config_file, workdir, cores, targets, profile), check=False)
        summary = export_library(solutions, library_dir, problem, load_config(config_file), config_file)
        summaries.append({"batch": batch, "snakemake_exit": done.returncode, **summary})
        log(f"library-grow: batch {batch} exported: {summary['rows_added']} new rows; library {summary['rows']} rows, "
            f"{summary['converged']} converged, {summary['cpu_hours']:.2f} CPU-hours")
        if done.returncode != 0:
            log(f"library-grow: snakemake exited {done.returncode}; what finished was exported, stopping")
            break
    return summaries
