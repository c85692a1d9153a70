"""The results tree: path templates of every workflow output, and the targets a config asks for.

Templates use Snakemake's wildcard syntax: ``{problem}`` (``dejong``, ``cr3bp``), ``{alpha}`` (the α label
of :func:`amorgs.config.alpha_label`, e.g. ``0.150``), ``{shard}`` (0-based), ``{model}`` (``cvae_gmm``,
``vanilla_cvae``, ``lstm``), ``{fraction}`` (:func:`fraction_label`, e.g. ``0.1``), ``{sampler}`` (one of
:data:`amorgs.ablation.arms.SAMPLER_NAMES`), ``{mseed}`` (an extra model-training seed) and ``{name}`` (a figure or table).  The Snakefile's rules
and ``amorgs check-outputs`` both take their file names from here.
"""

from __future__ import annotations

from amorgs.config import Config, alpha_label

SHARD = "results/{problem}/solutions/alpha={alpha}/shard-{shard}.parquet"
ALPHA_TABLE = "results/{problem}/solutions/alpha={alpha}.parquet"
HIGH_QUALITY = "results/{problem}/high_quality.parquet"
QUALITY_REPORT = "results/{problem}/quality_report.json"
DEJONG_MODEL = "results/dejong/models/cvae_gmm.pt"
DEJONG_SAMPLES = "results/dejong/predictions/samples.parquet"
DEJONG_METRICS = "results/dejong/predictions/metrics.json"
FIGURE = "results/figures/{name}.png"

CR3BP_ANALYSIS_METRICS = "results/cr3bp/analysis/metrics.json"
CR3BP_ANALYSIS_TABLE = "results/cr3bp/analysis/{name}.parquet"
CR3BP_MODEL = "results/cr3bp/models/{model}.pt"
CR3BP_FRACTION_MODEL = "results/cr3bp/models/fraction={fraction}/cvae_gmm.pt"
CR3BP_SAMPLES = "results/cr3bp/predictions/samples.parquet"
CR3BP_PREDICTION_METRICS = "results/cr3bp/predictions/metrics.json"
ABLATION_CELL = "results/cr3bp/ablation/alpha={alpha}/{sampler}.parquet"
#: Models and ablation cells of the extra model-training seeds (``cr3bp_models.extra_seeds``), wildcard {mseed}.
CR3BP_REPLICATE_MODEL = "results/cr3bp/models/seed={mseed}/{model}.pt"
ABLATION_REPLICATE_CELL = "results/cr3bp/ablation/seed={mseed}/alpha={alpha}/{sampler}.parquet"
ABLATION_SUMMARY = "results/cr3bp/ablation/summary.json"
TABLE = "results/tables/{name}"

#: What ``amorgs.analysis.structure_report.analyze`` returns (tables, figures), by name.
ANALYSIS_TABLES = ("modes", "funnels", "control_statistics", "moving_average", "diversity", "diverse_subset", "trajectories")
ANALYSIS_FIGURES = (
    "fig03_time_hyperplanes", "fig04_tof_histograms", "fig05_hyperplane_filtering", "fig06_inplane_mass_contours",
    "fig07_moving_average_macro", "fig08_moving_average_micro", "fig09_trajectories_across_hyperplanes",
    "fig10_trajectories_within_hyperplane", "fig11_funnels", "fig12_funnels", "fig13_control_statistics",
)
CR3BP_MODELS = ("cvae_gmm", "vanilla_cvae", "lstm")
PREDICTION_FIGURES = ("fig17_time_predictions", "fig18_data_fraction", "fig19_final_mass", "fig20_control_statistics")
ABLATION_FIGURES = (
    "fig21_solve_time_histograms", "fig22_capped_convergence", "fig23_amorgs_diversity",
    "fig22_iteration_capped", "ablation_speedups", "ablation_beta_sweep", "ablation_anytime",
)
#: The issue-11 statistics tables, each written as <name>.csv and <name>.md (anytime: CSV only).
ABLATION_STAT_TABLES = ("ablation_rates", "ablation_beta_sweep", "ablation_ert", "ablation_iteration_capped")
ABLATION_TABLES = (
    "table6.csv", "table6.md", "ablation_capped.csv", "ablation_coverage.csv",
    *(f"{n}.{ext}" for n in ABLATION_STAT_TABLES for ext in ("csv", "md")), "ablation_anytime.csv",
)


def fraction_label(fraction: float) -> str:
    """The string form of a data fraction in paths and wildcards (``0.1``, ``0.5``)."""
    return f"{fraction:g}"


def shard_paths(cfg: Config, problem: str, alpha: str) -> list[str]:
    """Every shard table of ``problem`` at α label ``alpha``."""
    n = getattr(cfg.problems, problem).generate.shards
    return [SHARD.format(problem=problem, alpha=alpha, shard=k) for k in range(n)]


def alpha_tables(cfg: Config, problem: str) -> list[str]:
    """The merged table of every generated α of ``problem``."""
    return [ALPHA_TABLE.format(problem=problem, alpha=a) for a in getattr(cfg.problems, problem).alpha_values()]


def fraction_models(cfg: Config) -> list[str]:
    """The reduced-data GMM-CVAE checkpoints of Fig. 18."""
    return [CR3BP_FRACTION_MODEL.format(fraction=fraction_label(f)) for f in cfg.cr3bp_models.data_fractions]


def ablation_cells(cfg: Config) -> list[str]:
    """One table per (test α, sampler) of the ablation, and one per (extra model seed, test α, sampler)."""
    cells = [
        ABLATION_CELL.format(alpha=alpha_label(a), sampler=s)
        for a in cfg.problems.cr3bp.alphas.test
        for s in cfg.ablation.samplers
    ]
    return cells + [
        ABLATION_REPLICATE_CELL.format(mseed=m, alpha=alpha_label(a), sampler=s)
        for m in cfg.cr3bp_models.extra_seeds
        for a in cfg.problems.cr3bp.alphas.test
        for s in cfg.ablation.samplers
    ]


def replicate_models(cfg: Config) -> list[str]:
    """The checkpoints of the extra model-training seeds (only those the ablation's arms load)."""
    from amorgs.ablation.arms import NEEDS_MODELS

    needed = sorted({m for s in cfg.ablation.samplers for m in NEEDS_MODELS[s]}) if cfg.ablation.enabled else []
    return [CR3BP_REPLICATE_MODEL.format(mseed=m, model=name) for m in cfg.cr3bp_models.extra_seeds for name in needed]


def figure_names(cfg: Config) -> list[str]:
    """The figures this config draws: Fig. 2 with De Jong enabled, Fig. 16 with the De Jong CVAE, Figs. 3–13
    with the CR3BP analysis, 17–20 with the CR3BP models and 21–23 with the ablation."""
    names = ["fig02_foxholes"] if cfg.problems.dejong.enabled else []
    if cfg.dejong_cvae.enabled:
        names.append("fig16_dejong_predictions")
    if cfg.cr3bp_analysis.enabled:
        names += ANALYSIS_FIGURES
    if cfg.cr3bp_models.enabled:
        names += PREDICTION_FIGURES
    if cfg.ablation.enabled:
        names += ABLATION_FIGURES
    return names


def targets(cfg: Config) -> list[str]:
    """The final outputs of a config (the inputs of ``rule all``): filtered tables, reports, models,
    predictions and figures; everything upstream follows from them."""
    out: list[str] = []
    for name in cfg.problems.enabled():
        out += [HIGH_QUALITY.format(problem=name), QUALITY_REPORT.format(problem=name)]
    if cfg.dejong_cvae.enabled:
        out += [DEJONG_MODEL, DEJONG_SAMPLES, DEJONG_METRICS]
    if cfg.cr3bp_analysis.enabled:
        out += [CR3BP_ANALYSIS_METRICS, *(CR3BP_ANALYSIS_TABLE.format(name=n) for n in ANALYSIS_TABLES)]
    if cfg.cr3bp_models.enabled:
        out += [CR3BP_MODEL.format(model=m) for m in CR3BP_MODELS] + fraction_models(cfg)
        out += [CR3BP_SAMPLES, CR3BP_PREDICTION_METRICS]
    if cfg.ablation.enabled:
        out += ablation_cells(cfg) + [ABLATION_SUMMARY, *(TABLE.format(name=n) for n in ABLATION_TABLES)]
        out += replicate_models(cfg)
    out += [FIGURE.format(name=n) for n in figure_names(cfg)]
    return out
