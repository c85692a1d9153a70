"""The results tree: the path template of every workflow output and the names of the files behind them.

Templates use Snakemake's wildcard syntax: ``{problem}`` (``dejong``, ``cr3bp``), ``{alpha}`` (the α label
of :func:`amorgs.alphas.alpha_label`, e.g. ``0.150``), ``{shard}`` (0-based), ``{model}`` (``cvae_gmm``,
``vanilla_cvae``, ``lstm``), ``{fraction}`` (:func:`fraction_label`, e.g. ``0.1``), ``{sampler}`` (one of
:data:`amorgs.ablation.arms.SAMPLER_NAMES`), ``{mseed}`` (an extra model-training seed), ``{source}`` (the α label a transfer's guesses come from) and ``{name}``
(a figure or table).  The steps
(:mod:`amorgs.steps`: each job's outputs) and the rules' inputs take their file names from here; which files a
config produces is the union of its jobs' outputs (:func:`amorgs.steps.targets`).
"""

from __future__ import annotations


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
#: Models trained on a fraction of the rows of every training α (Fig. 18; the ablation's learning curve).
CR3BP_FRACTION_MODEL = "results/cr3bp/models/fraction={fraction}/{model}.pt"
CR3BP_SAMPLES = "results/cr3bp/predictions/samples.parquet"
CR3BP_PREDICTION_METRICS = "results/cr3bp/predictions/metrics.json"
ABLATION_CELL = "results/cr3bp/ablation/alpha={alpha}/{sampler}.parquet"
#: Models and ablation cells of the extra model-training seeds (``cr3bp_models.extra_seeds``), wildcard {mseed}.
CR3BP_REPLICATE_MODEL = "results/cr3bp/models/seed={mseed}/{model}.pt"
ABLATION_REPLICATE_CELL = "results/cr3bp/ablation/seed={mseed}/alpha={alpha}/{sampler}.parquet"
#: Cells of a learned arm whose models saw only a fraction of the training data (the learning curve).
ABLATION_FRACTION_CELL = "results/cr3bp/ablation/fraction={fraction}/alpha={alpha}/{sampler}.parquet"
ABLATION_SUMMARY = "results/cr3bp/ablation/summary.json"
#: A global-search cell (issue 41): the events (a row per solve) and the feasible solutions of its searches.
GLOBAL_SEARCH_EVENTS = "results/cr3bp/global_search/alpha={alpha}/{strategy}-{sampler}.events.parquet"
GLOBAL_SEARCH_SOLUTIONS = "results/cr3bp/global_search/alpha={alpha}/{strategy}-{sampler}.solutions.parquet"
GLOBAL_SEARCH_SUMMARY = "results/cr3bp/global_search/summary.json"
GLOBAL_SEARCH_TABLES = ("global_search_runtime.csv", "global_search_runtime.md", "global_search_ratios.csv",
                        "global_search_ecdf.csv", "global_search_distinct.csv", "global_search_best_known.csv")
GLOBAL_SEARCH_FIGURE = "fig_global_search_ecdf"
#: Transfer data (issue 38): high-quality solutions of training α {source} solved at training α {alpha}.
TRANSFER_SHARD = "results/{problem}/transfer/alpha={alpha}/from={source}/shard-{shard}.parquet"
#: The transfer selector trained on every transfer shard of the run (issue 38 §2), and its report.
SELECTOR_MODEL = "results/cr3bp/models/selector.joblib"
SELECTOR_REPORT = "results/cr3bp/models/selector.training.json"
TABLE = "results/tables/{name}"
#: Snakemake's ``benchmark:`` file of every job (wall, CPU, memory; the rules in workflow/rules/), and the
#: per-rule report the workflow writes from them when it finishes (:mod:`amorgs.runtime_report`).
BENCHMARK_DIR = "results/benchmarks"
RUNTIME_TABLE = "results/tables/runtime_by_rule.csv"
RUNTIME_JOBS = "results/tables/runtime_by_job.csv"
RUNTIME_MARKDOWN = "results/tables/runtime_by_rule.md"
RUNTIME_FIGURE = "results/figures/runtime_by_rule.png"

#: The tables of the structure analysis (:class:`amorgs.analysis.structure_result.StructureResult`) and the
#: figures drawn from it (:func:`amorgs.figures.structure.structure_figures`), by name.
ANALYSIS_TABLES = ("modes", "funnels", "control_statistics", "moving_average", "diversity", "diverse_subset", "trajectories")
ANALYSIS_FIGURES = (
    "fig03_time_hyperplanes", "fig04_tof_histograms", "fig05_hyperplane_filtering", "fig06_inplane_mass_contours",
    "fig07_moving_average_macro", "fig08_moving_average_micro", "fig09_trajectories_across_hyperplanes",
    "fig10_trajectories_within_hyperplane", "fig11_funnels", "fig12_funnels", "fig13_control_statistics",
)
PREDICTION_FIGURES = ("fig17_time_predictions", "fig18_data_fraction", "fig19_final_mass", "fig20_control_statistics")
ABLATION_FIGURES = (
    "fig21_solve_time_histograms", "fig22_capped_convergence", "fig23_amorgs_diversity",
    "fig22_iteration_capped", "ablation_speedups", "ablation_beta_sweep", "ablation_anytime",
)
#: The ablation report's tables: one per study of :data:`amorgs.ablation.studies.STUDIES` (its ``table_files``).


def fraction_label(fraction: float) -> str:
    """The string form of a data fraction in paths and wildcards (``0.1``, ``0.5``)."""
    return f"{fraction:g}"


def training_report(checkpoint: str) -> str:
    """The training report (rows, epochs, CPU seconds) written beside a checkpoint ``<name>.pt``."""
    return checkpoint.removesuffix(".pt") + ".training.json"
