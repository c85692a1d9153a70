"""The numerical fingerprint of a solver's problem (amorgs.solvers.fingerprint) and the certificates it guards
(amorgs.certification): the same code gives the same bits in any process; a one-ulp change of the dynamics
changes them, and a reference made by the other code is then refused in one line instead of re-solved."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pandas as pd
import pytest

from amorgs.problems import get_problem
from amorgs.problems.cr3bp import constants as K
from amorgs.problems.cr3bp import rk8_kernel
from amorgs.solvers.fingerprint import function_fingerprint, nlp_fingerprint, sample_points
from amorgs.solvers.options import IpoptOptions

#: Small and uncompiled (CasADi's virtual machine calls the kernel library): cheap to build.
OPTIONS = {"compile": "none", "max_iter": 40}


def _clear_kernel_caches() -> None:
    rk8_kernel.c_source.cache_clear()
    rk8_kernel._external.cache_clear()


@pytest.fixture
def heavier_moon():
    """Call it to make the CR3BP mass ratio one ulp larger, everywhere the NLP's code reads it (the C kernel is
    regenerated); undone, caches included, after the test."""
    patch = pytest.MonkeyPatch()

    def apply() -> None:
        patch.setattr(K, "MU", float(np.nextafter(K.MU, 1.0)))
        _clear_kernel_caches()

    yield apply
    patch.undo()
    _clear_kernel_caches()


def test_the_fingerprint_is_a_function_of_the_code_and_alpha():
    cr3bp = get_problem("cr3bp")
    a, b = cr3bp.make_local_solver(OPTIONS), cr3bp.make_local_solver(OPTIONS)
    assert a.fingerprint(0.5) == b.fingerprint(0.5)  # a second build of the same code
    assert a.fingerprint(0.5) != a.fingerprint(0.6)  # the parameter is part of what is hashed
    assert len(a.fingerprint(0.5)) == 12 and int(a.fingerprint(0.5), 16) >= 0
    record = a.solve(cr3bp.sample_uniform(0.5, 1, np.random.default_rng(0))[0], 0.5)
    assert record.nlp_fingerprint == a.fingerprint(0.5)
    assert record.to_row(cr3bp.variable_names)["nlp_fingerprint"] == a.fingerprint(0.5)
    dejong = get_problem("dejong").make_local_solver(None)
    assert dejong.solve(np.array([1.0, 2.0]), 0.3).nlp_fingerprint == dejong.fingerprint(0.3) != dejong.fingerprint(0.4)


def test_the_fingerprint_sees_one_bit_of_any_output():
    import casadi as ca

    x, p = ca.MX.sym("x", 3), ca.MX.sym("p")
    lbw, ubw = np.full(3, -1.0), np.full(3, 1.0)

    def solver(scale):
        return ca.nlpsol("f", "ipopt", {"x": x, "p": p, "f": ca.sumsqr(x) * scale, "g": x[0] * p})

    base = nlp_fingerprint(solver(1.0), (lbw, ubw), 0.5)
    assert nlp_fingerprint(solver(1.0), (lbw, ubw), 0.5) == base
    assert nlp_fingerprint(solver(float(np.nextafter(1.0, 2.0))), (lbw, ubw), 0.5) != base
    assert nlp_fingerprint(solver(1.0), (lbw, ubw, np.zeros(1), np.zeros(1)), 0.5) != base  # bounds count
    points = sample_points(lbw, np.array([1.0, 1.0, np.inf]))
    assert points.shape == (4, 3) and np.all(np.abs(points) <= 4.0)
    assert function_fingerprint([lambda v, a: v * a], points, 0.5) != function_fingerprint([lambda v, a: v * a], points, 0.25)


def test_one_ulp_in_the_dynamics_changes_the_fingerprint(heavier_moon):
    before = get_problem("cr3bp").make_local_solver(OPTIONS).fingerprint(0.5)
    heavier_moon()
    after = get_problem("cr3bp").make_local_solver(OPTIONS).fingerprint(0.5)
    assert after != before


def _small_reference(path, alpha=0.5, n=2):
    """A reference directory of ``n`` real solves (starts, config, provenance with its identity), as
    ``amorgs reference-export`` writes one."""
    from amorgs.data.library import sha256_file
    from amorgs.reference import starts_identity
    from amorgs.solvers.multistart import run_multistart

    path.mkdir()
    (path / "config.yaml").write_text("problems:\n  cr3bp:\n    solver:\n      compile: none\n      max_iter: 40\n"
                                     "ablation:\n  iteration_caps: [20, 40]\n")
    table = run_multistart(get_problem("cr3bp"), alpha, 7, n, options=IpoptOptions(**OPTIONS), progress=False)
    starts = table.assign(sampler="uniform", model_seed=0)
    starts.to_parquet(path / "starts.parquet")
    identity = {"commit": "0" * 40, **starts_identity(starts)}
    (path / "provenance.json").write_text(json.dumps({
        "config_file": "config.yaml", "config_sha256": sha256_file(path / "config.yaml"), "config_hash": "x",
        "git_commit": "0" * 40, "files": [], "identity": identity}))
    return identity


def test_certification_refuses_in_one_line_when_the_code_moved_one_ulp(tmp_path, heavier_moon):
    from amorgs.certification import certify_reference
    from amorgs.errors import InputError

    ref = tmp_path / "ref"
    identity = _small_reference(ref)
    assert set(identity["nlp_fingerprints"]) == {"0.5"}
    cert = certify_reference(ref, sample=2, seed=0)
    assert cert["exact"] and cert["matched"] == 2 and cert["route"] == "today"

    heavier_moon()
    with pytest.raises(InputError, match=r"made by the code of commit 000000000000 \(α = 0\.5: \w{12} ≠ \w{12}.*"
                                         r"this code cannot reproduce it") as err:
        certify_reference(ref, sample=2, seed=0)
    assert "\n" not in str(err.value)


def test_starts_of_two_codes_at_one_alpha_have_no_identity():
    from amorgs.errors import InputError
    from amorgs.reference import starts_identity

    starts = pd.DataFrame({"alpha": [0.5, 0.5, 0.6], "options_hash": ["h"] * 3, "nlp_fingerprint": ["a", "b", "c"]})
    with pytest.raises(InputError, match=r"α = 0\.5 were solved by 2 codes"):
        starts_identity(starts)
    assert starts_identity(starts.iloc[1:])["nlp_fingerprints"] == {"0.5": "b", "0.6": "c"}


def test_export_needs_a_clean_tree_and_a_reachable_commit(tmp_path, monkeypatch):
    from amorgs.certification import check_exportable
    from amorgs.errors import InputError

    def git(*args, cwd=tmp_path):
        subprocess.run(["git", "-c", "user.name=t", "-c", "user.email=t@t", *args], cwd=cwd, check=True,
                       capture_output=True)

    git("init", "-q", "-b", "main")
    (tmp_path / "a.txt").write_text("1")
    git("add", "a.txt")
    git("commit", "-qm", "one")
    monkeypatch.chdir(tmp_path)
    assert len(check_exportable(tmp_path)["git_commit"]) == 40
    (tmp_path / "a.txt").write_text("2")
    with pytest.raises(InputError, match=r"uncommitted changes \(a\.txt\)"):
        check_exportable(tmp_path)
    git("checkout", "-q", "a.txt")
    git("checkout", "-q", "-b", "side")
    git("commit", "-q", "--allow-empty", "-m", "side")
    run = tmp_path.parent / f"{tmp_path.name}-run"
    git("checkout", "-q", "main")
    git("worktree", "add", "-q", str(run), "side")
    with pytest.raises(InputError, match=r"not reachable from HEAD"):
        check_exportable(run)
    nogit = tmp_path.parent / f"{tmp_path.name}-nogit"
    nogit.mkdir(exist_ok=True)
    with pytest.raises(InputError, match=r"not a git checkout"):
        check_exportable(nogit)


def test_the_certify_command_names_what_is_missing():
    out = subprocess.run([sys.executable, "-m", "amorgs", "reference-certify"], capture_output=True, text=True)
    assert out.returncode != 0 and "name a reference directory, or --all" in out.stderr
    out = subprocess.run([sys.executable, "-m", "amorgs", "reference-certify", "x", "--record"], capture_output=True,
                         text=True)
    assert out.returncode != 0 and "--record: only with --at-commit" in out.stderr
    out = subprocess.run([sys.executable, "-m", "amorgs", "reference-certify", "x", "--blas-core", "Haswell"],
                         capture_output=True, text=True)
    assert out.returncode != 0 and "--blas-core: only with --at-commit" in out.stderr


#: A child that prints the fingerprint of the default CR3BP NLP at α = 0.3 and its numpy's BLAS kernel set.
_FINGERPRINT_CHILD = """
from amorgs.problems import get_problem
from amorgs.solvers.fingerprint import blas_core
print(get_problem("cr3bp").make_local_solver({"compile": "none"}).fingerprint(0.3), blas_core())
"""


def test_the_nlp_has_the_same_bits_under_every_blas_kernel_set():
    """numpy's OpenBLAS picks its kernels from the CPU (or ``$OPENBLAS_CORETYPE``); the coast flow the NLP is built
    from once read it (scipy's DOP853), so two machines built other NLPs.  Now the NLP's constants come from the C
    RK8 kernel: the fingerprint is the same under two forced kernel sets, in fresh processes."""
    from amorgs.checkout import BLAS_CORE_FLAGS, check_blas_core
    from amorgs.errors import InputError

    cores = [c for c in ("Prescott", "Sandybridge", "Haswell", "SkylakeX") if _runs(check_blas_core, c)]
    assert len(cores) >= 2, "this CPU runs fewer than two of OpenBLAS's kernel sets"
    seen = {}
    for core in cores[-2:]:
        env = {**__import__("os").environ, "OPENBLAS_CORETYPE": core}
        out = subprocess.run([sys.executable, "-c", _FINGERPRINT_CHILD], capture_output=True, text=True, env=env)
        assert out.returncode == 0, out.stderr[-500:]
        fingerprint, active = out.stdout.split()
        assert active == core  # the kernel set was forced
        seen[core] = fingerprint
    assert len(set(seen.values())) == 1, seen
    with pytest.raises(InputError, match="unknown"):
        check_blas_core("Pentium4-but-faster")
    assert all(set(flags) for flags in BLAS_CORE_FLAGS.values())


def _runs(check, core: str) -> bool:
    from amorgs.errors import InputError

    try:
        check(core)
    except InputError:
        return False
    return True


def test_a_commit_runs_with_its_kernel_set_and_its_own_compile_cache(tmp_path, monkeypatch):
    """The at-commit route forces the recorded kernel set and gives each (commit, kernel set) its own compile
    cache: code before 2026-12-03 keyed compiled NLPs without their constants."""
    from amorgs.checkout import environment_at

    tree = tmp_path / "0123456789ab"
    env = environment_at(tree, "Prescott", tmp_path / "cache")
    assert env["OPENBLAS_CORETYPE"] == "Prescott" and env["AMORGS_CACHE_DIR"] == str(tmp_path / "cache")
    assert env["PYTHONPATH"].split(":")[0] == str(tree / "src")
    monkeypatch.delenv("OPENBLAS_CORETYPE", raising=False)
    monkeypatch.delenv("AMORGS_CACHE_DIR", raising=False)
    plain = environment_at(tree)
    assert "OPENBLAS_CORETYPE" not in plain and "AMORGS_CACHE_DIR" not in plain
