"""The CR3BP models sampled at the held-out test α and compared with the ground truth there (paper
Sec. V.B.3–6, Figs. 17–20)."""

from __future__ import annotations

import os

from amorgs import layout
from amorgs.alphas import metric_key, rows_at
from amorgs.config import Config, Section
from amorgs.steps import Job, Step, Wildcards, once_if, resources_of
from amorgs.steps.outputs import finite_metrics, use_agg, write_figures


class PredictSettings(Section):
    """``n_samples`` samples per test α from each model with ``seed``."""

    n_samples: int
    seed: int
    test_alphas: tuple[float, ...]


def _settings(cfg: Config, w: Wildcards) -> PredictSettings:
    m = cfg.cr3bp_models
    return PredictSettings(n_samples=m.n_samples, seed=m.seed, test_alphas=cfg.problems.cr3bp.alphas.test)


def _fraction_of(path: str) -> float:
    """The data fraction of a reduced-data checkpoint, read from its folder ``fraction={f}``."""
    return float(os.path.basename(os.path.dirname(path)).split("=", 1)[1])


def run_predict(job: Job, run) -> None:
    use_agg()
    import numpy as np
    import pandas as pd

    from amorgs.ablation.arms import build_sampler
    from amorgs.analysis.prediction import prediction_table
    from amorgs.data.io import write_json, write_parquet
    from amorgs.figures.prediction import (
        fig17_time_predictions,
        fig18_data_fraction,
        fig19_final_mass,
        fig20_control_statistics,
    )
    from amorgs.models import cvae
    from amorgs.models.samplers import CVAETimeMassUniformControl
    from amorgs.problems import get_problem

    s: PredictSettings = job.settings
    problem = get_problem("cr3bp")
    names = list(problem.variable_names)
    models_dir = os.path.dirname(job.input["models"][0])
    fractions = {_fraction_of(p): p for p in job.input["fraction_models"]}
    samplers = {("amorgs", 1.0): build_sampler("amorgs", problem, models_dir),
                ("uniform", 1.0): build_sampler("uniform", problem, models_dir)}
    for f, path in fractions.items():
        samplers[("cvae_gmm", f)] = CVAETimeMassUniformControl(problem, cvae.load(path))
    run.log_params({"data_fractions": sorted(fractions)})
    rng = np.random.default_rng(s.seed)
    frames = []
    for (source, fraction), sampler in samplers.items():
        for alpha in s.test_alphas:
            frame = pd.DataFrame(sampler.sample(alpha, s.n_samples, rng), columns=names)
            frame.insert(0, "alpha", alpha)
            frame.insert(1, "source", source)
            frame.insert(2, "data_fraction", fraction)
            frame.insert(3, "sample", range(len(frame)))
            frames.append(frame)
    samples = pd.concat(frames, ignore_index=True)
    hq = pd.read_parquet(job.input["high_quality"])
    run.log_dataset(hq, job.input["high_quality"], "evaluation")  # the ground truth at the test α
    truth = pd.concat([rows_at(hq, a) for a in s.test_alphas], ignore_index=True)
    # uniform guesses too: the baseline of the mechanism (how often a guess lands on a plane by chance)
    table = prediction_table(samples, truth, by=("alpha", "source", "data_fraction"))
    write_parquet(samples, job.output["samples"])
    write_json({"n_samples": s.n_samples, "rows": table.to_dict(orient="records")}, job.output["metrics"])
    for row in table.to_dict(orient="records"):
        model = f"{row['source']}_f{row['data_fraction']:g}"
        run.log_metrics(finite_metrics({metric_key(k, row["alpha"], model): v for k, v in row.items()
                                        if k not in ("alpha", "source", "data_fraction")}))
    run.log_artifact(job.output["metrics"])
    amorgs = samples[samples["source"] == "amorgs"]
    by_fraction = {1.0: amorgs, **{f: samples[(samples["source"] == "cvae_gmm") & (samples["data_fraction"] == f)]
                                   for f in fractions}}
    figures = {
        "fig17_time_predictions": fig17_time_predictions(amorgs, truth, s.test_alphas),
        "fig18_data_fraction": fig18_data_fraction(dict(sorted(by_fraction.items())), truth, s.test_alphas),
        "fig19_final_mass": fig19_final_mass(amorgs, truth, s.test_alphas),
        "fig20_control_statistics": fig20_control_statistics(
            {"LSTM": amorgs, "Ground truth": truth, "Uniform": samples[samples["source"] == "uniform"]}, s.test_alphas),
    }
    write_figures(figures, job.output["figures"], run)
    print(f"{job.output['samples']}: {len(samples)} samples at {len(s.test_alphas)} test α")


STAGE = 6
STEPS = (
    Step("predict_cr3bp", PredictSettings, _settings, run_predict, once_if("cr3bp_models"),
         lambda w: {"samples": layout.CR3BP_SAMPLES, "metrics": layout.CR3BP_PREDICTION_METRICS,
                    "figures": [layout.FIGURE.format(name=n) for n in layout.PREDICTION_FIGURES]},
         resources=resources_of("predict"),
         report=("cr3bp_predictions", "CR3BP predictions"),
         description="samples of the models at the test α vs the ground truth; Figs. 17–20"),
)
