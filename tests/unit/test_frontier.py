"""The frontier (issue 21 §1): the designs' folds, their configs, that a fold's test α never reaches training or
reuse, the aggregation on real solves of the committed library, and its figure."""

from __future__ import annotations

import io
import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml

from amorgs import steps
from amorgs.ablation.frontier import FrontierRun, frontier_metrics, frontier_table, gap, leave_one_out, sparse_grid
from amorgs.ablation.statistics import high_quality
from amorgs.ablation.running_time import art_interval
from amorgs.alphas import alpha_label, rows_at, rows_at_any
from amorgs.config import load_config
from amorgs.errors import ConfigError
from amorgs.frontier import library_alphas, plan

ROOT = Path(__file__).resolve().parents[2]
LIBRARY = ROOT / "data" / "library"
BASE = ROOT / "config" / "frontier.yaml"
BETA = 415.0


@pytest.fixture(scope="module")
def alphas():
    return library_alphas(LIBRARY)


def test_the_library_holds_the_fourteen_alphas(alphas):
    assert alphas == [0.1, 0.13, 0.15, 0.16, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.85, 0.9, 1.0]


def test_leave_one_out_and_sparse_grids(alphas):
    loo = leave_one_out(alphas, 0.5)
    assert loo.name == "loo-0.500" and loo.test == (0.5,) and len(loo.train) == 13 and 0.5 not in loo.train
    with pytest.raises(ValueError, match="not one of the library"):
        leave_one_out(alphas, 0.55)
    three = sparse_grid(alphas, 3)
    assert three.train == (0.1, 0.5, 1.0) and three.test == (0.3, 0.7)  # mid-gaps 0.3 and 0.75 (tie → 0.7)
    five = sparse_grid(alphas, 5)
    assert five.train == (0.1, 0.3, 0.5, 0.8, 1.0) and five.test == (0.2, 0.4, 0.6, 0.9)
    eight = sparse_grid(alphas, 8)
    assert len(eight.train) == 8 and not set(eight.test) & set(eight.train)
    assert all(any(a < t < b for a, b in zip(eight.train, eight.train[1:])) for t in eight.test)
    with pytest.raises(ValueError, match="2 ≤ k"):
        sparse_grid(alphas, 1)
    assert gap(0.5, loo.train) == pytest.approx((0.4, 0.1, 0.2))  # 0.4 and 0.6 tie: the smaller
    assert gap(0.1, leave_one_out(alphas, 0.1).train) == pytest.approx((0.13, 0.03, 0.3))
    assert gap(0.3, three.train) == pytest.approx((0.1, 0.2, 2 / 3))


def test_plan_writes_one_valid_config_per_fold(tmp_path):
    folds = plan(BASE, tmp_path / "runs", loo=(0.5, 1.0), sparse=(3,), sets=("ablation.n_starts=3",))
    assert [f.name for f, _ in folds] == ["loo-0.500", "loo-1.000", "sparse-3"]
    base = load_config(BASE)
    for fold, run in folds:
        cfg = load_config(run / "config.yaml")
        cr3bp = cfg.problems.cr3bp
        assert cr3bp.alphas.train_values() == fold.train and cr3bp.alphas.test == fold.test
        assert Path(cr3bp.library.path).is_absolute() and Path(cr3bp.library.path) == LIBRARY.resolve()
        assert cfg.ablation.n_starts == 3
        # everything else is the base's
        assert cfg.cr3bp_models == base.cr3bp_models and cfg.ablation.samplers == base.ablation.samplers
    with pytest.raises(ConfigError, match="no key ablation.n_start"):
        plan(BASE, tmp_path / "bad", loo=(0.5,), sets=("ablation.n_start=3",))
    with pytest.raises(ConfigError, match="not one of the library"):
        plan(BASE, tmp_path / "bad", loo=(0.55,))
    with pytest.raises(ConfigError, match="ablation.n_starts"):
        plan(BASE, tmp_path / "bad", loo=(0.5,), sets=("ablation.n_starts=0",))


def test_the_base_config_is_the_leave_out_fold_at_half():
    cfg = load_config(BASE)
    assert cfg.problems.cr3bp.alphas.test == (0.5,) and len(cfg.cr3bp_models.seeds) == 3
    assert cfg.ablation.n_starts * len(cfg.cr3bp_models.seeds) >= 100
    assert {"uniform", "nearest_alpha", "amorgs"} <= set(cfg.ablation.samplers)


# ---------------------------------------------------------------- the test α never reaches training or reuse


def test_every_training_and_reuse_job_of_every_fold_sees_only_the_training_alphas(tmp_path):
    """Each job that trains a model or builds a sampler gets its α from the fold's config: the training α only,
    none sharing a label with a test α (and the config refuses a test α that is also a training α)."""
    folds = plan(BASE, tmp_path, loo=(0.1, 0.5, 1.0), sparse=(3, 5))
    for fold, run in folds:
        cfg = load_config(run / "config.yaml")
        test = {alpha_label(a) for a in fold.test}
        seen = 0
        for rule, w in steps.expected_jobs(cfg):
            if rule.startswith(("train_cr3bp", "ablation_cell")) or rule == "ablation_report":
                settings = steps.registry()[rule].settings(cfg, w)
                assert not {alpha_label(a) for a in settings.train_alphas} & test, (fold.name, rule, w)
                seen += 1
        assert seen >= 10
    data = yaml.safe_load((folds[0][1] / "config.yaml").read_text())
    data["problems"]["cr3bp"]["alphas"]["train"].append(0.1)
    with pytest.raises(ConfigError, match="share the label"):
        load_config(_write(tmp_path / "leak.yaml", data))


def _write(path: Path, data: dict) -> Path:
    path.write_text(yaml.safe_dump(data))
    return path


@pytest.fixture(scope="module")
def library_hq():
    """The committed library's high-quality rows at α = 0.4, 0.5, 0.6 (real solves)."""
    from amorgs.data.library import read_library

    df = pd.concat([read_library(LIBRARY, "cr3bp", alpha_label(a)) for a in (0.4, 0.5, 0.6)], ignore_index=True)
    return df[high_quality(df, BETA)].reset_index(drop=True)


def test_a_fold_trains_and_reuses_without_its_test_alpha(tmp_path, monkeypatch, library_hq):
    """The real train step and the reuse sampler of the real ablation_cell settings, on a high-quality table that
    holds the test α's rows: the model is trained on the training α's rows only, and every reused guess is a
    training α's solution, never one of the test α."""
    from amorgs.ablation.arms import build_sampler
    from amorgs.models.samplers import make_valid
    from amorgs.problems import get_problem

    (fold, run), = plan(BASE, tmp_path / "runs", loo=(0.5,), sets=("cr3bp_models.epochs=1",))
    cfg = load_config(run / "config.yaml")
    monkeypatch.chdir(tmp_path)  # no results/mlflow here: tracking is a no-op
    library_hq.to_parquet("hq.parquet")
    train_rows = rows_at_any(library_hq, fold.train)
    assert len(rows_at(library_hq, 0.5)) > 50 and len(train_rows) > 100
    steps.run_step("train_cr3bp", cfg, {"model": "cvae_gmm"}, {"high_quality": "hq.parquet"},
                   {"model": "m/cvae_gmm.pt", "report": "m/cvae_gmm.training.json"})
    assert yaml.safe_load(Path("m/cvae_gmm.training.json").read_text())["rows"] == len(train_rows)

    problem = get_problem("cr3bp")
    names = list(problem.variable_names)
    s = steps.registry()["ablation_cell"].settings(cfg, {"alpha": "0.500", "sampler": "nearest_alpha"})
    sampler = build_sampler("nearest_alpha", problem, None, high_quality=library_hq, train_alphas=s.train_alphas)
    assert sampler.pool(s.alpha)[0] == 0.4
    x = sampler.sample(s.alpha, 400, np.random.default_rng(0))

    def matches(rows):
        ref = make_valid(rows[names].to_numpy(), problem)
        return np.all(np.isclose(x[:, None, :], ref[None, :, :], rtol=0, atol=1e-12), axis=2).any(axis=1)

    assert matches(rows_at(library_hq, 0.4)).all()
    assert not matches(rows_at(library_hq, 0.5)).any()


# ------------------------------------------------------------------------------------------ the aggregation


def _cells(library_hq_all: pd.DataFrame, alpha: float, reuse_alpha: float, n: int = 30) -> pd.DataFrame:
    """Cell tables made of real solves of the library at ``alpha`` (converged or not): three arms of ``n`` starts,
    split over two model seeds, the reuse arm marked with its pool."""
    rows = rows_at(library_hq_all, alpha).reset_index(drop=True)
    parts = []
    for i, arm in enumerate(("uniform", "nearest_alpha", "amorgs")):
        g = rows.iloc[i * n:(i + 1) * n].copy()
        g["sampler"], g["start"] = arm, np.arange(n) % (n // 2)
        g["model_seed"] = np.where(np.arange(n) < n // 2, 11, 12)
        g["reuse_alpha"] = reuse_alpha if arm == "nearest_alpha" else math.nan
        parts.append(g)
    return pd.concat(parts, ignore_index=True)


@pytest.fixture(scope="module")
def library_solves():
    from amorgs.data.library import read_library

    return pd.concat([read_library(LIBRARY, "cr3bp", alpha_label(a)) for a in (0.3, 0.5)], ignore_index=True)


@pytest.fixture(scope="module")
def runs(library_solves, alphas):
    loo = leave_one_out(alphas, 0.5)
    sparse = sparse_grid(alphas, 3)
    return [FrontierRun("loo", loo.name, loo.train, BETA, 0.02, _cells(library_solves, 0.5, 0.4)),
            FrontierRun("sparse-3", "sparse-3", sparse.train, BETA, 0.02, _cells(library_solves, 0.3, 0.1))]


def test_frontier_table_on_real_solves(runs):
    table = frontier_table(runs, n_boot=300, seed=1)
    assert len(table) == 2 * 3 * 2 * 2  # runs × arms × targets × units
    t = table.set_index(["run", "sampler", "target", "unit"])
    for r in runs:
        for arm, g in r.cells.groupby("sampler"):
            k = int(high_quality(g, BETA).sum())
            for unit in ("iterations", "cpu_s"):
                row = t.loc[(r.run, arm, "high_quality", unit)]
                assert row["n"] == 30 and row["model_seeds"] == 2 and row["k_found"] == k
                assert row["aRT"] == pytest.approx(g[unit].sum() / k, rel=1e-12)
                assert row["aRT_ci95_low"] <= row["aRT"] <= row["aRT_ci95_high"]
                hq = high_quality(g, BETA).to_numpy()  # the oracle solves only the starts that succeed
                assert row["aRT_oracle"] == pytest.approx(g[unit].to_numpy()[hq].sum() / k, rel=1e-12)
                assert row["aRT_oracle"] <= row["aRT"]
                reuse_art = t.loc[(r.run, "nearest_alpha", "high_quality", unit), "aRT"]
                assert row["oracle_to_reuse"] == pytest.approx(row["aRT_oracle"] / reuse_art, rel=1e-12)
                distinct = t.loc[(r.run, arm, "distinct", unit)]
                assert 0 < distinct["k_found"] <= k and distinct["aRT"] >= row["aRT"]
                assert distinct["aRT_oracle"] <= distinct["aRT"]
        for target in ("high_quality", "distinct"):
            for unit in ("iterations", "cpu_s"):
                learned, reuse = t.loc[(r.run, "amorgs", target, unit)], t.loc[(r.run, "nearest_alpha", target, unit)]
                assert learned["ratio_to_reuse"] == pytest.approx(learned["aRT"] / reuse["aRT"], rel=1e-12)
                assert learned["ratio_to_reuse_ci95_low"] <= learned["ratio_to_reuse"] <= learned["ratio_to_reuse_ci95_high"]
                assert math.isnan(reuse["ratio_to_reuse"]) and math.isnan(t.loc[(r.run, "uniform", target, unit)]["ratio_to_reuse"])
    loo = table[table["run"] == "loo-0.500"].iloc[0]
    assert (loo["alpha"], loo["nearest_train_alpha"], loo["reuse_alpha"]) == (0.5, 0.4, 0.4)
    assert loo["gap"] == pytest.approx(0.1) and loo["gap_relative"] == pytest.approx(0.2)
    sparse = table[table["run"] == "sparse-3"].iloc[0]
    assert sparse["gap"] == pytest.approx(0.2) and sparse["gap_relative"] == pytest.approx(2 / 3)
    pd.testing.assert_frame_equal(table, frontier_table(runs, n_boot=300, seed=1))  # seeded
    metrics = frontier_metrics(table)
    key = "frontier_ratio/loo-0.500/alpha_0.500/amorgs/iterations"
    assert metrics[key] == pytest.approx(t.loc[("loo-0.500", "amorgs", "high_quality", "iterations"), "ratio_to_reuse"])
    assert "frontier_ratio_ci95_low/sparse-3/alpha_0.300/amorgs/distinct_cpu_s" in metrics
    with pytest.raises(ValueError, match="no cells of \\['amorgs'\\]"):
        frontier_table([FrontierRun("x", "x", (0.4,), BETA, 0.02, runs[0].cells.query("sampler != 'amorgs'"))],
                       learned=("amorgs",))


def test_art_interval_brackets_the_art_and_is_infinite_without_a_find(runs):
    cells = runs[0].cells.copy()
    cells.loc[cells["sampler"] == "uniform", "m_f"] = 0.0  # uniform finds nothing
    iv = art_interval(cells, BETA, n_boot=200, seed=3)
    g = cells[cells["sampler"] == "amorgs"]
    art = g["iterations"].sum() / high_quality(g, BETA).sum()
    assert iv[("amorgs", "iterations")][0] <= art <= iv[("amorgs", "iterations")][1]
    assert iv[("uniform", "cpu_s")] == (math.inf, math.inf)
    assert iv == art_interval(cells, BETA, n_boot=200, seed=3)
    with pytest.raises(ValueError, match="one α"):
        art_interval(pd.concat([cells, runs[1].cells]), BETA)


def test_the_frontier_figure(runs):
    from amorgs.figures.frontier import fig_frontier

    table = frontier_table(runs, n_boot=100, seed=1)
    fig = fig_frontier(table)
    fig.savefig(io.BytesIO(), format="png", dpi=40)
    left, right = fig.axes[:2]
    assert left.get_yscale() == right.get_yscale() == "log"
    assert "relative gap" in right.get_xlabel() and "(N)" in left.get_xlabel()
    assert any(list(line.get_ydata()) == [1.0, 1.0] for line in left.lines)  # the line at 1
    learned = table[(table["sampler"] == "amorgs") & (table["unit"] == "iterations") & (table["target"] == "high_quality")]
    points = [line for line in left.lines if len(line.get_xdata()) == 1 and line.get_marker() != "_"]  # not dodged
    oracle = [line for line in left.lines if line.get_marker() == "_" and len(line.get_xdata())]  # reuse's oracle bound at each test α
    bound = table[(table["sampler"] == "nearest_alpha") & (table["unit"] == "iterations")
                  & (table["target"] == "high_quality")]
    assert sorted(float(o.get_ydata()[0]) for o in oracle) == pytest.approx(sorted(bound["oracle_to_reuse"]))
    assert all(0 < float(o.get_ydata()[0]) <= 1 for o in oracle)
    assert sorted(float(p.get_xdata()[0]) for p in points) == pytest.approx(sorted(learned["gap"]))
    assert left.get_xlim()[0] == 0
    assert {t.get_text() for t in left.texts} == {"0.5", "0.3"}


def test_points_sharing_a_gap_sit_side_by_side_centred_on_it_each_test_alpha_labelled_once():
    from amorgs.figures.frontier import fig_frontier

    rows = [{"design": run.split("-")[0], "run": run, "alpha": a, "gap": 0.1, "gap_relative": 0.1 / a,
             "sampler": arm, "target": "high_quality", "unit": "iterations", "n": 102, "ratio_to_reuse": 1.5,
             "ratio_to_reuse_ci95_low": 1.0, "ratio_to_reuse_ci95_high": 2.0}
            for run, a in (("sparse-5", 0.4), ("sparse-5", 0.6), ("loo-1.000", 1.0))
            for arm in ("amorgs", "continuation")]
    fig = fig_frontier(pd.DataFrame(rows))
    left = fig.axes[0]
    xs = sorted(float(line.get_xdata()[0]) for line in left.lines if len(line.get_xdata()) == 1)
    assert len(xs) == 6 and len(set(xs)) == 6  # six points at one gap, none on top of another
    assert np.mean(xs) == pytest.approx(0.1) and np.diff(xs) == pytest.approx([np.diff(xs)[0]] * 5)
    assert sorted(t.get_text() for t in left.texts) == ["0.4", "0.6", "1"]
    assert all(t.xy[1] == pytest.approx(2.0) for t in left.texts)  # above the whiskers


def _frontier(points):
    """A frontier table of (run, test α, relative gap, arm, ratio, upper end of its interval)."""
    return pd.DataFrame([{"design": run.split("-")[0], "run": run, "alpha": a, "gap_relative": g, "sampler": arm,
                          "target": "high_quality", "unit": "iterations", "ratio_to_reuse": r,
                          "ratio_to_reuse_ci95_low": r / 2, "ratio_to_reuse_ci95_high": hi}
                         for run, a, g, arm, r, hi in points])


def test_the_designer_follows_the_frontier():
    from amorgs.ablation.frontier import choose_sampler

    train = [0.1, 0.3, 0.5]
    table = _frontier([("sparse-3", 0.3, 0.67, "amorgs", 0.5, 0.9), ("sparse-3", 0.3, 0.67, "continuation", 0.7, 1.3),
                       ("sparse-5", 0.4, 0.25, "amorgs", 1.5, 3.0), ("sparse-5", 0.6, 0.17, "amorgs", 0.8, 0.95),
                       ("sparse-8", 0.9, 0.06, "amorgs", 2.0, 4.0)])
    far = choose_sampler(table, 0.2, train)  # gap 0.1 / 0.2 = 50 %: nearest measured 67 %, where AmorGS won
    assert far.sampler == "amorgs" and far.gap_relative == pytest.approx(0.5) and "0.300 in sparse-3" in far.reason
    mid = choose_sampler(table, 0.39, train)  # 2.6 %: nearest measured 6 % → reuse lost nothing there
    assert mid.sampler == "nearest_alpha" and "No learned arm beat reuse" in mid.reason
    pooled = choose_sampler(table, 0.58, train)  # 13.8 %: only 17 % (AmorGS won) lies within 1.25× of the nearest
    assert pooled.sampler == "amorgs" and len(pooled.evidence) == 1
    both = choose_sampler(table, 0.62, train)  # 19.4 %: 17 % and 25 % within the pooling factor: not every point won
    assert both.sampler == "nearest_alpha" and len(both.evidence) == 2
    assert choose_sampler(table, 0.3, train).sampler == "nearest_alpha"  # a known α: its own solutions
    assert choose_sampler(table, 0.2, train, available=("continuation",)).sampler == "nearest_alpha"
    assert "no frontier measurement" in choose_sampler(table.iloc[:0], 0.2, train).reason
