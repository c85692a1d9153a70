"""The best known trajectory per α (issue 41 §1): the target every global search is timed against.

One JSON file per problem (:data:`DEFAULT_PATH` for the CR3BP), keyed by α label::

    {"format": 1, "problem": "cr3bp",
     "alphas": {"0.300": {"alpha": 0.3, "m_f_kg": 439.38…, "x": [64 numbers, the stored decision vector],
                          "verify_defect": 7.1e-07, "source": {"kind": "search" | "library" | "lift", "where": …,
                          "commit": …}, "recorded": "2026-12-05T…"}}}

An entry changes only to a higher m_f, and only after the solution passes the project's independent check
here (inside the box, DOP853 re-propagation of the match point within the solver's ``verify_tol``): a row's own
``converged`` flag is not trusted.  Fed by :func:`from_library` (each α's best verified library row) and by
:func:`add_solutions` (a search's solutions table: ``amorgs global-search``'s, ``amorgs design``'s), and kept
non-decreasing in α by :func:`lift` (a trajectory stays feasible when the maximum thrust grows), all behind
``amorgs best-known``.
"""

from __future__ import annotations

import datetime as _dt
import math
from pathlib import Path

import numpy as np
import pandas as pd

from amorgs.alphas import alpha_label
from amorgs.data.io import read_json, write_json
from amorgs.errors import InputError

DEFAULT_PATH = "data/best_known/cr3bp.json"
PROBLEM = "cr3bp"


def read_record(path: str | Path = DEFAULT_PATH) -> dict:
    """The record (an empty one if the file does not exist yet); ``InputError`` naming a file that is not one."""
    p = Path(path)
    if not p.is_file():
        return {"format": 1, "problem": PROBLEM, "alphas": {}}
    try:
        record = read_json(p)
    except ValueError as exc:
        raise InputError(f"{p}: not a best-known record ({exc})") from None
    if not isinstance(record, dict) or record.get("problem") != PROBLEM or "alphas" not in record:
        raise InputError(f"{p}: not a best-known record of {PROBLEM}")
    return record


def best_m_f(record: dict, alpha: float) -> float:
    """The recorded best m_f (kg) at ``alpha``; NaN where none is recorded."""
    entry = record["alphas"].get(alpha_label(alpha))
    return float(entry["m_f_kg"]) if entry else math.nan


def verify(x: np.ndarray, alpha: float, verify_tol: float = 1e-5) -> float:
    """The independent match defect of the stored vector ``x`` at ``alpha`` (DU, VU, t); ``InputError`` if it
    lies outside the box or does not close within ``verify_tol``."""
    from amorgs.problems import get_problem
    from amorgs.problems.cr3bp.propagation import independent_defect

    problem = get_problem(PROBLEM)
    if not (np.all(x >= problem.lower) and np.all(x <= problem.upper)):
        raise InputError(f"α = {alpha:g}: the solution lies outside the decision box")
    defect = independent_defect(x, alpha, problem.initial_state, problem.terminal_state)
    if not defect <= verify_tol:
        raise InputError(f"α = {alpha:g}: the solution does not close (independent defect {defect:.3g} > {verify_tol:g})")
    return float(defect)


def offer(record: dict, alpha: float, x: np.ndarray, source: dict, verify_tol: float = 1e-5) -> bool:
    """Enter ``x`` (stored layout, m_f = x[3] kg) as the best known at ``alpha`` if it beats the entry there and
    passes :func:`verify`; returns whether it did.  ``record`` is changed in place."""
    x = np.asarray(x, float)
    m_f, current = float(x[3]), best_m_f(record, alpha)
    if math.isnan(m_f) or (not math.isnan(current) and m_f <= current):
        return False
    defect = verify(x, alpha, verify_tol)
    record["alphas"][alpha_label(alpha)] = {
        "alpha": float(alpha), "m_f_kg": m_f, "x": x.tolist(), "verify_defect": defect, "source": source,
        "recorded": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds")}
    return True


def _best_rows(table: pd.DataFrame, names: tuple[str, ...], candidates: int = 5) -> list[tuple[float, np.ndarray]]:
    """Per α of ``table``: its ``candidates`` highest-m_f rows flagged converged, best first (a row that fails the
    independent check gives way to the next)."""
    out = []
    rows = table[table["converged"].astype(bool)] if "converged" in table else table
    for alpha, here in rows.groupby("alpha"):
        top = here.sort_values("m_f", ascending=False).head(candidates)
        out += [(float(alpha), r) for r in top[list(names)].to_numpy(float)]
    return out


def add_solutions(record: dict, table: pd.DataFrame, source: dict, verify_tol: float = 1e-5) -> list[str]:
    """Offer every α's best rows of a solutions table (columns ``alpha``, ``m_f``, the stored vector's names,
    ``converged`` if present); returns the α labels whose entry improved."""
    from amorgs.problems import get_problem

    names = get_problem(PROBLEM).variable_names
    missing = [c for c in ("alpha", *names) if c not in table]
    if missing:
        raise InputError(f"{source.get('where', 'table')}: not a solutions table (no column {missing[0]!r})")
    improved = []
    for alpha, x in _best_rows(table, names):
        if x[3] <= best_m_f(record, alpha):
            continue
        try:
            if offer(record, alpha, x, source, verify_tol):
                improved.append(alpha_label(alpha))
        except InputError:
            continue  # flagged converged but fails the independent check here: not a best known
    return sorted(set(improved))


def from_library(record: dict, library_dir: str | Path, source_commit: str = "") -> list[str]:
    """Offer each library α's best verified rows (:func:`add_solutions`); returns the improved α labels."""
    from amorgs.data.library import read_library, read_manifest

    manifest = read_manifest(library_dir, PROBLEM)
    if manifest is None:
        raise InputError(f"{Path(library_dir) / PROBLEM}: no solution library")
    improved = []
    for entry in manifest["per_alpha"]:
        rows = read_library(library_dir, PROBLEM, alpha_label(entry["alpha"]))
        improved += add_solutions(record, rows, {"kind": "library", "where": str(Path(library_dir) / PROBLEM),
                                                 "commit": source_commit})
    return sorted(set(improved))


def lift(record: dict, alphas=None, verify_tol: float = 1e-5) -> list[str]:
    """Carry entries across α (changed in place): a trajectory flown at maximum thrust α_s with throttles ρ is
    flown unchanged at α_t with ρ' = ρ α_s / α_t wherever every ρ' ≤ 1
    (:func:`~amorgs.problems.cr3bp.controls.rescale_throttle`) — at every α_t ≥ α_s, and below α_s down to
    α_s max ρ.  So the best known m_f cannot fall as α grows, and an entry below a lower α's is beaten by that
    entry's trajectory.  Each entry, best first, is offered at every α of ``alphas`` (default: the record's own)
    where it beats the entry there, through :func:`offer` (the independent check at α_t); source ``{"kind":
    "lift", "from_alpha": α_s, "where": and "commit": the lifted entry's}``.  Returns the improved α labels."""
    from amorgs.problems.cr3bp.controls import rescale_throttle

    targets = sorted({float(a) for a in (alphas if alphas is not None else
                                         [e["alpha"] for e in record["alphas"].values()])})
    sources = sorted(record["alphas"].values(), key=lambda e: -float(e["m_f_kg"]))
    improved = []
    for entry in [dict(e) for e in sources]:
        alpha_from = float(entry["alpha"])
        for alpha_to in targets:
            if alpha_to == alpha_from:
                continue
            current = best_m_f(record, alpha_to)
            if not math.isnan(current) and float(entry["m_f_kg"]) <= current:
                continue
            y = rescale_throttle(np.asarray(entry["x"], float), alpha_from, alpha_to)
            if y is None:
                continue
            source = {"kind": "lift", "from_alpha": entry["source"].get("from_alpha", alpha_from),
                      "where": entry["source"].get("where", ""),
                      "commit": entry["source"].get("commit", "")}
            try:
                if offer(record, alpha_to, y, source, verify_tol):
                    improved.append(alpha_label(alpha_to))
            except InputError:
                continue  # does not close at α_t within the tolerance here: not entered
    return sorted(set(improved))


def best_entry_lifted(record: dict, alpha: float, verify_tol: float = 1e-5) -> dict | None:
    """The best known trajectory at ``alpha``, also where the record has no entry there: its entry, or any entry's
    trajectory carried to ``alpha`` by :func:`lift` (verified at ``alpha``) where that is higher — a record entry
    (``alpha``, ``m_f_kg``, ``x`` in the stored layout at ``alpha``, ``verify_defect``, ``source``); ``None``
    where neither.  ``record`` is not changed."""
    here = {"format": record.get("format", 1), "problem": record.get("problem", PROBLEM),
            "alphas": dict(record["alphas"])}
    lift(here, alphas=[alpha], verify_tol=verify_tol)
    return here["alphas"].get(alpha_label(alpha))


def best_m_f_lifted(record: dict, alpha: float, verify_tol: float = 1e-5) -> float:
    """The m_f (kg) of :func:`best_entry_lifted` at ``alpha``; NaN where there is none."""
    entry = best_entry_lifted(record, alpha, verify_tol)
    return float(entry["m_f_kg"]) if entry else math.nan


def source_where(path: str | Path, root: str | Path) -> str:
    """How the record names a solutions table: relative to ``root`` (the checkout) where it lies inside it, so that
    the entry names a file a reader of the repository can open; else its absolute path."""
    resolved = Path(path).resolve()
    try:
        return resolved.relative_to(Path(root).resolve()).as_posix()
    except ValueError:
        return str(resolved)


def save_record(record: dict, path: str | Path = DEFAULT_PATH) -> None:
    """Write the record atomically."""
    write_json(record, path)
