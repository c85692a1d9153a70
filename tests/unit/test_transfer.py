"""Transfer data (issue 38 §1): the pairs of training α, the jobs a config runs, and one real transfer shard —
high-quality library solutions of one training α solved at another, labelled with what each solve gave."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from config_files import mapping, write

from amorgs import steps
from amorgs.config import ConfigError, from_mapping, load_config
from amorgs.data.library import read_library
from amorgs.problems.cr3bp import Cr3bpFilter
from amorgs.ablation.arms import get_arm
from amorgs.steps.transfer import transfer_pairs

ROOT = Path(__file__).resolve().parents[2]


def _config(**transfer):
    data = mapping("smoke")
    data["transfer"].update(transfer)
    if not data["transfer"]["enabled"]:  # the selector's arms learn from the transfer data
        data["ablation"]["samplers"] = [s for s in data["ablation"]["samplers"] if not get_arm(s).transfer]
    return from_mapping(data, "test")


def test_pairs_are_ordered_training_alpha_within_the_gap_and_never_a_test_alpha():
    cfg = _config(max_relative_gap=0.15)
    assert transfer_pairs(cfg) == [(0.8, 0.7), (0.7, 0.8), (0.9, 0.8), (0.8, 0.9)]  # (from, to), by α_to
    assert len(transfer_pairs(_config(max_relative_gap=1.0))) == 6  # every ordered pair of 3 α
    jobs = steps.registry()["transfer"].jobs(_config(shards=2))
    assert len(jobs) == 8 and {j["source"] for j in jobs} | {j["alpha"] for j in jobs} == {"0.700", "0.800", "0.900"}
    assert steps.registry()["transfer"].jobs(_config(enabled=False)) == []
    assert all("transfer/alpha=" in p for p in steps.targets(_config()) if "/transfer/" in p)
    frontier_pairs = transfer_pairs(load_config(ROOT / "config" / "default.yaml").model_copy(
        update={"transfer": _config(max_relative_gap=0.3).transfer}))
    test = set(load_config(ROOT / "config" / "default.yaml").problems.cr3bp.alphas.test)
    assert frontier_pairs and not test & {a for pair in frontier_pairs for a in pair}


def test_transfer_needs_two_training_alpha_named_in_one_line(tmp_path):
    data = mapping("smoke")
    data["problems"]["cr3bp"]["alphas"]["train"] = [0.7]
    with pytest.raises(ConfigError, match=r"transfer\.enabled needs at least 2 α in problems\.cr3bp\.alphas\.train"):
        load_config(write(tmp_path, data))


def test_a_transfer_shard_solves_the_source_solutions_at_the_target_alpha(tmp_path, monkeypatch):
    cfg = _config(starts_per_pair=3)
    hq = Cr3bpFilter().select(pd.concat([read_library(ROOT / "data" / "library", "cr3bp", label).head(60)
                                         for label in ("0.700", "0.800")], ignore_index=True))
    monkeypatch.chdir(tmp_path)
    hq.to_parquet("hq.parquet")
    w = {"problem": "cr3bp", "alpha": "0.800", "source": "0.700", "shard": "0"}
    steps.run_step("transfer", cfg, w, {"high_quality": "hq.parquet"}, {"table": "t.parquet"})
    table = pd.read_parquet("t.parquet")
    assert len(table) == 3 and set(table["alpha"]) == {0.8} and set(table["source_alpha"]) == {0.7}
    assert np.allclose(table["gap_relative"], 0.125) and set(table["shard"]) == {0}
    pool = hq[hq["alpha"] == 0.7]
    assert table["source_pool_size"].iloc[0] == len(pool)
    names = [c.removeprefix("guess_") for c in table if c.startswith("guess_")]
    sources = {tuple(np.round(r, 9)) for r in pool[["tau_s", "tau_i", "tau_f", "m_f"]].to_numpy()}
    assert all(tuple(np.round(r, 9)) in sources for r in table[["guess_tau_s", "guess_tau_i", "guess_tau_f",
                                                                "guess_m_f"]].to_numpy())  # α_from's solutions
    assert len(names) == 64 and (table["iterations"] <= cfg.problems.cr3bp.solver.max_iter).all()
    assert table["nlp_fingerprint"].str.len().eq(12).all()
    steps.run_step("transfer", cfg, w, {"high_quality": "hq.parquet"}, {"table": "again.parquet"})
    again = pd.read_parquet("again.parquet")
    pd.testing.assert_frame_equal(table.drop(columns=["wall_s", "cpu_s"]), again.drop(columns=["wall_s", "cpu_s"]))
