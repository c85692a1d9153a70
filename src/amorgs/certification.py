"""Reproducibility certificates of the committed references, that cannot silently go stale.

A reference (``reference/<name>/``, :mod:`amorgs.reference`) holds every ablation start it solved
(``starts.parquet``).  Its *identity* is the code that solved them: the solver options' hash and the numerical
fingerprint of the NLP at each of its α (:mod:`amorgs.solvers.fingerprint`), beside the commit and the
environment (CasADi, numpy, CPU) they were taken in.  A certificate re-solves a seeded sample of the starts and
requires status, iterations and m_f bit for bit — which only the same identity can give.  So the fingerprints are
compared *first*: a mismatch is reported in one line (which code made the reference, which code is here)
instead of a page of re-solves that differ.

Every committed reference has one entry in the registry :data:`REGISTRY` (``reference/certification.json``)
that says how it is certified (its *route*):

* ``today``: today's code has the reference's fingerprints — re-solve here;
* ``commit``: the reference stays valid at the commit named — re-solve in a temporary git worktree of that
  commit, in this environment (:mod:`amorgs.checkout`), after checking that the worktree's solver still has the
  recorded fingerprints;
* ``historical``: not certifiable (the reason is recorded: e.g. no per-start table).

``amorgs reference-export`` enters a new reference as ``today``.  When a code change moves the fingerprint,
``amorgs reference-certify --all`` (CI) fails on every ``today`` reference until its author re-runs it or
records that it stays valid at its commit (``amorgs reference-certify REF --at-commit COMMIT --record``, which
certifies there first).
"""

from __future__ import annotations

import datetime as _dt
import json
import tempfile
from pathlib import Path

import numpy as np
import pandas as pd

from amorgs.checkout import (
    check_blas_core,
    environment_at,
    fingerprints_at,
    is_reachable,
    repository_root,
    resolve_commit,
    run_amorgs,
    worktree,
)
from amorgs.config import load_config
from amorgs.data.io import write_json
from amorgs.errors import InputError
from amorgs.reference import CONFIG_COPY, REGISTRY, STARTS_FILE, starts_identity, verify_reference
from amorgs.solvers.codegen import cache_dir
from amorgs.tracking import git_state, package_versions

ROUTES = ("today", "commit", "historical")


def alpha_key(alpha: float) -> str:
    """How an α is written as a key of ``nlp_fingerprints`` (``0.3``, ``1``)."""
    return f"{float(alpha):g}"


# ------------------------------------------------------------------------------------------- the registry


def registry_path(repo: str | Path = ".") -> Path:
    return repository_root(repo) / REGISTRY


def read_registry(repo: str | Path = ".") -> dict:
    """The registry (``{"format": 1, "references": {name: entry}}``); empty when the file does not exist."""
    path = registry_path(repo)
    if not path.is_file():
        return {"format": 1, "references": {}}
    try:
        registry = json.loads(path.read_text())
    except ValueError as exc:
        raise InputError(f"{path}: not a readable certification registry ({exc})") from None
    for name, entry in registry.get("references", {}).items():
        if entry.get("route") not in ROUTES:
            raise InputError(f"{path}: reference {name!r} has route {entry.get('route')!r}, expected one of {ROUTES}")
    return registry


def _under_reference(dest: str | Path) -> str | None:
    """The path of ``dest`` under the ``reference/`` folder of the repository holding it, None if it lies elsewhere."""
    dst = Path(dest).resolve()
    try:
        return dst.relative_to(repository_root(dst.parent if dst.parent.exists() else ".") / "reference").as_posix()
    except (ValueError, InputError):
        return None


def reference_name(dest: str | Path) -> str:
    """The registry's name of a reference directory: its path under the repository's ``reference/``."""
    return _under_reference(dest) or Path(dest).resolve().name


def under_reference(dest: str | Path) -> bool:
    """Whether ``dest`` lies under the ``reference/`` folder of the repository holding it (a committed reference)."""
    return _under_reference(dest) is not None


def record_entry(dest: str | Path, entry: dict) -> Path:
    """Write ``entry`` as the registry entry of the reference ``dest`` (the registry of the repository holding it)."""
    dst = Path(dest).resolve()
    path = registry_path(dst.parent)
    registry = read_registry(dst.parent)
    registry["references"][reference_name(dst)] = entry
    registry["references"] = dict(sorted(registry["references"].items()))
    write_json(registry, path)
    return path


def _entry(dest: Path, provenance: dict) -> dict | None:
    """The registry entry of ``dest``, else the identity its ``provenance`` (its manifest) records (route
    ``today``), else None."""
    try:
        entry = read_registry(dest.parent).get("references", {}).get(reference_name(dest))
    except InputError:
        entry = None
    if entry is not None:
        return entry
    return {"route": "today", **provenance["identity"]} if "identity" in provenance else None


# ------------------------------------------------------------------------------------------- identities


def identity_here(config_file: str | Path, alphas, problem: str = "cr3bp") -> dict:
    """This checkout's identity for the solver of ``config_file`` at ``alphas``: options hash, fingerprints
    (the NLP built per α in this process), environment."""
    from amorgs.problems import get_problem
    from amorgs.solvers.fingerprint import environment

    options = getattr(load_config(config_file).problems, problem).solver
    solver = get_problem(problem).make_local_solver(options)
    return {"options_hash": options.digest(),
            "nlp_fingerprints": {alpha_key(a): solver.fingerprint(float(a)) for a in sorted(set(alphas))},
            "environment": environment()}


def _differences(recorded: dict, found: dict) -> list[str]:
    out = []
    if recorded.get("options_hash") != found["options_hash"]:
        out.append(f"options {recorded.get('options_hash')} ≠ {found['options_hash']}")
    for key, fp in sorted(recorded.get("nlp_fingerprints", {}).items()):
        if found["nlp_fingerprints"].get(key) != fp:
            out.append(f"α = {key}: {fp} ≠ {found['nlp_fingerprints'].get(key)}")
    return out


# ------------------------------------------------------------------------------------------- certificates


def compare_resolves(rows: pd.DataFrame, records, variable_names: tuple[str, ...]) -> pd.DataFrame:
    """Each start of ``rows`` (a slice of :data:`~amorgs.reference.STARTS_FILE`) beside its re-solve
    (``records``: solve records in the same order, turned into table rows exactly as the ablation did, with
    ``variable_names``): ``status``/``status_again``, ``iterations``/``iterations_again``, ``m_f``/``m_f_again``
    (kg), and ``exact`` — the same status, the same iteration count and a bit-identical m_f (both NaN counts as
    identical)."""
    out = rows[["sampler", "alpha", "seed", "start", "status", "iterations", "m_f"]].reset_index(drop=True)
    again = pd.DataFrame([r.to_row(variable_names) for r in records])
    out["status_again"] = again["status"].to_numpy()
    out["iterations_again"] = again["iterations"].astype(int).to_numpy()
    out["m_f_again"] = again["m_f"].astype(float).to_numpy()
    m_f, m_f_again = out["m_f"].to_numpy(float), out["m_f_again"].to_numpy(float)
    same_m_f = (m_f == m_f_again) | (np.isnan(m_f) & np.isnan(m_f_again))
    out["exact"] = (out["status"] == out["status_again"]).to_numpy() & (
        out["iterations"] == out["iterations_again"]).to_numpy() & same_m_f
    return out


def _read_starts(dst: Path) -> pd.DataFrame:
    path = dst / STARTS_FILE
    if not path.is_file():
        raise InputError(f"{path}: this reference has no per-start table (exported before they were kept); "
                         "re-export it from its run to certify it")
    return pd.read_parquet(path)


def _check_counts(sample: int, workers: int) -> None:
    if sample < 1:
        raise InputError(f"--sample {sample}: certify at least 1 start")
    if workers < 1:
        raise InputError(f"--workers {workers}: at least 1 solver process")


def _resolve_sample(dst: Path, manifest: dict, starts: pd.DataFrame, sample: int, seed: int, workers: int) -> dict:
    """Re-solve ``sample`` of the ``starts`` of the verified reference ``dst`` (manifest ``manifest``; drawn
    without replacement with ``numpy.random.default_rng(seed)``) from their stored guesses with this checkout's
    solver and the options of the run's config, and compare (:func:`compare_resolves`); no identity check (see
    :func:`certify_reference`)."""
    from amorgs.problems import get_problem
    from amorgs.solvers.multistart import solve_guesses

    problem = get_problem("cr3bp")
    options = load_config(dst / CONFIG_COPY).problems.cr3bp.solver
    rng = np.random.default_rng(seed)
    chosen = starts.iloc[np.sort(rng.choice(len(starts), size=min(sample, len(starts)), replace=False))]
    guess_cols = [f"guess_{v}" for v in problem.variable_names]
    compared = []
    for alpha, rows in chosen.groupby("alpha", sort=True):
        records, _ = solve_guesses(problem, float(alpha), rows[guess_cols].to_numpy(float), workers, options,
                                   progress=False)
        compared.append(compare_resolves(rows, records, problem.variable_names))
    table = pd.concat(compared, ignore_index=True)
    dm = (table["m_f"] - table["m_f_again"]).abs()
    return {
        "reference": str(dst),
        "config_hash": manifest["config_hash"],
        "git_commit_of_run": manifest["git_commit"],
        "sample": int(len(table)),
        "seed": int(seed),
        "of_starts": int(len(starts)),
        "matched": int(table["exact"].sum()),
        "exact": bool(table["exact"].all()),
        "max_abs_dm_f_kg": float(dm.max()) if dm.notna().any() else 0.0,
        "options_hash": options.digest(),
        **git_state(Path.cwd()),
        "packages": {k.removeprefix("version."): v for k, v in package_versions().items()},
        "rows": json.loads(table.to_json(orient="records")),
    }


def certify_reference(dest: str | Path, sample: int = 20, seed: int = 0, workers: int = 1,
                      at_commit: str | None = None, blas_core: str | None = None) -> dict:
    """The reproducibility certificate of the committed reference ``dest`` (files checked against its manifest
    first).  Its recorded identity (registry entry, else its provenance) is compared with the code that would
    re-solve it:

    * ``at_commit`` None: this checkout.  Options or a fingerprint that differ raise ``InputError`` in one line
      naming both codes — nothing is re-solved.
    * ``at_commit`` a commit (``"recorded"``: the registry's): a temporary worktree of it, whose solver must have
      the recorded fingerprints (``InputError`` otherwise: the environment changed), runs that commit's own
      ``amorgs reference-certify``, with numpy's OpenBLAS forced to the kernel set ``blas_core`` (None: the one
      recorded for the reference, if any) — code older than 2026-12-05 built its NLP with numpy's BLAS.

    Returns the certificate (:func:`_resolve_sample`'s keys plus ``route``, ``code_commit``, ``nlp_fingerprints``,
    ``environment`` and, at a commit, ``blas_core``); ``exact`` says whether every re-solve matched bit for bit."""
    dst = Path(dest)
    manifest = verify_reference(dst)
    starts = _read_starts(dst)
    _check_counts(sample, workers)
    entry = _entry(dst, manifest)
    if entry is not None and entry["route"] == "historical":
        raise InputError(f"{dst}: historical, not certifiable — {entry.get('why', 'no reason recorded')}")
    alphas = sorted(set(starts["alpha"].astype(float)))
    recorded = {**starts_identity(starts), **(entry or {})}
    if at_commit is None:
        here = identity_here(dst / CONFIG_COPY, alphas)
        if "nlp_fingerprints" not in recorded:
            raise InputError(f"{dst}: no recorded fingerprint — certify it at the commit that made it and record "
                             f"that: amorgs reference-certify {dst} --at-commit COMMIT --record")
        diff = _differences(recorded, here)
        if diff:
            commit = str(recorded.get("commit", "?"))[:12]
            raise InputError(
                f"{dst}: made by the code of commit {commit} ({'; '.join(diff)} here at "
                f"{git_state(Path.cwd())['git_commit'][:12]}): this code cannot reproduce it — certify it at its "
                f"commit (--at-commit {commit}), or re-run it")
        cert = _resolve_sample(dst, manifest, starts, sample, seed, workers)
        return {**cert, "route": "today", "code_commit": cert["git_commit"],
                "nlp_fingerprints": here["nlp_fingerprints"], "environment": here["environment"]}

    commit = recorded.get("commit") if at_commit == "recorded" else at_commit
    if not commit:
        raise InputError(f"{dst}: no commit recorded to certify at; name one: --at-commit COMMIT")
    commit = resolve_commit(commit, dst.parent)
    core = (entry or {}).get("blas_core", "") if blas_core is None else blas_core
    if core:
        check_blas_core(core)
    with worktree(commit, dst.parent) as tree:
        # Its own compile cache per (commit, kernel set): code before 2026-12-03 keyed its compiled NLPs without
        # their constants, so an NLP compiled under one kernel set would be loaded under another.
        env = environment_at(tree, core, cache_dir() / "commits" / f"{commit[:12]}-{core or 'auto'}")
        there = fingerprints_at(tree, alphas, config=dst / CONFIG_COPY, env=env)
        if "nlp_fingerprints" in recorded:
            diff = _differences(recorded, there)
            if diff:
                raise InputError(f"{dst}: commit {commit[:12]} here gives other bits than recorded ({'; '.join(diff)}; "
                                 f"environment here: {there['environment']}) — the environment changed"
                                 + ("" if core else "; name the BLAS kernel set it was made with (--blas-core)"))
        with tempfile.TemporaryDirectory(prefix="amorgs-cert-") as tmp:
            output = Path(tmp) / "certificate.json"
            run = run_amorgs(tree, ["reference-certify", str(dst.resolve()), "--sample", str(sample), "--seed",
                                    str(seed), "--workers", str(workers), "--output", str(output)], env=env)
            if not output.is_file():
                last = (run.stderr.strip().splitlines() or run.stdout.strip().splitlines() or ["no output"])[-1]
                raise InputError(f"{dst}: the certificate at commit {commit[:12]} failed: {last}")
            cert = json.loads(output.read_text())
    return {**cert, "reference": str(dst), "route": "commit", "code_commit": commit, "nlp_fingerprints": there["nlp_fingerprints"],
            "environment": there["environment"], "blas_core": core}


def record_at_commit(dest: str | Path, cert: dict, why: str = "") -> Path:
    """Record in the registry that the reference ``dest`` stays valid at the commit its certificate ``cert``
    (an exact one, :func:`certify_reference` with ``at_commit``) was made at."""
    if not cert["exact"] or cert.get("route") != "commit":
        raise InputError(f"{dest}: only an exact certificate at a commit can be recorded")
    return record_entry(dest, {
        "route": "commit", "commit": cert["code_commit"], "options_hash": cert["options_hash"],
        "nlp_fingerprints": cert["nlp_fingerprints"], "environment": cert["environment"],
        **({"blas_core": cert["blas_core"]} if cert.get("blas_core") else {}),
        "recorded": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"),
        "certified": f"{cert['matched']} of {cert['sample']} starts exact (seed {cert['seed']})",
        **({"why": why} if why else {})})


def references_under(root: str | Path) -> list[Path]:
    """Every reference directory (one holding ``provenance.json``) under ``root``."""
    return sorted(p.parent for p in Path(root).rglob("provenance.json"))


def certify_all(repo: str | Path = ".", sample: int = 3, seed: int = 0, workers: int = 1,
                skip_unsupported_cpu: bool = False) -> list[dict]:
    """Certify every committed reference by its route (:data:`REGISTRY`); one result per reference:
    ``{"reference", "route", "ok", "line"}`` (and ``certificate``).  A reference missing from the registry,
    one whose fingerprint moved, or a re-solve that differs is not ok.  A ``commit`` route pinned to a BLAS kernel
    set this CPU cannot run (:func:`~amorgs.checkout.check_blas_core`) is not ok either, unless
    ``skip_unsupported_cpu``: then it is ``skipped`` (ok, and the line says why) — this machine cannot tell."""
    root = repository_root(repo)
    registry = read_registry(root)["references"]
    results = []
    for dest in references_under(root / "reference"):
        name = dest.relative_to(root / "reference").as_posix()
        entry = registry.get(name)
        if entry is None:
            results.append({"reference": name, "route": None, "ok": False,
                            "line": f"not in {REGISTRY}: export it with amorgs reference-export, or record its route"})
            continue
        if entry["route"] == "historical":
            results.append({"reference": name, "route": "historical", "ok": True,
                            "line": f"historical, not certified: {entry.get('why', '')}"})
            continue
        if entry["route"] == "commit" and entry.get("blas_core"):
            try:
                check_blas_core(entry["blas_core"])
            except InputError as exc:
                results.append({"reference": name, "route": "commit", "ok": skip_unsupported_cpu,
                                "skipped": skip_unsupported_cpu,
                                "line": f"not checked on this CPU: {exc}" if skip_unsupported_cpu else str(exc)})
                continue
        try:
            cert = certify_reference(dest, sample, seed, workers,
                                     at_commit="recorded" if entry["route"] == "commit" else None)
        except InputError as exc:
            results.append({"reference": name, "route": entry["route"], "ok": False, "line": str(exc)})
            continue
        at = f"at commit {cert['code_commit'][:12]}" if entry["route"] == "commit" else "with today's code"
        results.append({"reference": name, "route": entry["route"], "ok": cert["exact"], "certificate": cert,
                        "line": f"{cert['matched']} of {cert['sample']} starts exact {at}"})
    for name in sorted(set(registry) - {r["reference"] for r in results}):
        results.append({"reference": name, "route": registry[name]["route"], "ok": False,
                        "line": f"in {REGISTRY} but no reference/{name}/provenance.json"})
    return results


def check_exportable(run_dir: str | Path = ".", branch: str = "HEAD") -> dict:
    """The run's commit, if a reference or library may be exported from it: ``InputError`` when the checkout of
    ``run_dir`` has uncommitted changes to tracked files, or its commit is not reachable from ``branch`` (the
    branch the export is committed to)."""
    from amorgs.checkout import dirty_files

    state = git_state(run_dir)
    if state["git_commit"] == "unknown":
        raise InputError(f"{Path(run_dir).resolve()}: not a git checkout — a reference records the commit that ran it")
    dirty = dirty_files(run_dir)
    if dirty:
        raise InputError(f"{Path(run_dir).resolve()}: uncommitted changes ({', '.join(dirty[:3])}"
                         f"{' …' if len(dirty) > 3 else ''}) — commit them, re-run, then export")
    if not is_reachable(state["git_commit"], branch, repo="."):
        raise InputError(f"commit {state['git_commit'][:12]} of the run is not reachable from {branch} here — "
                         "push or merge it first, so that its provenance can be followed")
    return state
