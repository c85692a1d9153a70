"""Another commit's amorgs: a temporary git worktree of that commit, run in this environment.

A committed reference stays checkable after the code moves on: its starts are re-solved by the code that made
them, in a throwaway ``git worktree`` of that commit, with this interpreter and its packages (the same
environment) and the worktree's ``src`` first on ``PYTHONPATH`` (``amorgs reference-certify --at-commit``).
Also the git facts that provenance needs: is the tree clean, is a commit reachable from the branch.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from amorgs.errors import InputError

#: The fingerprint module, loaded by file path into another commit's process (it imports no amorgs).
FINGERPRINT_MODULE = Path(__file__).resolve().parent / "solvers" / "fingerprint.py"


def _git(args: list[str], cwd: str | Path = ".") -> subprocess.CompletedProcess:
    return subprocess.run(["git", *args], cwd=cwd, capture_output=True, text=True)


def repository_root(path: str | Path = ".") -> Path:
    """The top of the git checkout holding ``path`` (``InputError`` outside one)."""
    out = _git(["rev-parse", "--show-toplevel"], cwd=path)
    if out.returncode:
        raise InputError(f"{Path(path).resolve()}: not inside a git checkout")
    return Path(out.stdout.strip())


def resolve_commit(commit: str, repo: str | Path = ".") -> str:
    """The full hash of ``commit``; ``InputError`` when the repository does not hold it."""
    out = _git(["rev-parse", "--verify", "--quiet", f"{commit}^{{commit}}"], cwd=repo)
    if out.returncode:
        raise InputError(f"commit {commit}: not in the repository at {repository_root(repo)} (a shallow clone? "
                         "`git fetch --unshallow`)")
    return out.stdout.strip()


def is_reachable(commit: str, branch: str = "HEAD", repo: str | Path = ".") -> bool:
    """Whether ``commit`` exists and is an ancestor of (or equal to) ``branch``."""
    if _git(["cat-file", "-e", f"{commit}^{{commit}}"], cwd=repo).returncode:
        return False
    return _git(["merge-base", "--is-ancestor", commit, branch], cwd=repo).returncode == 0


def dirty_files(repo: str | Path = ".") -> list[str]:
    """Tracked files with uncommitted changes (``git status --porcelain``, untracked files aside)."""
    out = _git(["status", "--porcelain", "--untracked-files=no"], cwd=repo)
    return [line[3:] for line in out.stdout.splitlines() if line.strip()]


@contextmanager
def worktree(commit: str, repo: str | Path = ".") -> Iterator[Path]:
    """A detached worktree of ``commit`` in a temporary directory, removed (with its git record) on exit."""
    full = resolve_commit(commit, repo)
    root = repository_root(repo)
    with tempfile.TemporaryDirectory(prefix="amorgs-commit-") as tmp:
        tree = Path(tmp) / full[:12]
        out = _git(["worktree", "add", "--detach", str(tree), full], cwd=root)
        if out.returncode:
            raise InputError(f"commit {full[:12]}: git worktree add failed: {out.stderr.strip().splitlines()[-1]}")
        try:
            yield tree
        finally:
            _git(["worktree", "remove", "--force", str(tree)], cwd=root)
            _git(["worktree", "prune"], cwd=root)


#: The instruction-set flags (``/proc/cpuinfo``) each of numpy's OpenBLAS kernel sets needs: forcing a set the
#: CPU lacks (``$OPENBLAS_CORETYPE``) would crash the process on its first BLAS call.
BLAS_CORE_FLAGS = {
    "SkylakeX": ("avx512f", "avx512cd", "avx512bw", "avx512dq", "avx512vl"),
    "Cooperlake": ("avx512f", "avx512cd", "avx512bw", "avx512dq", "avx512vl", "avx512_bf16"),
    "Haswell": ("avx2", "fma"),
    "Zen": ("avx2", "fma"),
    "Sandybridge": ("avx",),
    "Nehalem": ("sse4_2",),
    "Prescott": ("pni",),
}


def check_blas_core(core: str) -> None:
    """``InputError`` in one line unless this CPU can run numpy's OpenBLAS kernel set ``core``."""
    if core not in BLAS_CORE_FLAGS:
        raise InputError(f"BLAS kernel set {core!r}: unknown (one of {', '.join(BLAS_CORE_FLAGS)})")
    try:
        with open("/proc/cpuinfo") as fh:
            flags = set(next((line.split(":", 1)[1].split() for line in fh if line.startswith("flags")), []))
    except OSError:
        return  # not Linux: let OpenBLAS decide
    missing = [f for f in BLAS_CORE_FLAGS[core] if f not in flags]
    if missing:
        raise InputError(f"BLAS kernel set {core}: this CPU lacks {', '.join(missing)}, which it needs — certify on "
                         f"a CPU that has them")


def environment_at(tree: Path, blas_core: str = "", cache: Path | None = None) -> dict[str, str]:
    """The environment of a process that runs ``tree``'s amorgs: this interpreter, ``tree/src`` first on
    ``PYTHONPATH``, one thread per numerical library; numpy's OpenBLAS forced to the kernel set ``blas_core``
    where one is named (``$OPENBLAS_CORETYPE``: code older than 2026-12-05 built the NLP's coast flow with numpy's
    BLAS, so its bits depend on that kernel set; :func:`check_blas_core` first), and the compile cache ``cache``
    where one is named (``$AMORGS_CACHE_DIR``)."""
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(tree / "src"), *filter(None, [env.get("PYTHONPATH")])])
    for key in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
        env.setdefault(key, "1")
    if blas_core:
        check_blas_core(blas_core)
        env["OPENBLAS_CORETYPE"] = blas_core
    if cache is not None:
        env["AMORGS_CACHE_DIR"] = str(cache)
    return env


def run_amorgs(tree: Path, args: list[str], timeout_s: float | None = None,
               env: dict[str, str] | None = None) -> subprocess.CompletedProcess:
    """``python -m amorgs ARGS`` with ``tree``'s package, in ``tree`` (``env``: default :func:`environment_at`)."""
    return subprocess.run([sys.executable, "-m", "amorgs", *args], cwd=tree, env=env or environment_at(tree),
                          capture_output=True, text=True, timeout=timeout_s)


#: Run in another commit's process: that commit's CR3BP solver for the given options, fingerprinted by today's
#: fingerprint module (loaded by path).  Works with every commit since the solver kept ``_nlp(α) → (tr, nlpsol,
#: lbw, ubw[, lbg, ubg])``; older commits solved with lbg = ubg = 0.
_FINGERPRINT_SCRIPT = r"""
import importlib.util, json, sys
import numpy as np
spec = importlib.util.spec_from_file_location("amorgs_fingerprint_today", sys.argv[1])
fp = importlib.util.module_from_spec(spec); spec.loader.exec_module(fp)
request = json.loads(sys.argv[2])
from amorgs.problems import get_problem
problem = get_problem(request["problem"])
if request.get("config"):
    from amorgs.config import load_config
    options = getattr(load_config(request["config"]).problems, request["problem"]).solver
else:
    options = request["options"]
solver = problem.make_local_solver(options)
out = {"options_hash": getattr(solver, "options_hash", ""), "nlp_fingerprints": {}, "environment": fp.environment()}
for alpha in request["alphas"]:
    built = solver._nlp(float(alpha))
    nlpsol, bounds = built[1], list(built[2:])
    if len(bounds) == 2:
        n_g = nlpsol.size1_out("g")
        bounds += [np.zeros(n_g), np.zeros(n_g)]
    out["nlp_fingerprints"][f"{float(alpha):g}"] = fp.nlp_fingerprint(nlpsol, tuple(bounds), float(alpha))
print("FINGERPRINTS " + json.dumps(out))
"""


def fingerprints_at(tree: Path, alphas, problem: str = "cr3bp", config: str | Path | None = None,
                    options: dict | None = None, timeout_s: float = 1800.0, env: dict[str, str] | None = None) -> dict:
    """``{"options_hash", "nlp_fingerprints": {α: fingerprint}, "environment"}`` of the solver of ``tree``'s
    code: for the solver options of ``config`` (a config file that code reads) or ``options`` (a mapping it
    accepts), in ``env`` (default :func:`environment_at`).  ``InputError`` with the last line of the error when
    that code cannot build it."""
    request = {"problem": problem, "alphas": [float(a) for a in alphas],
               "config": str(Path(config).resolve()) if config else None, "options": options}
    out = subprocess.run([sys.executable, "-c", _FINGERPRINT_SCRIPT, str(FINGERPRINT_MODULE), json.dumps(request)],
                         cwd=tree, env=env or environment_at(tree), capture_output=True, text=True, timeout=timeout_s)
    line = next((x for x in out.stdout.splitlines() if x.startswith("FINGERPRINTS ")), None)
    if out.returncode or line is None:
        last = (out.stderr.strip().splitlines() or ["no output"])[-1]
        raise InputError(f"commit at {tree.name}: its solver could not be fingerprinted ({last})")
    return json.loads(line.removeprefix("FINGERPRINTS "))
