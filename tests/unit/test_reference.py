"""The committed reference results (reference/study/, reference/study-paper/): every file matches its
manifest, and the manifest describes a complete run of the shipped config it names — the shipped file (overrides
of the typed defaults) has the effective config of the file the run read (``config.yaml``, verbatim)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from amorgs.config import load_config
from amorgs.reference import verify_reference

ROOT = Path(__file__).resolve().parents[2]
#: Each committed reference result and the config that made it.
REFERENCES = {"study": "config/study.yaml", "study-paper": "config/study-paper.yaml"}


@pytest.mark.parametrize("name", REFERENCES)
def test_committed_reference_matches_its_manifest_and_config(name):
    config_file = REFERENCES[name]
    manifest = verify_reference(ROOT / "reference" / name)  # config.yaml included: the file as the run read it
    assert manifest["config_file"] == config_file
    ran = load_config(ROOT / "reference" / name / "config.yaml")
    assert load_config(ROOT / config_file) == ran, (
        f"{config_file} (merged over today's defaults) is no longer the config reference/{name} ran: rerun it and "
        "re-export")
    files = {f["file"] for f in manifest["files"]}
    assert {"tables/ablation_ert.md", "tables/ablation_rates.md", "tables/ablation_seeds.md",
            "cr3bp/ablation/summary.json"} <= files
    cfg = ran
    cells = [t for t in manifest["solve_tables"] if t["file"].startswith("cr3bp/ablation/")]
    n_arms, n_alphas = len(cfg.ablation.samplers), len(cfg.problems.cr3bp.alphas.test)
    assert sum(t["rows"] for t in cells if "/fraction=" not in t["file"]) >= n_arms * n_alphas * 200
    assert manifest["cpu_hours"]["total"] > 0


@pytest.mark.parametrize("name", REFERENCES)
def test_committed_readme_names_the_reference_as_the_repository_sees_it(name):
    readme = (ROOT / "reference" / name / "README.md").read_text()
    assert f"--dest reference/{name} --check" in readme and str(ROOT) not in readme


def test_dest_is_shown_relative_to_the_run_when_inside_it(tmp_path):
    from amorgs.reference import _shown

    assert _shown(tmp_path / "reference" / "x", tmp_path) == Path("reference/x")
    assert _shown(tmp_path / "elsewhere", tmp_path / "run") == tmp_path / "elsewhere"


def test_a_reference_config_copy_that_differs_is_named(tmp_path):
    import shutil

    from amorgs.errors import InputError

    ref = tmp_path / "study"
    shutil.copytree(ROOT / "reference" / "study", ref)
    (ref / "config.yaml").write_text((ref / "config.yaml").read_text() + "\n# edited\n")
    with pytest.raises(InputError, match=r"config\.yaml: differs from the config_sha256"):
        verify_reference(ref)
    (ref / "config.yaml").unlink()
    with pytest.raises(InputError, match=r"config\.yaml: missing"):
        verify_reference(ref)


def test_certificate_compares_iterations_status_and_m_f_exactly():
    import numpy as np
    import pandas as pd

    from amorgs.certification import compare_resolves
    from amorgs.solvers.record import SolveRecord

    names = ("tau_s", "tau_i", "tau_f", "m_f")
    rows = pd.DataFrame({"sampler": ["uniform"] * 4, "alpha": [0.5] * 4, "seed": [1] * 4, "start": range(4),
                         "status": ["Solve_Succeeded"] * 3 + ["timeout"], "iterations": [40, 41, 42, 0],
                         "m_f": [420.0, 421.0, 422.0, np.nan]})

    def record(status, iterations, m_f):
        return SolveRecord(status=status, converged=True, solver_success=True, x=np.array([1.0, 2.0, 3.0, m_f]),
                           iterations=iterations)

    again = [record("Solve_Succeeded", 40, 420.0), record("Solve_Succeeded", 43, 421.0),
             record("Solve_Succeeded", 42, np.nextafter(422.0, 500.0)), record("timeout", 0, np.nan)]
    table = compare_resolves(rows, again, names)
    assert table["exact"].tolist() == [True, False, False, True]  # one more iteration; m_f one ulp off
    assert table["iterations_again"].tolist() == [40, 43, 42, 0]


def test_a_reference_without_starts_cannot_be_certified_and_says_so():
    from amorgs.errors import InputError
    from amorgs.certification import certify_reference

    with pytest.raises(InputError, match=r"reference/study/starts\.parquet: this reference has no per-start table"):
        certify_reference(ROOT / "reference" / "study", sample=1)


FRONTIER = ROOT / "reference" / "frontier"
#: The committed frontier folds (reference-export --starts-only of each fold's run).
FOLDS = sorted(p.name for p in FRONTIER.iterdir() if (p / "starts.parquet").is_file()) if FRONTIER.is_dir() else []


def _without_library_path(mapping: dict) -> dict:
    mapping["problems"]["cr3bp"]["library"].pop("path")  # absolute, where the fold ran
    return mapping


def test_the_committed_frontier_is_recomputed_from_its_folds_starts_and_the_shipped_base_config(tmp_path, monkeypatch):
    """Each committed fold is the fold `amorgs frontier-plan` writes today from config/frontier.yaml (but for where
    the library lay), its files match its manifest, and the committed frontier table is exactly what the
    aggregation computes from the folds' starts."""
    import pandas as pd

    from amorgs.ablation.frontier import frontier_table
    from amorgs.config import effective_mapping, read_yaml
    from amorgs.frontier import plan, read_run

    assert FOLDS, "reference/frontier holds no fold"
    monkeypatch.chdir(ROOT)
    sparse = tuple(int(name.removeprefix("sparse-")) for name in FOLDS if name.startswith("sparse-"))
    loo = tuple(float(name.removeprefix("loo-")) for name in FOLDS if name.startswith("loo-"))
    planned = {fold.name: run for fold, run in plan("config/frontier.yaml", tmp_path, loo=loo, sparse=sparse)}
    assert sorted(planned) == FOLDS
    for name, run in planned.items():
        shipped = _without_library_path(effective_mapping(read_yaml(run / "config.yaml")))
        ran = _without_library_path(effective_mapping(read_yaml(FRONTIER / name / "config.yaml")))
        assert shipped == ran, f"config/frontier.yaml no longer plans the fold reference/frontier/{name} ran"
    table = frontier_table([read_run(FRONTIER / name) for name in FOLDS])  # verifies each fold's manifest
    committed = pd.read_csv(FRONTIER / "frontier.csv")
    pd.testing.assert_frame_equal(table, committed, check_dtype=False, rtol=1e-12)


def selector_folds() -> list[Path]:
    """The committed folds of the transfer selector (issue 38): the pilot, then every fold, by name."""
    folds = sorted(p for p in (ROOT / "reference" / "selector-folds").iterdir() if (p / "starts.parquet").is_file())
    return [ROOT / "reference" / "selector-pilot", *folds]


def test_the_committed_selector_frontier_is_recomputed_from_its_folds_starts():
    """reference/selector-frontier/frontier.csv (what `amorgs design --sampler auto` reads beside the five arms'
    frontier) is exactly the aggregation of the committed selector folds' starts, with the oracle bound."""
    import pandas as pd

    from amorgs.ablation.frontier import frontier_table
    from amorgs.frontier import read_run

    table = frontier_table([read_run(p) for p in selector_folds()])
    committed = pd.read_csv(ROOT / "reference" / "selector-frontier" / "frontier.csv")
    pd.testing.assert_frame_equal(table, committed, check_dtype=False, rtol=1e-12)
    reuse = table[(table["sampler"] == "nearest_alpha") & (table["unit"] == "iterations")]
    assert ((reuse["oracle_to_reuse"] > 0) & (reuse["oracle_to_reuse"] <= 1)).all()


def _run_with_arms(tmp_path, base: Path, arms_from: dict[str, str], tamper: bool = False) -> Path:
    """A run directory of ``base``'s design with ``nearest_alpha_perturbed`` added to its samplers, holding only the cell
    tables of the arms in ``arms_from`` (arm → the committed arm whose starts it copies), and the library
    manifest ``base`` read (a stand-in file whose SHA-256 the copied reference is told)."""
    import json

    import pandas as pd
    import yaml

    run = tmp_path / "run"
    cfg = yaml.safe_load((base / "config.yaml").read_text())
    cfg["ablation"]["samplers"] = [*cfg["ablation"]["samplers"], "nearest_alpha_perturbed"]
    (run / "data" / "library" / "cr3bp").mkdir(parents=True)
    (run / "config.yaml").write_text(yaml.safe_dump(cfg, sort_keys=False))
    manifest = run / "data" / "library" / "cr3bp" / "provenance.json"
    manifest.write_text(json.dumps({"totals": {"rows": 1, "converged": 1, "cpu_hours": 0.0}}))
    from amorgs.data.library import sha256_file

    prov = json.loads((base / "provenance.json").read_text())
    prov["library"]["manifest_sha256"] = sha256_file(manifest)
    (base / "provenance.json").write_text(json.dumps(prov))
    starts = pd.read_parquet(base / "starts.parquet")
    for arm, source in arms_from.items():
        for cell, rows in starts[starts["sampler"] == source].groupby("cell", sort=False):
            table = rows.drop(columns="cell").assign(sampler=arm).reset_index(drop=True)
            if tamper and arm == source:
                table.loc[0, "iterations"] += 1
            path = run / "results" / cell.replace(f"/{source}.parquet", f"/{arm}.parquet")
            path.parent.mkdir(parents=True, exist_ok=True)
            table.to_parquet(path)
    return run


def test_add_arms_keeps_the_committed_arms_and_checks_the_rerun_ones(tmp_path):
    """``reference-export --add-arms``: a run of the fold's design that ran only the cells of a new arm and of
    reuse (the check) adds the new arm; reuse must reproduce exactly, else nothing is written."""
    import shutil

    import pandas as pd

    from amorgs.errors import InputError
    from amorgs.frontier import read_run
    from amorgs.reference import add_arms_to_reference

    new = "nearest_alpha_perturbed"  # stands in for a new arm: its cells are copies of reuse's
    base = tmp_path / "sparse-3"
    shutil.copytree(FRONTIER / "sparse-3", base)
    before = pd.read_parquet(base / "starts.parquet")
    held = list(dict.fromkeys(before["sampler"]))
    run = _run_with_arms(tmp_path, base, {"nearest_alpha": "nearest_alpha", new: "nearest_alpha"}, tamper=True)
    with pytest.raises(InputError, match="rerun of 'nearest_alpha' does not reproduce"):
        add_arms_to_reference(base, [new, "nearest_alpha"], "config.yaml", run)
    pd.testing.assert_frame_equal(pd.read_parquet(base / "starts.parquet"), before)  # nothing written

    shutil.rmtree(run)
    run = _run_with_arms(tmp_path, base, {"nearest_alpha": "nearest_alpha", new: "nearest_alpha"})
    manifest = add_arms_to_reference(base, [new, "nearest_alpha"], "config.yaml", run)
    assert manifest["reproduced"] == {"nearest_alpha": int((before["sampler"] == "nearest_alpha").sum())}
    assert manifest["earlier_run"]["arms"] == [a for a in held if a != "nearest_alpha"]
    after = pd.read_parquet(base / "starts.parquet")
    assert len(after) == len(before) + (before["sampler"] == "nearest_alpha").sum()
    kept = after[after["sampler"] != new].sort_values(["cell", "start"]).reset_index(drop=True)  # timings too
    pd.testing.assert_frame_equal(kept, before.sort_values(["cell", "start"]).reset_index(drop=True))
    fold = read_run(base)  # the frontier reads it: every cell of every arm, the manifest verified
    assert set(fold.cells["sampler"]) == {*held, new}
    readme = (base / "README.md").read_text()
    assert f"arms {new}, nearest_alpha from this run" in readme and "from the earlier run" in readme
    with pytest.raises(InputError, match="not the design"):
        (run / "config.yaml").write_text((run / "config.yaml").read_text().replace("n_starts: 34", "n_starts: 35"))
        add_arms_to_reference(base, [new], "config.yaml", run)


@pytest.mark.parametrize("args, said", [
    (["reference-certify", "reference/frontier/loo-0.100", "--sample", "0"], "--sample 0: certify at least 1 start"),
    (["reference-certify", "reference/frontier/loo-0.100", "--workers", "0"], "--workers 0: at least 1 solver process"),
    (["frontier", "reference/frontier/loo-0.100", "--n-boot", "0", "--no-mlflow"],
     "--n-boot 0: a 95 % interval needs at least 100 bootstrap resamples"),
    (["frontier", "reference/frontier/loo-0.100", "--reuse", "bogus", "--no-mlflow"], "--reuse bogus: not an arm (arms: "),
    (["frontier", "reference/frontier/loo-0.100", "--learned", "amorgs", "bogus", "--no-mlflow"],
     "--learned bogus: not an arm (arms: "),
    (["frontier", "reference/frontier/loo-0.100", "--no-mlflow", "--dest", "/proc/fr"], "--dest /proc/fr: cannot write there"),
    (["reference-certify", "reference/frontier/loo-0.100", "--output", "/proc/x/c.json"],
     "--output /proc/x/c.json: cannot write there"),
    (["reference-certify"], "name a reference directory, or --all"),
])
def test_certify_and_frontier_refuse_bad_counts_in_one_line_before_any_work(tmp_path, args, said):
    if not (FRONTIER / "loo-0.100").is_dir():
        pytest.skip("the committed frontier fold loo-0.100 is absent")
    dest = ["--dest", str(tmp_path / "f")] if args[0] == "frontier" and "--dest" not in args else []
    out = subprocess.run([sys.executable, "-m", "amorgs", *args, *dest],
                         cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert out.returncode != 0 and "Traceback" not in out.stderr
    assert out.stderr.strip().startswith(f"amorgs {args[0]}: {said}") and len(out.stderr.strip().splitlines()) == 1
    assert not (tmp_path / "f").exists()


def test_every_committed_reference_has_a_certification_route():
    """reference/certification.json names every committed reference (a directory with provenance.json) and only
    those; a `commit` route names a commit of this repository with the fingerprints it gave; a `historical` one
    says why.  The certificates themselves run in CI (`amorgs reference-certify --all`, .ci/run)."""
    import json

    from amorgs.certification import REGISTRY, references_under

    registry = json.loads((ROOT / REGISTRY).read_text())["references"]
    committed = {p.relative_to(ROOT / "reference").as_posix() for p in references_under(ROOT / "reference")}
    assert set(registry) == committed
    for name, entry in registry.items():
        assert entry["route"] in ("today", "commit", "historical"), name
        if entry["route"] == "historical":
            assert entry["why"], name
            continue
        starts = __import__("pandas").read_parquet(ROOT / "reference" / name / "starts.parquet")
        assert set(entry["nlp_fingerprints"]) == {f"{a:g}" for a in starts["alpha"].unique()}, name
        assert set(starts["options_hash"]) == {entry["options_hash"]}, name
        has_history = subprocess.run(["git", "cat-file", "-e", f"{entry['commit']}^{{commit}}"], cwd=ROOT,
                                     capture_output=True).returncode == 0
        shallow = subprocess.run(["git", "rev-parse", "--is-shallow-repository"], cwd=ROOT, capture_output=True,
                                 text=True).stdout.strip() == "true"
        assert has_history or shallow, f"{name}: commit {entry['commit']} is not in the repository"


def test_the_readme_lead_says_what_the_committed_frontier_says():
    """The README's lead paragraph, claim by claim, against reference/frontier/frontier.csv (iterations per
    high-quality solution, 95 % intervals): how many points each learned arm is significantly slower than reuse,
    their ratio range, that none is significantly faster, and the widest gap's point ratios."""
    import re

    import pandas as pd

    lead = (ROOT / "README.md").read_text().split("## Quick start")[0]
    lead = re.sub(r"\s+", " ", lead)
    table = pd.read_csv(FRONTIER / "frontier.csv")
    ratios = table[table["ratio_to_reuse"].notna() & (table["unit"] == "iterations")
                   & (table["target"] == "high_quality")]
    assert ratios["run"].nunique() == 6 and len(ratios[ratios["sampler"] == "amorgs"]) == 10
    assert not (ratios["ratio_to_reuse_ci95_high"] < 1).any()  # "no learned sampler is significantly faster"
    assert "no learned sampler we built is significantly faster than reusing" in lead
    for arm, words in {"amorgs": "AmorGS at", "continuation": "secant continuation at",
                       "reuse_cvae": "reuse-conditioned CVAE (which corrects each retrieved solution to the target α) at"}.items():
        slower = ratios[(ratios["sampler"] == arm) & (ratios["ratio_to_reuse_ci95_low"] > 1)]["ratio_to_reuse"]
        claim = f"{words} {len(slower)}" + (" of the 10 points" if arm == "amorgs" else "")
        assert claim in lead, claim
        assert f"({slower.min():.1f}–{slower.max():.1f}×" in lead, (arm, slower.min(), slower.max())
    widest = ratios[ratios["gap_relative"] == ratios["gap_relative"].max()].set_index("sampler")
    assert (widest["ratio_to_reuse"] < 1).all()
    for arm, name in {"amorgs": "AmorGS", "continuation": "continuation", "reuse_cvae": "reuse-conditioned CVAE"}.items():
        r = widest.loc[arm]
        assert (f"{name} {r.ratio_to_reuse:.2f}, " in lead or f"{name} {r.ratio_to_reuse:.2f}, 95 % " in lead
                ), (name, r.ratio_to_reuse)
        assert f"{r.ratio_to_reuse_ci95_low:.2f}–{r.ratio_to_reuse_ci95_high:.2f}" in lead, arm


def test_two_references_whose_folders_share_a_name_keep_their_own_certificates(tmp_path):
    """The default certificate is named by the reference's path under reference/ (``/`` as ``--``): the
    leave-one-α-out and the sparse-3 global-search studies at α = 0.3, both folders ``alpha=0.300``, do not
    overwrite each other's certificate."""
    import json

    names = ["global-search/alpha=0.300", "global-search/sparse-3/alpha=0.300"]
    for name in names:
        if not (ROOT / "reference" / name).is_dir():
            pytest.skip(f"the committed reference {name} is absent")
        out = subprocess.run([sys.executable, "-m", "amorgs", "reference-certify", str(ROOT / "reference" / name),
                              "--sample", "1"], cwd=tmp_path, capture_output=True, text=True, timeout=300)
        assert out.returncode == 0, out.stdout + out.stderr
    made = sorted(p.name for p in (tmp_path / "results" / "certificates").iterdir())
    assert made == ["global-search--alpha=0.300-seed0.json", "global-search--sparse-3--alpha=0.300-seed0.json"]
    for name, file in zip(names, made):
        assert json.loads((tmp_path / "results" / "certificates" / file).read_text())["exact"], name


def test_a_reference_pinned_to_kernels_this_cpu_lacks_is_skipped_only_when_asked(tmp_path, monkeypatch):
    """``reference-certify --all``: a ``commit`` route pinned to a BLAS kernel set this CPU cannot run fails (it
    cannot be certified here), and with ``--skip-unsupported-cpu`` is reported as not checked, saying why — no
    re-solve is tried either way; a reference of today's route is still certified."""
    import json

    from amorgs import certification
    from amorgs.errors import InputError

    subprocess.run(["git", "init", "-q", str(tmp_path)], check=True)
    for name in ("old", "new"):
        (tmp_path / "reference" / name).mkdir(parents=True)
        (tmp_path / "reference" / name / "provenance.json").write_text("{}")
    registry = {"format": 1, "references": {"old": {"route": "commit", "blas_core": "SkylakeX", "commit": "0" * 40},
                                             "new": {"route": "today"}}}
    (tmp_path / "reference" / "certification.json").write_text(json.dumps(registry))

    def lacks(core):
        raise InputError(f"BLAS kernel set {core}: this CPU lacks avx512f, which it needs — certify on a CPU that "
                         "has them")

    def certify(dest, *args, at_commit=None, **kwargs):
        assert Path(dest).name == "new" and at_commit is None, dest  # the pinned one is never re-solved
        return {"exact": True, "matched": 3, "sample": 3, "code_commit": "1" * 40}

    monkeypatch.setattr(certification, "check_blas_core", lacks)
    monkeypatch.setattr(certification, "certify_reference", certify)
    strict = {r["reference"]: r for r in certification.certify_all(tmp_path)}
    assert not strict["old"]["ok"] and "this CPU lacks avx512f" in strict["old"]["line"] and strict["new"]["ok"]
    lenient = {r["reference"]: r for r in certification.certify_all(tmp_path, skip_unsupported_cpu=True)}
    assert lenient["old"]["ok"] and lenient["old"]["skipped"] and lenient["new"]["ok"]
    assert lenient["old"]["line"].startswith("not checked on this CPU: BLAS kernel set SkylakeX")
