"""A global-search study: cells (strategy × sampler) at one α, their searches spread over worker processes, and
the tables that answer "how soon is the best known trajectory reached" (:mod:`amorgs.ablation.global_search`).

The library-based samplers (reuse and its kin) draw on the library's high-quality rows at the *training* α: every
library α except the study's (leave-one-α-out, as the frontier's folds), or the ones named (``library_alphas``: a
sparse design's, e.g. the frontier's sparse-3 fold 0.1, 0.5, 1.0), β-filtered.  The best known objective is
the lowest of the library's verified rows at the study's α and of every feasible solution the study found
(``best_known_source`` says which).
"""

from __future__ import annotations

import json
import os
import sys
import time
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import asdict, dataclass
from multiprocessing import get_context
from pathlib import Path

import numpy as np
import pandas as pd

from amorgs.ablation.arms import build_sampler, get_arm
from amorgs.ablation.global_search import (
    DELTAS,
    Cell,
    as_search,
    best_known,
    distinct_near_best,
    ert_ratios,
    paired_ratios,
    repeats_search_0,
    run_search,
    runtime_ecdf,
    runtime_to_target,
    strategy_settings,
)
from amorgs.alphas import alpha_label
from amorgs.errors import InputError
from amorgs.problems.cr3bp import BETA_KG
from amorgs.problems.cr3bp.transcription import variable_names
from amorgs.solvers.basin_hopping import HopSettings
from amorgs.solvers.options import IpoptOptions


@dataclass(frozen=True)
class GlobalStudy:
    """What a study runs: ``searches`` searches of ``budget`` IPOPT iterations for every (strategy, sampler) at
    ``alpha``; ``solver`` is the CR3BP solver's options; β (kg) selects the library rows the
    library-based samplers draw on, at ``library_alphas`` (N; None: every library α but ``alpha``); ``models_dir``
    holds the checkpoints of learned samplers; ``record`` is the best-known record that joins the target."""

    alpha: float
    samplers: tuple[str, ...] = ("uniform", "nearest_alpha")
    strategies: tuple[str, ...] = ("multistart", "mbh")
    searches: int = 30
    budget: int = 5000
    seed: int = 0
    hops: HopSettings = HopSettings()
    deltas: tuple[float, ...] = DELTAS
    solver: IpoptOptions = IpoptOptions()
    min_final_mass_kg: float = BETA_KG
    library_dir: str = "data/library"
    models_dir: str | None = None
    record: str = "data/best_known/cr3bp.json"
    library_alphas: tuple[float, ...] | None = None

    def summary(self) -> dict:
        """What the study ran, as JSON data (``study.json`` beside its events): α, cells, searches, the budget,
        seed, hop settings, δ and the solver options — what a reader of the events needs to recompute its
        statistics (e.g. ``amorgs design --strategy auto``); ``library_alphas`` where named (a study of every
        library α but its own, as every study before them, records none)."""
        hops = asdict(self.hops)
        if not hops["variables"]:  # every variable hops: the study.json of the studies before hop variables existed
            del hops["variables"]
        return {"alpha": self.alpha, "samplers": list(self.samplers), "strategies": list(self.strategies),
                "searches": self.searches, "budget": self.budget, "seed": self.seed,
                "hops": hops, "deltas": list(self.deltas), "solver": self.solver.to_dict(),
                **({"library_alphas": list(self.library_alphas)} if self.library_alphas is not None else {})}

    def cells(self) -> list[Cell]:
        return [Cell(sampler=s, strategy=t, alpha=self.alpha, searches=self.searches, budget=self.budget,
                     seed=self.seed, hops=self.hops) for t in self.strategies for s in self.samplers]

    def check(self) -> None:
        """One-line ``InputError`` for a bad setting, before any solve."""
        for name in self.samplers:
            try:
                arm = get_arm(name)
            except ValueError as exc:
                raise InputError(f"--samplers: {exc}") from None
            if (arm.learned or arm.transfer) and self.models_dir is None:
                raise InputError(f"--samplers {name}: a learned sampler needs --models-dir")
        for strategy in self.strategies:
            try:
                strategy_settings(strategy, self.hops)
            except ValueError as exc:
                raise InputError(f"--strategies: {exc}") from None
        try:
            self.hops.movable(variable_names())
        except ValueError as exc:
            raise InputError(f"--hop-variables: {exc}") from None
        if self.searches < 1 or self.budget < 1:
            raise InputError("--searches and --budget must be positive")
        if self.library_alphas is not None and alpha_label(self.alpha) in map(alpha_label, self.library_alphas):
            raise InputError(f"--library-alphas: holds the searched α {self.alpha:g} (reuse must not see the answer)")
        if self.library_alphas is not None and not any(get_arm(s).high_quality for s in self.samplers):
            raise InputError(f"--library-alphas: no sampler of {', '.join(self.samplers)} draws on the library")


def library_rows(library_dir: str, alpha: float) -> pd.DataFrame:
    """The library's rows at ``alpha`` (every one, converged or not)."""
    from amorgs.data.library import read_library

    return read_library(library_dir, "cr3bp", alpha_label(alpha))


def training_high_quality(study: GlobalStudy) -> tuple[pd.DataFrame | None, tuple[float, ...] | None]:
    """The library's high-quality rows at the study's ``library_alphas``, or at every library α but the study's
    where it names none, and those α (None, None when no sampler needs them).  ``InputError`` naming the α when a
    named one is not in the library."""
    if not any(get_arm(s).high_quality for s in study.samplers):
        return None, None
    from amorgs.data.library import read_library, read_manifest

    manifest = read_manifest(study.library_dir, "cr3bp")
    if manifest is None:
        raise InputError(f"{study.library_dir}: no solution library (a library-based sampler needs one)")
    held = [float(e["alpha"]) for e in manifest["per_alpha"]]
    if study.library_alphas is not None:
        missing = [a for a in study.library_alphas if alpha_label(a) not in map(alpha_label, held)]
        if missing:
            raise InputError(f"--library-alphas: {', '.join(f'{a:g}' for a in missing)} not in {study.library_dir} "
                             f"(it holds α {', '.join(f'{a:g}' for a in held)})")
        train = tuple(float(a) for a in study.library_alphas)
    else:
        train = tuple(a for a in held if alpha_label(a) != alpha_label(study.alpha))
    if not train:
        raise InputError(f"{study.library_dir}: no library α besides {study.alpha} to reuse")
    frames = [read_library(study.library_dir, "cr3bp", alpha_label(a)) for a in train]
    table = pd.concat(frames, ignore_index=True)
    hq = table[table["converged"] & (table["m_f"] >= study.min_final_mass_kg)].reset_index(drop=True)
    return hq, train


_WORKER: dict = {}


def _init_worker(study: GlobalStudy, high_quality, train_alphas) -> None:
    from amorgs.problems import get_problem

    from amorgs.solvers.basin_hopping import hop_solver_options

    problem = get_problem("cr3bp")
    warm = hop_solver_options("mbh_warm", study.solver)
    _WORKER.update(problem=problem, solver=problem.make_local_solver(study.solver),
                   hop_solver=problem.make_local_solver(warm) if "mbh_warm" in study.strategies else None, samplers={
        name: build_sampler(name, problem, models_dir=study.models_dir, high_quality=high_quality,
                            train_alphas=train_alphas) for name in study.samplers})


def _search_task(task: tuple[Cell, int]) -> tuple[list[dict], list[dict]]:
    cell, r = task
    p = _WORKER["problem"]
    solver, hop_solver = _WORKER["solver"], _WORKER["hop_solver"] if cell.strategy == "mbh_warm" else None
    return run_search(cell, r, _WORKER["samplers"][cell.sampler].sample, solver, p.lower, p.upper,
                      p.variable_names, hop_solver)


def certifiable_starts(events: pd.DataFrame, study: GlobalStudy) -> pd.DataFrame:
    """The events of a study that a certificate can re-solve (:data:`amorgs.reference.STARTS_FILE`'s layout, for
    :func:`amorgs.certification.certify_reference`): those that record their guess (``guess_<name>`` columns) and
    were solved with the study's own solver options (``options_hash`` — a warm hop's options differ), one row each:
    ``sampler``, ``strategy``, ``alpha``, ``seed`` (the search r, whose generator is ``default_rng([study seed, r])``),
    ``start`` (the solve's index in its search), ``kind``, ``status``, ``iterations``, ``m_f`` (kg, −objective),
    ``options_hash``, ``nlp_fingerprint`` and the guess.  Events of older studies (no guesses) are left out."""
    guesses = [c for c in events.columns if c.startswith("guess_")]
    if not guesses or "options_hash" not in events:
        return pd.DataFrame(columns=["sampler", "strategy", "alpha", "seed", "start", "kind", "status", "iterations",
                                     "m_f", "options_hash", "nlp_fingerprint"])
    keep = events[guesses].notna().all(axis=1) & (events["options_hash"] == study.solver.digest())
    rows = events[keep]
    out = pd.DataFrame({"sampler": rows["sampler"], "strategy": rows["strategy"], "alpha": rows["alpha"].astype(float),
                        "seed": rows["search"].astype(int), "start": rows["solve"].astype(int), "kind": rows["kind"],
                        "status": rows["status"], "iterations": rows["iterations"].astype(int),
                        "m_f": -rows["objective"].astype(float), "options_hash": rows["options_hash"],
                        "nlp_fingerprint": rows["nlp_fingerprint"]})
    return pd.concat([out, rows[guesses]], axis=1).reset_index(drop=True)


#: The folder, under a study's destination, that holds each finished search while the study runs (one JSON file
#: per search: its event rows and feasible solutions) — an interrupted study resumes from it, and the command
#: removes it once the tables are written.
CHECKPOINT_DIR = ".searches"
#: The settings that name a study's cells.  A search depends on its cell, its index and the rest of the study's
#: identity alone, so a study run again with other cells — resumed from a checkpoint, or extending a finished
#: study (:func:`finished_searches`) — keeps the searches of the cells the two share.
CELL_KEYS = ("samplers", "strategies")


def inputs_identity(study: GlobalStudy) -> dict:
    """The contents of what the samplers draw on: the SHA-256 of the library's manifest (a library that grew
    between two runs gives other pools) and of every file in the models folder but its Markdown notes (recorded in
    ``study.json`` as ``inputs``: what a study that extends this one must draw on too)."""
    from amorgs.data.library import MANIFEST, sha256_file

    manifest = Path(study.library_dir) / "cr3bp" / MANIFEST
    if study.models_dir and not Path(study.models_dir).is_dir():
        raise InputError(f"--models-dir {study.models_dir}: no such folder")
    models = sorted(p for p in Path(study.models_dir).iterdir() if p.is_file() and p.suffix != ".md") \
        if study.models_dir else []
    return {"library_manifest_sha256": sha256_file(manifest) if manifest.is_file() else None,
            "models_sha256": {p.name: sha256_file(p) for p in models}}


def without_cells(settings: dict) -> dict:
    """A study's settings (``study.json``, :meth:`GlobalStudy.summary`) less :data:`CELL_KEYS` and the ``inputs``
    that ``study.json`` records beside them."""
    return {k: v for k, v in settings.items() if k not in CELL_KEYS and k != "inputs"}


def _identity(study: GlobalStudy) -> dict:
    """What a checkpoint's searches must share with the study that resumes them: every setting of the searches
    but the cells (:meth:`GlobalStudy.summary` less :data:`CELL_KEYS`), β, and :func:`inputs_identity`."""
    return {**without_cells(study.summary()), "min_final_mass_kg": study.min_final_mass_kg,
            "library_dir": study.library_dir, "models_dir": study.models_dir, **inputs_identity(study)}


def finished_searches(dest: str | Path, study: GlobalStudy) -> dict[tuple[str, str, int], tuple[list, list]]:
    """The searches of the finished study in ``dest`` (its ``events.parquet``, ``solutions.parquet`` and
    ``study.json``), keyed (strategy, sampler, search), for ``study`` to keep instead of solving them again: the
    same settings but the cells (``library_alphas`` aside where none of its samplers drew on the library), the
    same :func:`inputs_identity`, and no cell that ``study`` leaves out.  ``InputError`` naming the file or the
    setting otherwise."""
    from amorgs.data.io import read_json

    dest = Path(dest)
    missing = [n for n in ("events.parquet", "solutions.parquet", "study.json") if not (dest / n).is_file()]
    if missing:
        raise InputError(f"--extend {dest}: no {', '.join(missing)} (a finished global-search --dest)")
    held = read_json(dest / "study.json")
    want = json.loads(json.dumps(without_cells(study.summary())))
    drew_on_library = any(get_arm(s).high_quality for s in held.get("samplers", []))
    unread = set() if drew_on_library else {"library_alphas"}
    differ = sorted(k for k in (set(want) | set(without_cells(held))) - unread if held.get(k) != want.get(k))
    if differ:
        raise InputError(f"--extend {dest}: its study.json differs in {', '.join(differ)} (only the cells may change)")
    if held.get("inputs") != json.loads(json.dumps(inputs_identity(study))):
        raise InputError(f"--extend {dest}: its study.json records "
                         + ("no inputs (a study before they were recorded)" if "inputs" not in held else
                            "other inputs") + "; the library manifest and every model file must be the same bytes")
    events = pd.read_parquet(dest / "events.parquet")
    solutions = pd.read_parquet(dest / "solutions.parquet")
    if not len(events):
        return {}
    cells = {(c.strategy, c.sampler) for c in study.cells()}
    dropped = sorted(set(zip(events["strategy"], events["sampler"])) - cells)
    if dropped:
        raise InputError(f"--extend {dest}: holds the cells {', '.join(' × '.join(c) for c in dropped)}, which "
                         "--strategies/--samplers leave out (name them too)")
    keys = ["strategy", "sampler", "search"]
    sols = {k: g.to_dict("records") for k, g in solutions.groupby(keys, sort=False)} if len(solutions) else {}
    return {k: (g.to_dict("records"), sols.get(k, [])) for k, g in events.groupby(keys, sort=False)}


def _search_file(folder: Path, cell: Cell, r: int) -> Path:
    return folder / f"{cell.strategy}--{cell.sampler}--{r:04d}.json"


def clear_checkpoint(folder: str | Path, study: GlobalStudy) -> int:
    """Remove ``study``'s searches from the checkpoint ``folder`` once its tables hold them, and the folder when
    nothing else is left in it; the searches of other cells (a study resumed with fewer cells) stay for a later
    run.  Returns how many stay."""
    import shutil

    folder = Path(folder)
    for cell in study.cells():
        for r in range(cell.searches):
            _search_file(folder, cell, r).unlink(missing_ok=True)
    left = len(list(folder.glob("*--*.json")))
    if not left:
        shutil.rmtree(folder)
    return left


def _open_checkpoint(folder: Path, study: GlobalStudy) -> None:
    """Create ``folder`` for ``study``'s searches, or check that the searches already in it are this study's
    (``InputError`` naming the folder otherwise: a search of other settings must not join these tables)."""
    from amorgs.data.io import atomic_path

    folder.mkdir(parents=True, exist_ok=True)
    marker = folder / "study.json"
    want = json.loads(json.dumps(_identity(study)))
    if marker.is_file():  # a marker written before the cells left the identity still names them: not compared
        if without_cells(json.loads(marker.read_text())) != want:
            raise InputError(f"{folder}: holds the searches of a study with other settings, library or models (its "
                             "study.json); delete it or choose another --dest")
        return
    if any(folder.glob("*--*.json")):
        raise InputError(f"{folder}: holds searches but no study.json saying which study they belong to; delete it "
                         "or choose another --dest")
    with atomic_path(marker) as tmp:
        tmp.write_text(json.dumps(want, indent=1, sort_keys=True) + "\n")


def _save_search(path: Path, result: tuple[list[dict], list[dict]]) -> None:
    from amorgs.data.io import atomic_path

    with atomic_path(path) as tmp:  # JSON keeps every float bit for bit (repr), NaN included
        tmp.write_text(json.dumps({"events": result[0], "solutions": result[1]}, default=_plain))


def _plain(value):
    """A numpy scalar as the Python number or bool it holds (for JSON)."""
    if isinstance(value, np.generic):
        return value.item()
    raise TypeError(f"{type(value).__name__} is not JSON data")


def _load_search(path: Path) -> tuple[list[dict], list[dict]]:
    data = json.loads(path.read_text())
    return data["events"], data["solutions"]


def _progress_line(done: int, total: int, resumed: int, task: tuple[Cell, int], started: float) -> str:
    cell, r = task
    elapsed = time.monotonic() - started
    ran = done - resumed
    left = f", about {elapsed / ran * (total - done) / 60:.0f} min left" if ran and done < total else ""
    return (f"global-search: {done}/{total} searches ({cell.strategy} × {cell.sampler}, search {r} done), "
            f"{elapsed / 60:.1f} min{left}")


def _same_searches(tasks: list[tuple[Cell, int]]) -> dict[int, int]:
    """The searches that need no solve: task index → the index of search 0 of its cell, for every search r > 0 of
    a cell that :func:`~amorgs.ablation.global_search.repeats_search_0`."""
    first = {cell: i for i, (cell, r) in enumerate(tasks) if r == 0}
    return {i: first[cell] for i, (cell, r) in enumerate(tasks) if r and repeats_search_0(cell)}


def run_study(study: GlobalStudy, workers: int = 1, checkpoint: str | Path | None = None,
              report: Callable[[str], None] | None = None,
              finished: dict[tuple[str, str, int], tuple[list, list]] | None = None) -> dict[str, pd.DataFrame]:
    """Run every search of every cell on ``workers`` spawned processes (each builds its own solver and samplers;
    results do not depend on the number of workers) and compute the study's tables: ``events``, ``solutions``,
    ``runtime_to_target``, ``runtime_ecdf``, ``ert_ratios``, ``ert_pairs``
    (:func:`~amorgs.ablation.global_search.paired_ratios`), ``distinct`` and ``best_known`` (one row: objective,
    m_f, source).  With ``checkpoint`` (a folder), each finished search is saved there at once and searches
    already saved by an interrupted run of the same study are not solved again (the same tables as an
    uninterrupted run: every search is seeded on its own).  A multi-start from a sampler that ignores the seed
    (the selector's one ranking) is solved once, its search 0 copied to the others (:func:`_same_searches`: the
    same tables as solving each).  ``finished`` (:func:`finished_searches`) holds searches of a finished study of
    the same settings, kept as they are (the same tables as solving them again).  ``report`` receives a line per
    finished search (default: standard error)."""
    study.check()
    hq, train = training_high_quality(study)  # a library α it lacks is refused before the checkpoint is made
    say = report or (lambda line: print(line, file=sys.stderr, flush=True))
    for key in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):  # before the workers import numpy
        os.environ.setdefault(key, "1")
    tasks = [(cell, r) for cell in study.cells() for r in range(cell.searches)]
    copies = _same_searches(tasks)
    folder = Path(checkpoint) if checkpoint is not None else None
    results: dict[int, tuple[list[dict], list[dict]]] = {}
    total = len(tasks) - len(copies)
    if folder is not None:  # first: a search saved here is newer than the finished study's tables
        _open_checkpoint(folder, study)
        results = {i: _load_search(_search_file(folder, *t)) for i, t in enumerate(tasks)
                   if i not in copies and _search_file(folder, *t).is_file()}
        if results:
            say(f"global-search: {len(results)} of {total} searches resumed from {folder}")
    if finished:
        kept = {i: finished[(cell.strategy, cell.sampler, r)] for i, (cell, r) in enumerate(tasks)
                if i not in copies and i not in results and (cell.strategy, cell.sampler, r) in finished}
        say(f"global-search: {len(kept)} of {total} searches kept from the finished study")
        results.update(kept)
    pending = [i for i in range(len(tasks)) if i not in results and i not in copies]
    started, resumed = time.monotonic(), len(results)

    def done(i: int, result: tuple[list[dict], list[dict]]) -> None:
        if folder is not None:
            _save_search(_search_file(folder, *tasks[i]), result)
        results[i] = result
        say(_progress_line(len(results), total, resumed, tasks[i], started))

    for cell in dict.fromkeys(tasks[i][0] for i in copies):
        say(f"global-search: {cell.strategy} × {cell.sampler} starts every search from the same guesses (the "
            f"sampler does not use the seed): search 0 is solved once and stands for all {cell.searches}")
    if workers <= 1 and pending:
        _init_worker(study, hq, train)
        for i in pending:
            done(i, _search_task(tasks[i]))
    elif pending:
        with ProcessPoolExecutor(workers, mp_context=get_context("spawn"), initializer=_init_worker,
                                 initargs=(study, hq, train)) as pool:
            futures = {pool.submit(_search_task, tasks[i]): i for i in pending}
            try:
                for future in as_completed(futures):
                    done(futures[future], future.result())
            except BaseException:  # a search raised (or Ctrl-C): keep what finished, start nothing more
                pool.shutdown(wait=False, cancel_futures=True)
                for future, i in futures.items():
                    if i not in results and future.done() and not future.cancelled() and future.exception() is None:
                        done(i, future.result())
                raise
    for i, j in copies.items():
        results[i] = as_search(results[j], tasks[i][1])
    ordered = [results[i] for i in range(len(tasks))]
    events = pd.DataFrame([e for ev, _ in ordered for e in ev])
    solutions = pd.DataFrame([s for _, so in ordered for s in so])
    return summarize(study, events, solutions)


def summarize(study: GlobalStudy, events: pd.DataFrame, solutions: pd.DataFrame) -> dict[str, pd.DataFrame]:
    """The study's tables from its events and solutions, timed against the best known objective at its α: the
    best-known record's (:mod:`amorgs.data.best_known`, ``record``), the library's verified rows' or the study's
    own, whichever is lowest; hits beyond the budget do not count."""
    from amorgs.data import best_known as bk

    library = library_rows(study.library_dir, study.alpha)
    verified = library[library["converged"]] if len(library) else library
    found = solutions["objective"] if len(solutions) else []
    lib_best = best_known(-verified["m_f"]) if len(verified) else np.nan
    record_best = -bk.best_m_f_lifted(bk.read_record(study.record), study.alpha)
    best = best_known([lib_best], [record_best], found)
    source = "library" if best == lib_best else "best-known record" if best == record_best else "this study"
    tables = {
        "events": events,
        "solutions": solutions,
        "runtime_to_target": runtime_to_target(events, best, study.deltas, seed=study.seed, budget=study.budget),
        "runtime_ecdf": runtime_ecdf(events, best, study.deltas, budget=study.budget),
        "ert_ratios": ert_ratios(events, best, study.deltas, seed=study.seed, budget=study.budget),
        "ert_pairs": paired_ratios(events, best, study.deltas, seed=study.seed, budget=study.budget),
        "distinct": distinct_near_best(solutions, best, study.deltas) if len(solutions) else pd.DataFrame(),
        "best_known": pd.DataFrame([{"alpha": study.alpha, "objective": best, "m_f": -best, "source": source,
                                     "library_rows": len(library), "library_best_m_f": -lib_best}]),
    }
    return tables


def compare(table: pd.DataFrame, by: Sequence[str] = ("strategy", "sampler")) -> pd.DataFrame:
    """The runtime-to-target table pivoted for reading: one row per δ, a column per (strategy, sampler) with
    "ERT (lo–hi), successes/searches"."""
    def cell(row) -> str:
        if not np.isfinite(row["ert"]):
            return f"— (0/{row['searches']})"
        hi = "∞" if not np.isfinite(row["ert_hi"]) else f"{row['ert_hi']:.0f}"
        return f"{row['ert']:.0f} ({row['ert_lo']:.0f}–{hi}), {row['successes']}/{row['searches']}"

    out = table.assign(name=table[list(by)].astype(str).agg(" × ".join, axis=1), text=table.apply(cell, axis=1))
    return out.pivot(index="delta", columns="name", values="text")
