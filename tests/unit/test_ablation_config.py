"""The issue-11 parts of the config: the arm registry, iteration caps, model seeds, config/study.yaml, layout."""

from __future__ import annotations

from pathlib import Path

import pytest
from config_files import load, mapping, write

from amorgs import config as C
from amorgs import layout, steps
from amorgs.ablation.arms import DEFAULT_SAMPLER_NAMES, SAMPLER_NAMES
from amorgs.ablation.studies import table_files

#: The committed study's arms (reference/study*): every arm of its time (the arms of issues 21, 38 and 41 came later).
STUDY_ARMS = tuple(name for name in SAMPLER_NAMES
                   if name not in ("continuation", "reuse_cvae", "selector", "selector_sampled", "amorgs_selected"))


def test_default_and_smoke_run_every_arm_small():
    for name, starts, arms in (("default", 24, DEFAULT_SAMPLER_NAMES), ("smoke", 2, SAMPLER_NAMES)):
        cfg = load(name)  # the default runs every arm but the selector, which needs the transfer data
        assert set(cfg.ablation.samplers) == set(arms) and cfg.ablation.n_starts == starts
        assert all(c <= cfg.problems.cr3bp.solver.max_iter for c in cfg.ablation.iteration_caps)


def test_study_config_size(tmp_path):
    cfg = load("study")
    assert set(cfg.ablation.samplers) == set(STUDY_ARMS)
    assert len(cfg.cr3bp_models.seeds) >= 3
    # the paper's widths: the override the study's header documents validates
    paper = mapping("study")
    paper["cr3bp_models"].update(preset="paper", learning_rate=1.0e-3, epochs=1000)
    assert C.load_config(write(tmp_path, paper, "study-paper.yaml")).cr3bp_models.preset == "paper"
    assert cfg.ablation.n_starts * len(cfg.cr3bp_models.seeds) >= 200
    cells = steps.outputs_of("ablation_cell", cfg, "table") + steps.outputs_of("ablation_cell_replicate", cfg, "table")
    assert len(cells) == len(cfg.cr3bp_models.seeds) * len(cfg.problems.cr3bp.alphas.test) * len(STUDY_ARMS)
    assert "results/cr3bp/ablation/seed=12/alpha=0.150/gmm_lstm.parquet" in cells
    models = steps.outputs_of("train_cr3bp_replicate", cfg, "model")
    assert "results/cr3bp/models/seed=13/lstm.pt" in models and len(models) == 2 * 3
    targets = steps.targets(cfg)
    assert set(models) <= set(targets)
    assert {"results/tables/ablation_ert.md", "results/figures/ablation_anytime.png"} <= set(targets)


def test_replicate_jobs_are_expected():
    cfg = load("study")
    jobs = steps.expected_jobs(cfg)
    rep = [w for rule, w in jobs if rule == "ablation_cell_replicate"]
    assert len(rep) == 2 * 2 * len(STUDY_ARMS)
    assert {"alpha": "0.850", "sampler": "nearest_alpha", "mseed": "13"} in rep
    trained = [w for rule, w in jobs if rule == "train_cr3bp_replicate"]
    assert {"model": "lstm", "mseed": "12"} in trained and len(trained) == 2 * 3


def test_reuse_replicates_are_slices_of_one_draw():
    """The model seeds' cells of a reuse arm share one seed and take consecutive slices (issue 21); a learned
    arm's replicates have their own seeds."""
    cfg = load("study")
    rule = steps.registry()["ablation_cell_replicate"]
    main = steps.registry()["ablation_cell"].settings(cfg, {"alpha": "0.150", "sampler": "nearest_alpha"})
    reps = [rule.settings(cfg, {"alpha": "0.150", "sampler": "nearest_alpha", "mseed": str(m)})
            for m in cfg.cr3bp_models.extra_seeds]
    assert {c.seed for c in reps} == {main.seed} and main.start_offset == 0
    assert [c.start_offset for c in reps] == [cfg.ablation.n_starts * (k + 1) for k in range(len(reps))]
    learned = [rule.settings(cfg, {"alpha": "0.150", "sampler": "amorgs", "mseed": str(m)})
               for m in cfg.cr3bp_models.extra_seeds]
    assert len({c.seed for c in learned}) == len(learned) and {c.start_offset for c in learned} == {0}


def test_iteration_caps_may_not_exceed_max_iter(tmp_path):
    data = mapping()
    data["ablation"]["iteration_caps"] = [10, 60]  # smoke max_iter = 50
    with pytest.raises(C.ConfigError, match=r"iteration_caps \[60\] exceed problems\.cr3bp\.solver\.max_iter = 50"):
        C.load_config(write(tmp_path, data))


def test_baselines_without_models(tmp_path):
    data = mapping()
    data["cr3bp_models"]["enabled"] = False
    data["ablation"]["samplers"] = ["uniform", "nearest_alpha", "nearest_alpha_perturbed"]
    cfg = C.load_config(write(tmp_path, data))  # the reuse baselines need no model
    assert cfg.ablation.samplers[1] == "nearest_alpha"
    data["ablation"]["samplers"] = ["uniform", "gmm_lstm"]
    with pytest.raises(C.ConfigError, match=r"\['gmm_lstm'\] need cr3bp_models\.enabled"):
        C.load_config(write(tmp_path, data))
    data["ablation"]["perturbation_scale"] = -0.1
    with pytest.raises(C.ConfigError, match="perturbation_scale"):
        C.load_config(write(tmp_path, data))


def test_figures_do_not_import_torch():
    import subprocess
    import sys

    code = "import sys, amorgs.figures.ablation, amorgs.ablation.report; print('torch' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"


def test_check_outputs_inspects_the_new_ablation_outputs(tmp_path, monkeypatch):
    import json

    import pandas as pd

    from amorgs.checks import _check_file

    monkeypatch.chdir(tmp_path)
    (tmp_path / "results/tables").mkdir(parents=True)
    (tmp_path / "results/cr3bp/ablation").mkdir(parents=True)
    good = "results/tables/ablation_ert.csv"
    pd.DataFrame({"alpha": [0.15], "sampler": ["uniform"], "aRT": [1.0]}).to_csv(good, index=False)
    assert _check_file(good) is None
    bad = "results/tables/ablation_rates.csv"
    pd.DataFrame({"x": [1]}).to_csv(bad, index=False)
    assert "lacks column(s) ['alpha', 'sampler']" in _check_file(bad)
    Path(layout.ABLATION_SUMMARY).write_text(json.dumps({"percent_hq/alpha_0.150/uniform": 50.0}))
    assert "aRT_iterations/" in _check_file(layout.ABLATION_SUMMARY)
    Path(layout.ABLATION_SUMMARY).write_text(json.dumps({"aRT_iterations/alpha_0.150/uniform": 50.0}))
    assert _check_file(layout.ABLATION_SUMMARY) is None


def test_ablation_report_step_writes_every_declared_output(tmp_path, monkeypatch):
    """The ablation_report step, with the issue-11 settings, writes every table and figure the step declares."""
    import json

    import numpy as np
    import pandas as pd

    cfg = load("smoke")
    monkeypatch.chdir(tmp_path)  # no results/mlflow here: tracking is a no-op
    rng = np.random.default_rng(0)
    cells = []
    for alpha in (0.15, 0.85):
        for k, sampler in enumerate(("uniform", "nearest_alpha", "amorgs")):
            n = 8
            hq = rng.random(n) < 0.3 + 0.3 * k
            cells.append(pd.DataFrame({
                "problem": "cr3bp", "alpha": alpha, "sampler": sampler, "seed": 1, "start": np.arange(n),
                "converged": hq, "m_f": np.where(hq, rng.uniform(415, 440, n), 300.0),
                "tau_s": rng.uniform(5, 30, n), "tau_i": rng.uniform(1, 10, n), "tau_f": rng.uniform(1, 10, n),
                "guess_tau_s": 10.0, "guess_tau_i": 2.0, "guess_tau_f": 2.0, "guess_m_f": 420.0,
                "iterations": rng.integers(20, 1000, n), "cpu_s": rng.uniform(0.2, 10, n), "wall_s": 1.0,
            }))
            if sampler == "nearest_alpha":  # a reuse cell records the training α it drew from and its pool
                cells[-1] = cells[-1].assign(reuse_alpha=0.16 if alpha == 0.15 else 0.8, reuse_pool_size=5)
    for k, fraction in enumerate((0.1, 0.5)):  # AmorGS with models that saw a fraction of the data
        hq = rng.random(8) < 0.2 + 0.2 * k
        cells.append(cells[2].assign(data_fraction=fraction, converged=hq, m_f=np.where(hq, 430.0, 300.0)))
    paths = []
    for i, c in enumerate(cells):
        paths.append(str(tmp_path / f"cell{i}.parquet"))
        c.to_parquet(paths[-1])
    truth = pd.concat(cells)[lambda d: d["converged"]]
    truth.to_parquet(tmp_path / "hq.parquet")
    t = "results/tables"
    # the data the arms draw on (solves at the training α 0.7–0.9 count, the test α 0.15 does not) and the
    # training reports of the main seed's models
    pd.DataFrame({"alpha": [0.7, 0.8, 0.15], "cpu_s": [1000.0, 800.0, 5000.0]}).to_parquet("a.parquet")
    reports = []
    for model, cpu in (("cvae_gmm", 100.0), ("lstm", 50.0), ("vanilla_cvae", 7.0)):
        reports.append(f"{model}.training.json")
        Path(reports[-1]).write_text(json.dumps({"model": model, "train_cpu_s": cpu}))
    steps.run_step("ablation_report", cfg, {},
                   {"cells": paths, "high_quality": str(tmp_path / "hq.parquet"), "alpha_tables": ["a.parquet"],
                    "training_reports": reports},
                   steps.registry()["ablation_report"].outputs({}))
    even = pd.read_csv(f"{t}/ablation_break_even.csv").set_index(["alpha", "sampler"])
    assert even.loc[(0.15, "amorgs"), "upfront_cpu_h"] == pytest.approx((1800 + 150) / 3600)
    assert even.loc[(0.15, "nearest_alpha"), "upfront_cpu_h"] == pytest.approx(1800 / 3600)
    assert set(even["solutions_wanted"]) == set(cfg.ablation.break_even_solutions)
    curve = pd.read_csv(f"{t}/ablation_learning_curve.csv")
    it = curve[(curve["unit"] == "iterations") & (curve["alpha"] == 0.15)].set_index("data_fraction")
    assert list(it.index) == [0.1, 0.5, 1.0] and set(it["sampler"]) == {"amorgs"}
    assert list(it["n"]) == [8, 8, 8]
    pools = pd.read_csv(f"{t}/ablation_reuse_pool.csv").set_index("alpha")
    assert list(pools["sampler"]) == ["nearest_alpha"] * 2 and (pools["pool_size"] == 5).all()
    assert (pools["starts_with_replacement"] == 3).all() and pools.loc[0.85, "reuse_alpha"] == 0.8
    assert "pool" in Path(f"{t}/ablation_reuse_pool.md").read_text()
    distinct = pd.read_csv(f"{t}/ablation_ert_distinct.csv")
    assert (distinct["k_distinct"] <= distinct["k_high_quality"]).all() and (distinct["eta"] == 0.02).all()
    table6 = pd.read_csv(f"{t}/table6.csv")
    assert (table6["n"] == 8).all()  # the learning-curve cells stay out of the main tables
    for name in table_files():
        assert (tmp_path / t / name).stat().st_size > 0, name
    for name in layout.ABLATION_FIGURES:
        assert (tmp_path / "results/figures" / f"{name}.png").read_bytes().startswith(b"\x89PNG"), name
    summary = json.loads(Path(layout.ABLATION_SUMMARY).read_text())
    assert "aRT_iterations/alpha_0.850/nearest_alpha" in summary and "itcap_percent/alpha_0.150/amorgs/cap_50" in summary
    from amorgs.checks import _check_file

    assert [m for m in (_check_file(f"{t}/{n}") for n in table_files()) if m] == []
