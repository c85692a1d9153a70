"""The results tree: path templates of every workflow output, and the targets a config asks for.

Templates use Snakemake's wildcard syntax: ``{problem}`` (``dejong``, ``cr3bp``), ``{alpha}`` (the α label
of :func:`amorgs.config.alpha_label`, e.g. ``0.150``) and ``{shard}`` (0-based).  The Snakefile's rules
and ``amorgs check-outputs`` both take their file names from here.
"""

from __future__ import annotations

from amorgs.config import Config

SHARD = "results/{problem}/solutions/alpha={alpha}/shard-{shard}.parquet"
ALPHA_TABLE = "results/{problem}/solutions/alpha={alpha}.parquet"
HIGH_QUALITY = "results/{problem}/high_quality.parquet"
QUALITY_REPORT = "results/{problem}/quality_report.json"
DEJONG_MODEL = "results/dejong/models/cvae_gmm.pt"
DEJONG_SAMPLES = "results/dejong/predictions/samples.parquet"
DEJONG_METRICS = "results/dejong/predictions/metrics.json"
FIGURE = "results/figures/{name}.png"


def shard_paths(cfg: Config, problem: str, alpha: str) -> list[str]:
    """Every shard table of ``problem`` at α label ``alpha``."""
    n = getattr(cfg.problems, problem).generate.shards
    return [SHARD.format(problem=problem, alpha=alpha, shard=k) for k in range(n)]


def alpha_tables(cfg: Config, problem: str) -> list[str]:
    """The merged table of every generated α of ``problem``."""
    return [ALPHA_TABLE.format(problem=problem, alpha=a) for a in getattr(cfg.problems, problem).alpha_values()]


def figure_names(cfg: Config) -> list[str]:
    """The figures this config draws: Fig. 2 with De Jong enabled, Fig. 16 with the De Jong CVAE."""
    names = ["fig02_foxholes"] if cfg.problems.dejong.enabled else []
    if cfg.dejong_cvae.enabled:
        names.append("fig16_dejong_predictions")
    return names


def targets(cfg: Config) -> list[str]:
    """The final outputs of a config (the inputs of ``rule all``): filtered tables, reports, models,
    predictions and figures; everything upstream follows from them."""
    out: list[str] = []
    for name in cfg.problems.enabled():
        out += [HIGH_QUALITY.format(problem=name), QUALITY_REPORT.format(problem=name)]
    if cfg.dejong_cvae.enabled:
        out += [DEJONG_MODEL, DEJONG_SAMPLES, DEJONG_METRICS]
    out += [FIGURE.format(name=n) for n in figure_names(cfg)]
    return out
