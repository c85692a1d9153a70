"""The runtime report (issue 40 §1): Snakemake's per-job benchmark files → a table per rule and per job, a figure."""

from __future__ import annotations

import pandas as pd
import pytest

from amorgs import layout
from amorgs.runtime_report import read_benchmarks, runtime_by_rule, write_runtime_report

HEADER = "s\th:m:s\tmax_rss\tmax_vms\tmax_uss\tmax_pss\tio_in\tio_out\tmean_load\tcpu_time\n"


def bench(root, rule, job, *runs):
    path = root / rule / f"{job}.tsv"
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(HEADER + "".join(f"{s}\t0:00:{int(s):02d}\t{rss}\t1\t1\t1\t0\t0\t50\t{cpu}\n" for s, cpu, rss in runs))


def test_per_job_then_per_rule_the_latest_execution_of_each_job(tmp_path, monkeypatch):
    root = tmp_path / layout.BENCHMARK_DIR
    bench(root, "generate", "cr3bp/alpha=0.100/shard-0", (30.0, 29.0, 300.0))
    bench(root, "generate", "cr3bp/alpha=0.200/shard-0", (99.0, 98.0, 310.0), (20.0, 19.0, 290.0))  # rerun: latest
    bench(root, "filter", "cr3bp", (2.0, 1.0, 200.0))
    bench(root, "train_cr3bp", "lstm", (60.0, 110.0, 900.0))
    jobs = read_benchmarks(root)
    assert len(jobs) == 4 and set(jobs["rule"]) == {"generate", "filter", "train_cr3bp"}
    assert jobs.set_index("job").loc["cr3bp/alpha=0.200/shard-0", "wall_s"] == 20.0
    rules = runtime_by_rule(jobs)
    assert list(rules["rule"]) == ["train_cr3bp", "generate", "filter"]  # the most CPU first
    gen = rules.set_index("rule").loc["generate"]
    assert gen["jobs"] == 2 and gen["wall_min"] == pytest.approx(50 / 60) and gen["cpu_min"] == pytest.approx(48 / 60)
    assert gen["max_rss_mb"] == 300.0 and rules["cpu_share"].sum() == pytest.approx(1)
    monkeypatch.chdir(tmp_path)
    paths = write_runtime_report(root)
    assert [p.name for p in paths] == ["runtime_by_rule.csv", "runtime_by_job.csv", "runtime_by_rule.md",
                                       "runtime_by_rule.png"]
    pd.testing.assert_frame_equal(pd.read_csv(paths[0]), rules, check_dtype=False)
    assert "4 jobs" in paths[2].read_text() and paths[3].stat().st_size > 0
    assert write_runtime_report(tmp_path / "none") == []  # nothing benchmarked: nothing written
