"""The versioned solution library: solves kept in the repository so that work accumulates across runs.

Layout (committed)::

    data/library/{problem}/alpha={label}/shards-{first:05d}-{last:05d}.parquet   one file per α per export
    data/library/{problem}/provenance.json                                        the manifest (format 2)

Every file consolidates the generate shards of one α that one export found (a ``shard`` column keeps
them apart); its manifest entry records the shard indices, row count, converged count, SHA-256, size,
solver-option hashes, generation, CPU-hours, export time and git commit.  :func:`compact_library`
(``amorgs library-compact``) merges them into one file per (α, generation), the same rows in fewer bytes.

*Generations* (:data:`GENERATIONS`): when the solver that fills the library changes in substance (issue 22:
interpolated coasts, then Cartesian controls at low thrust), a new generation starts beside the old one.
Every file entry names its generation (entries without one are generation 1), and the manifest's
``generations`` says what each is, its solver-option hashes and its totals.  Every generation stays verified and readable; a row's
``options_hash`` says exactly which options produced it.  Shard indices are shared across generations (a
batch index is never reused), so the seeds never collide.

*Compact storage* (files exported since generation 2, manifest ``"guesses": "seeded"``): the 64 ``guess_*``
columns are not stored — each row's guess is row ``start`` of the problem's uniform draw from
``default_rng(seed)``, exactly as the generate rule drew it; export checks that bit for bit and reading
restores the columns, so readers see the same table either way.  The manifest is the source of truth: a
library read (:func:`read_library_file`) refuses a file that is not listed, whose hash or row count
differs, or that is not a readable Parquet table — always naming the file; :func:`verify_library` checks the
whole library (and refuses unlisted files) before a workflow's first job.

Only the library config (``config/library.yaml``: its own base seed, generate/merge only) feeds the library:
:func:`export_library` checks every shard against it (seed derived from (seed, problem, α, shard), one
row per configured start, the config's solver-option hash) and refuses anything else, naming the file.  A
library belongs to one config identity (seed, starts per shard, solver options: :func:`library_identity`,
recorded in the manifest): export refuses any other config, whatever its file name — another config's shards
need another library directory.  Shards are immutable (same α and index ⇒ same seed ⇒ same rows), so an
export adds only indices not yet listed; a listed index whose shard holds other solves is refused, naming it.
Solutions are stored inside the problem's box: values outside it by at most :data:`CLIP_TOLERANCE` (the
NLP's own bound tolerance) are clipped on export; anything farther is refused.

A workflow run whose config enables the library merges these files with its own fresh shards; the merged
table's ``source`` column says ``library`` or ``fresh``.  ``library.max_rows_per_alpha`` takes a fixed
slice (the first rows in (shard, start) order) so that small configs stay small as the library grows.
"""

from __future__ import annotations

import datetime as _dt
import hashlib
import json
import math
import subprocess
from pathlib import Path

import numpy as np
import pandas as pd

from amorgs.data.io import write_json, write_parquet
from amorgs.data.seeds import shard_seed
from amorgs.data.tables import TIMING_COLUMNS, merge_shards, validate_solutions
from amorgs.errors import InputError
from amorgs.problems import get_problem

SOURCE_LIBRARY = "library"
SOURCE_FRESH = "fresh"
FORMAT = 2
MANIFEST = "provenance.json"
#: Largest distance (in the variable's own units) outside the box that export clips instead of refusing.
CLIP_TOLERANCE = 1e-6
#: Manifest value of a file without ``guess_*`` columns (see the module docstring, compact storage).
GUESSES_SEEDED = "seeded"
#: The row column of the NLP's numerical fingerprint (:mod:`amorgs.solvers.fingerprint`); "" where unknown.
FINGERPRINT = "nlp_fingerprint"


# ------------------------------------------------------------------------------------------- reading


def sha256_file(path: str | Path) -> str:
    """Hex SHA-256 of a file's bytes."""
    digest = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def read_table(path: str | Path) -> pd.DataFrame:
    """Read one Parquet table; an unreadable (truncated, corrupt, missing) file raises :class:`InputError`
    naming it, instead of an Arrow traceback."""
    try:
        return pd.read_parquet(path)
    except Exception as exc:  # pyarrow raises several unrelated types for damaged files
        reason = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise InputError(f"{path}: not a readable Parquet table ({reason})") from None


def read_manifest(library_dir: str | Path, problem: str) -> dict | None:
    """The library manifest of ``problem`` (``provenance.json``), or None if the problem has no library."""
    path = Path(library_dir) / problem / MANIFEST
    if not path.is_file():
        return None
    try:
        manifest = json.loads(path.read_text())
    except (OSError, ValueError) as exc:
        raise InputError(f"{path}: not a readable library manifest ({exc})") from None
    if manifest.get("format") != FORMAT:
        raise InputError(f"{path}: library manifest format {manifest.get('format')!r}, expected {FORMAT}")
    return manifest


def library_files(library_dir: str | Path, problem: str, alpha_label: str, manifest: dict | None = None) -> list[Path]:
    """The files of one (problem, α label) as listed in the manifest (read here unless given), in order; empty
    without a library."""
    manifest = manifest or read_manifest(library_dir, problem)
    if manifest is None:
        return []
    root = Path(library_dir) / problem
    return [root / e["file"] for e in manifest["files"] if e["file"].startswith(f"alpha={alpha_label}/")]


def _entry_of(path: Path, manifest: dict, root: Path) -> dict:
    try:
        rel = path.resolve().relative_to(root.resolve()).as_posix()
    except ValueError:
        raise InputError(f"{path}: not inside the library {root}") from None
    for entry in manifest["files"]:
        if entry["file"] == rel:
            return entry
    raise InputError(f"{path}: not listed in {root / MANIFEST} (a library file must be added by `amorgs library-export`)")


def read_library_file(path: str | Path, library_dir: str | Path, problem: str, manifest: dict | None = None) -> pd.DataFrame:
    """Read one library file after checking it against the manifest (read here unless given: a caller reading
    many files reads it once): listed, same SHA-256, same row count."""
    path = Path(path)
    root = Path(library_dir) / problem
    manifest = manifest or read_manifest(library_dir, problem)
    if manifest is None:
        raise InputError(f"{path}: the library {root} has no {MANIFEST}")
    entry = _entry_of(path, manifest, root)
    if not path.is_file():
        raise InputError(f"{path}: listed in {root / MANIFEST} but missing")
    digest = sha256_file(path)
    if digest != entry["sha256"]:
        raise InputError(
            f"{path}: SHA-256 {digest[:12]}… differs from the manifest's {entry['sha256'][:12]}… "
            "(the file was modified after export; restore it with git)"
        )
    df = read_table(path)
    if len(df) != entry["rows"]:
        raise InputError(f"{path}: {len(df)} rows, the manifest lists {entry['rows']}")
    if FINGERPRINT not in df:  # exported before rows carried it: unknown (the entry's ``codes`` says which commits)
        df = df.assign(**{FINGERPRINT: ""})
    return restore_seeded_guesses(df, problem) if entry.get("guesses") == GUESSES_SEEDED else df


def seeded_guesses(df: pd.DataFrame, problem: str) -> np.ndarray:
    """The initial guesses of ``df``'s rows as the generate rule drew them: row ``start`` of
    ``sample_uniform(α, ·, default_rng(seed))`` (a draw's row k does not depend on how many rows follow it)."""
    prob = get_problem(problem)
    out = np.empty((len(df), len(prob.variable_names)))
    starts = df["start"].to_numpy(dtype=int)
    for (seed, alpha), idx in df.groupby(["seed", "alpha"], sort=False).indices.items():
        draw = prob.sample_uniform(float(alpha), int(starts[idx].max()) + 1, np.random.default_rng(int(seed)))
        out[idx] = draw[starts[idx]]
    return out


def _guess_columns(problem: str) -> list[str]:
    return [f"guess_{v}" for v in get_problem(problem).variable_names]


def drop_seeded_guesses(df: pd.DataFrame, problem: str, where: str) -> pd.DataFrame:
    """``df`` without its ``guess_*`` columns, after checking bit for bit that :func:`seeded_guesses`
    reproduces them (``InputError`` naming ``where`` otherwise)."""
    cols = _guess_columns(problem)
    if not np.array_equal(df[cols].to_numpy(dtype=float), seeded_guesses(df, problem)):
        raise InputError(f"{where}: the initial guesses are not the seeded uniform draw of their (seed, start); "
                         "only the generate rule's shards can be stored compactly")
    return df.drop(columns=cols)


def restore_seeded_guesses(df: pd.DataFrame, problem: str) -> pd.DataFrame:
    """A compactly stored table with its ``guess_*`` columns back in table order (right after ``start``)."""
    cols = _guess_columns(problem)
    guesses = pd.DataFrame(seeded_guesses(df, problem), columns=cols, index=df.index)
    at = list(df.columns).index("start") + 1
    return pd.concat([df.iloc[:, :at], guesses, df.iloc[:, at:]], axis=1)


def verify_library(library_dir: str | Path, problem: str) -> dict | None:
    """Check a whole library against its manifest before any job reads it: every listed file present with
    its size and SHA-256, and no file under ``library_dir/problem`` that the manifest does not list.  Raises
    :class:`InputError` naming the first offending file; returns the manifest (None if there is no library:
    nothing to check)."""
    root = Path(library_dir) / problem
    manifest = read_manifest(library_dir, problem)
    if manifest is None:
        if root.is_dir() and any(p.is_file() for p in root.rglob("*")):
            raise InputError(f"{root}: library files but no {MANIFEST}")
        return None
    listed = {e["file"]: e for e in manifest["files"]}
    for path in sorted(p for p in root.rglob("*") if p.is_file()):
        rel = path.relative_to(root).as_posix()
        if rel != MANIFEST and rel not in listed:
            raise InputError(f"{path}: not listed in {root / MANIFEST} (a library file must be added by "
                             "`amorgs library-export`; remove it or restore the library with git)")
    for rel, entry in listed.items():
        path = root / rel
        if not path.is_file():
            raise InputError(f"{path}: listed in {root / MANIFEST} but missing")
        if path.stat().st_size != entry["bytes"] or sha256_file(path) != entry["sha256"]:
            raise InputError(f"{path}: differs from {root / MANIFEST} (size or SHA-256; the file was modified "
                             "after export; restore it with git)")
    return manifest


def read_library(library_dir: str | Path, problem: str, alpha_label: str, max_rows: int | None = None) -> pd.DataFrame:
    """Every verified library row of one (problem, α label) in (shard, start) order, optionally only the first
    ``max_rows`` of them (a fixed slice); an empty table if there are none."""
    manifest = read_manifest(library_dir, problem)
    files = library_files(library_dir, problem, alpha_label, manifest)
    if not files:
        return pd.DataFrame()
    df = merge_shards(read_library_file(p, library_dir, problem, manifest) for p in files)
    return df.head(max_rows).reset_index(drop=True) if max_rows is not None else df


def tag_source(df: pd.DataFrame, source: str) -> pd.DataFrame:
    """Add (or overwrite) the ``source`` column."""
    return df.assign(source=source)


# ------------------------------------------------------------------------------------------- export


def git_commit() -> str:
    """The checkout's commit (``git rev-parse HEAD``), or ``unknown`` outside a git checkout."""
    try:
        return subprocess.run(["git", "rev-parse", "HEAD"], capture_output=True, text=True, check=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return "unknown"


def check_library_shard(df: pd.DataFrame, path: str | Path, problem: str, base_seed: int, starts: int,
                        alpha_values: dict[str, float], options_hash: str | None = None) -> None:
    """Refuse (``InputError`` naming the file) a shard that the library config did not produce: wrong
    problem or α, a seed other than ``shard_seed(base_seed, problem, α, shard)``, a row count other than
    ``starts``, mixed solver-option hashes, or (``options_hash`` given) a hash other than the config's."""
    where = str(path)
    if len(df) == 0:
        raise InputError(f"{where}: empty shard")
    try:
        validate_solutions(df, where=where)
    except ValueError as exc:
        raise InputError(str(exc)) from None
    label = Path(path).parent.name.removeprefix("alpha=")
    if label not in alpha_values:
        raise InputError(f"{where}: α label {label} is not an α of the library config")
    alpha = alpha_values[label]
    if set(df["problem"]) != {problem} or not np.allclose(df["alpha"], alpha, rtol=0, atol=1e-12):
        raise InputError(f"{where}: rows are not {problem} at α = {alpha!r}")
    shards = set(df["shard"].astype(int))
    if len(shards) != 1:
        raise InputError(f"{where}: rows from several shards {sorted(shards)}")
    shard = shards.pop()
    expected = shard_seed(base_seed, problem, alpha, shard)
    seeds = set(df["seed"].astype(int))
    if seeds != {expected}:
        raise InputError(
            f"{where}: seed {sorted(seeds)} is not the library config's seed {expected} for shard {shard} at "
            f"α = {alpha!r}: this shard was produced by another config and cannot enter the library"
        )
    if len(df) != starts:
        raise InputError(f"{where}: {len(df)} rows, the library config makes {starts} per shard")
    if df["options_hash"].nunique() != 1:
        raise InputError(f"{where}: mixed solver-option hashes {sorted(df['options_hash'].unique())}")
    if FINGERPRINT in df and len(set(df[FINGERPRINT]) - {""}) > 1:
        raise InputError(f"{where}: rows of several codes (NLP fingerprints {sorted(set(df[FINGERPRINT]) - {''})})")
    if options_hash is not None and df["options_hash"].iloc[0] != options_hash:
        raise InputError(f"{where}: solver-option hash {df['options_hash'].iloc[0]}, the library config's is "
                         f"{options_hash}: this shard was solved with other options and cannot enter the library")


def clip_to_bounds(df: pd.DataFrame, names, lower, upper, where: str, tol: float = CLIP_TOLERANCE) -> pd.DataFrame:
    """Clip the solution columns ``names`` into [lower, upper]; a value farther out than ``tol`` raises
    ``InputError`` naming the file, column and distance.  NaN (no solution) stays NaN."""
    out = df.copy()
    for name, lo, hi in zip(names, lower, upper):
        col = out[name].to_numpy(dtype=float)
        excess = np.nanmax(np.maximum(lo - col, col - hi), initial=-np.inf) if np.isfinite(col).any() else -np.inf
        if excess > tol:
            raise InputError(f"{where}: column {name!r} lies {excess:.3g} outside its bounds [{lo}, {hi}]")
        out[name] = np.where(np.isnan(col), col, np.clip(col, lo, hi))
    return out


def _per_alpha(entries: list[dict]) -> list[dict]:
    table = pd.DataFrame(entries)
    rows = []
    for alpha, g in table.groupby("alpha"):
        best = [e for e in g["best_objective"] if e is not None and e == e]
        rows.append({"alpha": float(alpha), "files": int(len(g)), "shards": int(g["shards"].map(len).sum()),
                     "rows": int(g["rows"].sum()), "converged": int(g["converged"].sum()),
                     "best_objective": float(min(best)) if best else None})
    return rows


#: The library's generations: what changed in the solver that fills it (see the module docstring).
GENERATIONS = {
    1: "RK8 coasts, integrated at every evaluation (every solve before issue 22)",
    2: "coasts read off the interpolated ballistic flow (issue 22)",
    3: "Cartesian controls (a direction with ‖v‖ ≤ 1 and the throttle) at low thrust, interpolated coasts (issue 22)",
}


def solver_generation(solver) -> int:
    """The generation a solver's rows belong to: 3 with Cartesian controls, 2 with interpolated coasts, else 1."""
    transcription = getattr(solver, "transcription", None)
    if getattr(transcription, "controls", None) == "cartesian":
        return 3
    return 2 if getattr(transcription, "coast", None) == "interpolant" else 1


def _generations(files: list[dict], codes: dict | None = None) -> list[dict]:
    """The manifest's ``generations``: what each is, its solver-option hashes, its code (the NLP fingerprint per
    α, for the generations whose rows carry one: ``codes``, the manifest's ``generation_codes``) and its totals."""
    codes = codes or {}
    out = []
    for number in sorted({e.get("generation", 1) for e in files}):
        mine = [e for e in files if e.get("generation", 1) == number]
        code = codes.get(str(number), {})
        out.append({"generation": number, "what": GENERATIONS.get(number) or code.get("what", ""),
                    "options_hashes": sorted({h for e in mine for h in e["options_hashes"]}),
                    **({"nlp_fingerprints": code["nlp_fingerprints"]} if code else
                       {"nlp_fingerprints": "not recorded (rows made before issue 37; each file's sources name their "
                                            "commits)"}),
                    "files": len(mine), "rows": sum(e["rows"] for e in mine),
                    "converged": sum(e["converged"] for e in mine),
                    "cpu_hours": sum(e["cpu_hours"] for e in mine)})
    return out


def assign_generation(manifest: dict, base: int, options_hash: str, alpha_key: str, fingerprint: str,
                      commit: str) -> int:
    """The generation that new rows of one α join, so that a generation never mixes codes.

    Rows without a fingerprint (made before issue 37) join ``base`` (:func:`solver_generation`), as before.  Rows
    with one join the *fingerprinted* generation (``manifest["generation_codes"]``) of the same solver options
    that holds their fingerprint at this α, else the latest one that has no rows at this α yet (a code is known
    by its fingerprints at the α it solved: a batch at new α joins the newest code); else they start a new
    generation, recorded with their options hash, fingerprint and commit.  Updates ``generation_codes``."""
    if not fingerprint:
        return base
    codes = manifest.setdefault("generation_codes", {})
    mine = [n for n in sorted(codes, key=int, reverse=True) if codes[n]["options_hash"] == options_hash]
    same = [n for n in mine if codes[n]["nlp_fingerprints"].get(alpha_key) == fingerprint]
    free = [n for n in mine if alpha_key not in codes[n]["nlp_fingerprints"]]
    for number in same[:1] or free[:1]:  # the generation of this code at this α, else the latest without this α
        codes[number]["nlp_fingerprints"][alpha_key] = fingerprint
        return int(number)
    number = max([base, *GENERATIONS, *(e.get("generation", 1) for e in manifest["files"]), *map(int, codes)]) + 1
    codes[str(number)] = {"what": f"generation {base}'s solver, one code per generation (NLP fingerprints, issue 37); "
                                  f"first rows from commit {commit[:12]}",
                          "options_hash": options_hash, "based_on": base, "first_commit": commit,
                          "nlp_fingerprints": {alpha_key: fingerprint}}
    return number


def library_identity(cfg, problem: str) -> dict:
    """What fixes the rows of a library shard besides its α and index: the base seed, the starts per shard and
    the solver-option hash of ``cfg`` (a typed config) for ``problem``.  Two configs with the same identity
    make identical shards; a library holds the shards of one identity only."""
    section = getattr(cfg.problems, problem)
    return {"seed": int(cfg.seed), "starts_per_shard": int(section.generate.starts_per_shard),
            "options_hash": section.solver.digest()}


def manifest_identity(manifest: dict) -> dict:
    """The identity (:func:`library_identity`) a manifest records; a manifest written before the identity had
    its own key gives the solver-option hash of its latest export."""
    if "identity" in manifest:
        return manifest["identity"]
    latest = max(manifest["files"], key=lambda e: (e["exported"], e["file"]))
    return {"seed": manifest["seed"], "starts_per_shard": manifest["starts_per_shard"],
            "options_hash": latest["options_hashes"][-1]}


def _generation_of(manifest: dict, options_hash: str) -> int:
    """The generation of the files whose rows carry ``options_hash`` (1 when none says otherwise)."""
    return max((e.get("generation", 1) for e in manifest["files"] if options_hash in e["options_hashes"]), default=1)


def _check_same_library(manifest: dict, identity: dict, solver, config_file: str | Path, root: Path) -> None:
    """Refuse a config whose shards would differ from the library's (``InputError`` naming both).  A solver of
    a later generation (:func:`solver_generation`) than the library's current one starts that generation:
    its options hash becomes the library's."""
    held = manifest_identity(manifest)
    new_generation = solver_generation(solver) > _generation_of(manifest, held["options_hash"])
    diff = [f"{k} {identity[k]!r} (the library's: {held[k]!r})" for k in ("seed", "starts_per_shard", "options_hash")
            if identity[k] != held[k] and not (k == "options_hash" and new_generation)]
    if diff:
        raise InputError(
            f"{config_file}: not the config of the library {root} (recorded in {root / MANIFEST}: "
            f"{manifest.get('config_file')}): {', '.join(diff)}; a different library needs its own --library-dir"
        )


def check_library_config(manifest: dict, cfg, config_file: str | Path, root: Path, problem: str) -> None:
    """Refuse (``InputError`` naming both) a config that may not grow the library of ``manifest``: another
    identity (:func:`_check_same_library`), or another file than the one the manifest records, even of the same
    identity (the manifest's config record changes only through that file)."""
    _check_same_library(manifest, library_identity(cfg, problem), getattr(cfg.problems, problem).solver,
                        config_file, root)
    recorded = manifest.get("config_file")
    given = Path(config_file).resolve().as_posix()
    if recorded and Path(recorded).as_posix() != Path(config_file).as_posix() and given != Path(recorded).resolve().as_posix() \
            and not (not Path(recorded).is_absolute() and given.endswith("/" + Path(recorded).as_posix())):
        raise InputError(f"{config_file}: the library {root} is grown from {recorded} only (its manifest "
                         "records that file); another config needs its own --library-dir")


def _same_solves(shard: pd.DataFrame, held: pd.DataFrame) -> bool:
    """Whether a shard table holds the same solves as the library's rows of that shard (timings aside)."""
    if FINGERPRINT not in shard and FINGERPRINT in held and not held[FINGERPRINT].astype(bool).any():
        held = held.drop(columns=FINGERPRINT)  # a shard made before rows carried it, held as unknown
    columns = [c for c in held.columns if c not in TIMING_COLUMNS]
    if sorted(shard.columns) != sorted(held.columns) or len(shard) != len(held):
        return False
    a = shard[columns].sort_values("start").reset_index(drop=True)
    b = held[columns].sort_values("start").reset_index(drop=True)
    try:
        pd.testing.assert_frame_equal(a, b, check_dtype=False, check_exact=True)
    except AssertionError:
        return False
    return True


#: Starts of every new shard that export re-solves (seeded by the shard's seed), by default.
RESOLVE_SAMPLE = 1


def verify_rows(df: pd.DataFrame, problem, options, where: str) -> None:
    """Recompute what a shard says about its rows instead of trusting it (``InputError`` naming the file, the
    start and the column otherwise): every row's ``objective`` is the problem's objective of its stored solution
    (−m_f), ``solver_success`` is the solver's status with the match-point defect within ``feasibility_tol``,
    and ``converged`` is that success with the solution's independent re-propagation defect (recomputed here,
    the problem's ``verify_defect``) within ``verify_tol``."""
    from amorgs.solvers.ipopt import IPOPT_SUCCESS

    names = list(problem.variable_names)
    for row in df.itertuples(index=False):
        r = row._asdict()
        x = np.array([r[n] for n in names], float)
        start = f"{where}: start {r['start']}"
        has_x = bool(np.all(np.isfinite(x)))
        if has_x and r["objective"] != problem.objective(x):
            raise InputError(f"{start}: objective {r['objective']!r} is not the solution's ({problem.objective(x)!r})")
        success = bool(has_x and r["status"] in IPOPT_SUCCESS and r["defect"] <= options.feasibility_tol)
        if bool(r["solver_success"]) != success:
            raise InputError(f"{start}: solver_success {r['solver_success']} but status {r['status']!r} and "
                             f"match-point defect {r['defect']!r} (feasibility_tol {options.feasibility_tol})")
        verify = problem.verify_defect(x, float(r["alpha"])) if success else math.nan
        converged = bool(success and verify <= options.verify_tol)
        if bool(r["converged"]) != converged:
            raise InputError(f"{start}: converged {r['converged']} but the solution re-propagates with defect "
                             f"{verify:.3g} (verify_tol {options.verify_tol})")


def resolve_check(df: pd.DataFrame, solver, problem, where: str, sample: int = RESOLVE_SAMPLE) -> int:
    """Re-solve ``sample`` starts of one shard (chosen with ``default_rng(seed)``) from their guesses with
    ``solver`` and require the recorded status, iterations and m_f bit for bit (``InputError`` naming the file
    and the start otherwise; first, a recorded NLP fingerprint must be ``solver``'s at this α: only the code
    that made a shard can reproduce it).  Returns the starts re-solved."""
    if sample <= 0 or not len(df):
        return 0
    alpha = float(df["alpha"].iloc[0])
    held = sorted(set(df[FINGERPRINT]) - {""}) if FINGERPRINT in df else []
    if held and hasattr(solver, "fingerprint") and held != [solver.fingerprint(alpha)]:
        raise InputError(f"{where}: solved by code with NLP fingerprint {held[0]}; this code's is "
                         f"{solver.fingerprint(alpha)} at α = {alpha:g} — export it with the code that made it")
    rng = np.random.default_rng(int(df["seed"].iloc[0]))
    rows = df.iloc[np.sort(rng.choice(len(df), size=min(sample, len(df)), replace=False))]
    guesses = seeded_guesses(rows, problem.name)
    for (_, row), guess in zip(rows.iterrows(), guesses):
        again = solver.solve(guess, alpha)
        m_f, m_f_again = float(row["m_f"]), float(again.x[3])
        same = (again.status == row["status"] and int(again.iterations) == int(row["iterations"])
                and (m_f == m_f_again or (math.isnan(m_f) and math.isnan(m_f_again))))
        if not same:
            raise InputError(f"{where}: start {row['start']} re-solves to {again.status}, {again.iterations} "
                             f"iterations, m_f {m_f_again!r}; the shard says {row['status']}, {row['iterations']}, "
                             f"{m_f!r} — not this code's solve of its seeded guess")
    return len(rows)


def _solution_keys(df: pd.DataFrame, names: list[str]) -> pd.Series:
    """One bytes key per row's solution vector (NaN rows: no solution, no key)."""
    x = df[names].to_numpy(float)
    keys = pd.Series([r.tobytes() for r in x], index=df.index)
    return keys[np.all(np.isfinite(x), axis=1)]


def export_library(solutions_dir: str | Path, library_dir: str | Path, problem: str, cfg, config_file: str | Path,
                   resolve_sample: int = RESOLVE_SAMPLE) -> dict:
    """Add every finished library-config shard under ``solutions_dir/alpha=*/`` not yet in the library.

    ``cfg`` is the typed config read from ``config_file`` (:func:`amorgs.config.load_config`; the file's text —
    overrides of the typed defaults — is recorded, and so is the effective config with its hash).  The library is one config's: ``config_file`` must have the identity (:func:`library_identity`) that the
    manifest records, whatever file it is (another config's shards need another ``library_dir``).  Every shard
    is checked (:func:`check_library_shard`; a new one must carry the config's solver-option hash, a held one
    may predate it); a shard whose index the library holds must hold the same solves as the library (timings
    aside), or the export is refused naming the file; one bad shard refuses the whole export.  Per α, the new shards become one consolidated file
    ``alpha={label}/shards-{first}-{last}.parquet`` (solutions clipped into the box, see
    :func:`clip_to_bounds`), and the manifest gains its entry.  Nothing new: the library is left untouched.
    Returns a summary: files and rows added, held shards found identical, and the library totals.

    The gate verifies what it admits (issue 39): each new shard's rows are re-verified (:func:`verify_rows`:
    objective, solver verdict and the independent re-propagation recomputed), its solutions must not repeat a
    solution the library holds or another new shard brings, and ``resolve_sample`` of its starts are re-solved
    from their seeded guesses and must reproduce it bit for bit (:func:`resolve_check`).  The manifest's config
    record changes only through the config file it records (``config/library.yaml``).
    """
    section = getattr(cfg.problems, problem)
    alpha_values = section.alpha_values()
    identity = library_identity(cfg, problem)
    prob = get_problem(problem)
    root = Path(library_dir) / problem
    if not Path(solutions_dir).is_dir():
        raise InputError(f"{solutions_dir}: no such directory (--solutions-dir: the generate rule's "
                         "results/<problem>/solutions of a library-config run)")
    manifest = read_manifest(library_dir, problem)
    if manifest is not None:
        check_library_config(manifest, cfg, config_file, root, problem)
    else:
        manifest = {"format": FORMAT, "problem": problem, "files": [], "exports": []}
    holder = {(e["file"].split("/")[0], k): e["file"] for e in manifest["files"] for k in e["shards"]}
    held_tables: dict[str, pd.DataFrame] = {}

    def clipped(df: pd.DataFrame, where) -> pd.DataFrame:
        return clip_to_bounds(df, prob.variable_names, prob.lower, prob.upper, where=str(where))

    new: dict[str, list[tuple[int, pd.DataFrame]]] = {}
    identical = 0
    for path in sorted(Path(solutions_dir).glob("alpha=*/shard-*.parquet")):
        label_dir = path.parent.name
        if not path.stem.removeprefix("shard-").isdigit():
            raise InputError(f"{path}: not a shard table name (shard-<index>.parquet)")
        shard = int(path.stem.removeprefix("shard-"))
        df = read_table(path)
        held_file = holder.get((label_dir, shard))
        check_library_shard(df, path, problem, cfg.seed, section.generate.starts_per_shard, alpha_values,
                            options_hash=None if held_file else identity["options_hash"])
        if int(df["shard"].iloc[0]) != shard:
            raise InputError(f"{path}: file name says shard {shard}, rows say {int(df['shard'].iloc[0])}")
        if held_file is None:
            new.setdefault(label_dir, []).append((shard, df))
            continue
        if held_file not in held_tables:
            held_tables[held_file] = read_library_file(root / held_file, library_dir, problem)
        held = held_tables[held_file]
        if not _same_solves(clipped(df, path), held[held["shard"] == shard]):
            raise InputError(f"{path}: the library already holds shard {shard} at {label_dir} ({root / held_file}) "
                             "with different solves; shards are immutable, so this one was not made by the "
                             "library's config and code")
        identical += 1

    if new:
        _gate(new, manifest, root, library_dir, problem, prob, section.solver, solutions_dir, resolve_sample)
    files = manifest["files"]
    if not new:
        if not files:
            raise InputError(f"no library-config shard tables under {solutions_dir}/alpha=*/ to export")
        return {"files_added": 0, "rows_added": 0, "held_identical": identical, **manifest["totals"]}

    now = _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds")
    commit = git_commit()
    added_rows = 0
    for label_dir, parts in sorted(new.items()):
        shards = sorted(k for k, _ in parts)
        where = f"{solutions_dir}/{label_dir}"
        df = clipped(merge_shards(d for _, d in parts), where)
        rel = f"{label_dir}/shards-{shards[0]:05d}-{shards[-1]:05d}.parquet"
        fingerprints = sorted(set(df[FINGERPRINT]) - {""}) if FINGERPRINT in df else []
        if len(fingerprints) > 1:
            raise InputError(f"{where}: shards of several codes (NLP fingerprints {fingerprints}): export them "
                             "from separate runs")
        generation = assign_generation(manifest, solver_generation(section.solver), identity["options_hash"],
                                       label_dir.removeprefix("alpha="), fingerprints[0] if fingerprints else "", commit)
        write_parquet(drop_seeded_guesses(df, problem, where), root / rel)
        conv = df[df["converged"]]
        files.append({
            "file": rel,
            "alpha": float(df["alpha"].iloc[0]),
            "shards": shards,
            "rows": int(len(df)),
            "converged": int(len(conv)),
            "best_objective": float(conv["objective"].min()) if len(conv) else None,
            "sha256": sha256_file(root / rel),
            "bytes": (root / rel).stat().st_size,
            "options_hashes": sorted(df["options_hash"].astype(str).unique().tolist()),
            "guesses": GUESSES_SEEDED,
            "generation": generation,
            "nlp_fingerprints": fingerprints,
            "cpu_hours": float(df["cpu_s"].fillna(0).sum() / 3600),
            "exported": now,
            "git_commit": commit,
        })
        added_rows += len(df)
    files.sort(key=lambda e: e["file"])
    manifest["exports"].append({"created": now, "git_commit": commit, "files_added": len(new), "rows_added": added_rows})
    manifest.update({
        "problem": problem,
        "config_file": str(config_file),
        "config": Path(config_file).read_text(),
        "effective_config": cfg.model_dump(mode="json"),
        "config_hash": cfg.hash,
        "seed": identity["seed"],
        "starts_per_shard": identity["starts_per_shard"],
        "identity": identity,
        **_summaries(files, manifest.get("generation_codes")),
    })
    write_json(manifest, root / MANIFEST)
    return {"files_added": len(new), "rows_added": added_rows, "held_identical": identical, **manifest["totals"]}


def _gate(new: dict, manifest: dict, root: Path, library_dir, problem: str, prob, options, solutions_dir,
          resolve_sample: int) -> None:
    """The checks of :func:`export_library` on the new shards that their own columns cannot vouch for: rows
    re-verified, no repeated solution, a seeded sample re-solved (``InputError`` naming the file)."""
    names = list(prob.variable_names)
    seen: dict[bytes, str] = {}
    for entry in manifest["files"]:  # every solution the library holds
        held = read_library_file(root / entry["file"], library_dir, problem, manifest)
        seen.update({k: str(root / entry["file"]) for k in _solution_keys(held, names)})
    solver = prob.make_local_solver(options) if resolve_sample > 0 else None
    for label_dir, parts in sorted(new.items()):
        for shard, df in parts:
            where = f"{solutions_dir}/{label_dir}/shard-{shard}.parquet"
            df = clip_to_bounds(df, names, prob.lower, prob.upper, where=where)  # the rows as they would be stored
            verify_rows(df, prob, options, where)
            keys = _solution_keys(df, names)
            for start, key in zip(df.loc[keys.index, "start"], keys):
                if key in seen:
                    raise InputError(f"{where}: start {start}'s solution is already held ({seen[key]}): a shard "
                                     "brings solves of its own seeded guesses, never copies")
                seen[key] = where
            if solver is not None:
                resolve_check(df, solver, prob, where, resolve_sample)


def _summaries(files: list[dict], codes: dict | None = None) -> dict:
    """The manifest's derived keys over its file entries: ``totals``, ``generations`` and ``per_alpha``."""
    total_bytes = sum(e["bytes"] for e in files)
    rows = sum(e["rows"] for e in files)
    return {
        "totals": {
            "files": len(files),
            "shards": sum(len(e["shards"]) for e in files),
            "rows": rows,
            "converged": sum(e["converged"] for e in files),
            "cpu_hours": sum(e["cpu_hours"] for e in files),
            "bytes": total_bytes,
            "bytes_per_row": total_bytes / rows,
        },
        "generations": _generations(files, codes),
        "per_alpha": _per_alpha(files),
    }


def compact_library(library_dir: str | Path, problem: str) -> dict:
    """Rewrite the library as one compact file per (α, generation): the same rows, fewer bytes.

    Each export adds one file per α (≈ 100 rows), and a Parquet file's footer (≈ 37 KB for 80 columns) is a
    third of such a file; files written before compact storage also hold the 64 ``guess_*`` columns.  Per
    (α, generation) with more than one file or any stored guesses, every file is read through the manifest
    (hash and rows checked), the rows are merged in (shard, start) order, the guesses are checked bit for bit
    against the seeded draw and dropped (:func:`drop_seeded_guesses`), and the merged table is written as
    ``alpha={label}/shards-{first}-{last}.parquet`` — after checking that reading it back gives exactly the
    rows read before.  Its manifest entry unions the merged entries (shards, rows, converged, option hashes,
    CPU-hours; ``sources``: each merged file's name, shards, export time and commit), and the manifest gains
    a ``compactions`` record.  Readers see the same table for every α before and after (:func:`read_library`
    merges files in (shard, start) order).  Not atomic across files: run it on a committed library (an
    interrupted compaction is undone with ``git checkout``).  Returns bytes and files before and after.
    """
    root = Path(library_dir) / problem
    manifest = verify_library(library_dir, problem)
    if manifest is None:
        raise InputError(f"{root}: no library to compact (no {MANIFEST})")
    files = manifest["files"]
    groups: dict[tuple[str, int], list[dict]] = {}
    for entry in files:
        groups.setdefault((entry["file"].split("/")[0], entry.get("generation", 1)), []).append(entry)
    now = _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds")
    kept, written, replaced = [], [], []
    for (label_dir, generation), entries in sorted(groups.items()):
        if len(entries) == 1 and entries[0].get("guesses") == GUESSES_SEEDED:
            kept.append(entries[0])
            continue
        df = merge_shards(read_library_file(root / e["file"], library_dir, problem, manifest) for e in entries)
        shards = sorted(k for e in entries for k in e["shards"])
        if sorted(df["shard"].unique().tolist()) != sorted(set(shards)) or len(shards) != len(set(shards)):
            raise InputError(f"{root / label_dir}: the files' rows and the manifest's shard lists disagree")
        rel = f"{label_dir}/shards-{shards[0]:05d}-{shards[-1]:05d}.parquet"
        tmp = root / f"{rel}.compact"
        write_parquet(drop_seeded_guesses(df, problem, str(root / label_dir)), tmp)
        back = restore_seeded_guesses(read_table(tmp), problem)
        pd.testing.assert_frame_equal(back, df, check_exact=True)  # the same rows, bit for bit
        conv = df[df["converged"]]
        written.append((tmp, root / rel))
        replaced.extend(root / e["file"] for e in entries)
        kept.append({
            "file": rel,
            "alpha": entries[0]["alpha"],
            "shards": shards,
            "rows": int(len(df)),
            "converged": int(len(conv)),
            "best_objective": float(conv["objective"].min()) if len(conv) else None,
            "sha256": sha256_file(tmp),
            "bytes": tmp.stat().st_size,
            "options_hashes": sorted({h for e in entries for h in e["options_hashes"]}),
            "guesses": GUESSES_SEEDED,
            "generation": generation,
            **({"nlp_fingerprints": sorted({f for e in entries for f in e["nlp_fingerprints"]})}
               if any("nlp_fingerprints" in e for e in entries) else {}),
            "cpu_hours": sum(e["cpu_hours"] for e in entries),
            "exported": max(e["exported"] for e in entries),
            "git_commit": max(entries, key=lambda e: e["exported"]).get("git_commit", "unknown"),
            "compacted": now,
            "sources": [{k: e[k] for k in ("file", "shards", "exported", "git_commit") if k in e} for e in entries],
        })
    before = {"files": len(files), "bytes": sum(e["bytes"] for e in files)}
    if not written:
        return {"before": before, "after": before, "files_rewritten": 0}
    for path in replaced:
        path.unlink()
    for tmp, final in written:
        tmp.replace(final)
    kept.sort(key=lambda e: e["file"])
    after = {"files": len(kept), "bytes": sum(e["bytes"] for e in kept)}
    manifest["files"] = kept
    manifest.setdefault("compactions", []).append({"created": now, "git_commit": git_commit(),
                                                   "files_before": before["files"], "bytes_before": before["bytes"],
                                                   "files_after": after["files"], "bytes_after": after["bytes"]})
    manifest.update(_summaries(kept, manifest.get("generation_codes")))
    write_json(manifest, root / MANIFEST)
    return {"before": before, "after": after, "files_rewritten": len(replaced)}


def held_shards(library_dir: str | Path, problem: str) -> set[tuple[str, int]]:
    """(α label, shard index) of every shard the library holds."""
    manifest = read_manifest(library_dir, problem)
    if manifest is None:
        return set()
    return {(e["file"].split("/")[0].removeprefix("alpha="), k) for e in manifest["files"] for k in e["shards"]}
