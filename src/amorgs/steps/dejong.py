"""De Jong's 5th function (paper Sec. V.A): the GMM-prior CVAE trained on the filtered minima at the training
α, its samples at the held-out test α scored against the analytic minima, and Figs. 2 and 16."""

from __future__ import annotations

from amorgs import layout
from amorgs.alphas import cap_per_alpha, metric_key, rows_at_any
from amorgs.config import Config, DejongCVAE, Section
from amorgs.models.names import DEJONG_PRESETS
from amorgs.steps import Job, Step, Wildcards, once_if, resources_of
from amorgs.steps.outputs import use_agg, write_png


class DejongTrainSettings(Section):
    """The CVAE section of the config and the training α (rows at other α are left out)."""

    model: DejongCVAE
    train_alphas: tuple[float, ...]


def _train_settings(cfg: Config, w: Wildcards) -> DejongTrainSettings:
    return DejongTrainSettings(model=cfg.dejong_cvae, train_alphas=cfg.problems.dejong.alphas.train_values())


def _cvae_config(preset: str):
    from amorgs.models.cvae import CVAEConfig

    presets = {"dejong_paper": CVAEConfig.dejong_paper,
               "small": lambda: CVAEConfig.small(x_dim=2, latent_dim=2, n_components=2)}
    assert set(presets) == set(DEJONG_PRESETS), "every registered preset has a network size"
    return presets[preset]()


def run_train(job: Job, run) -> None:
    import numpy as np
    import pandas as pd
    import torch

    from amorgs.data.io import atomic_path
    from amorgs.models import cvae
    from amorgs.models.training import TrainConfig, train
    from amorgs.problems import get_problem

    s: DejongTrainSettings = job.settings
    m = s.model
    torch.set_num_threads(job.threads)
    names = list(get_problem("dejong").variable_names)
    data, output = job.input["high_quality"], job.output["model"]
    df = cap_per_alpha(rows_at_any(pd.read_parquet(data), s.train_alphas), m.max_rows_per_alpha, m.seed)
    x = df[names].to_numpy(dtype=np.float64, copy=True)
    alpha = df["alpha"].to_numpy(dtype=np.float64, copy=True)
    cfg = TrainConfig(epochs=m.epochs, batch_size=m.batch_size, lr=m.learning_rate, seed=m.seed, device="cpu",
                      validation_fraction=m.validation_fraction, patience=m.patience)
    run.log_params({"rows": len(df)})
    run.log_dataset(df, data, "training")
    run.start_model("cvae_gmm", {"preset": m.preset, **vars(cfg)})
    torch.manual_seed(m.seed)
    model = cvae.GMMPriorCVAE(_cvae_config(m.preset), cvae.Normalizer.from_data(x))
    history = train(model, x, alpha, cfg, on_epoch=lambda epoch, metrics: run.log_metrics(metrics, step=epoch))
    with atomic_path(output) as tmp:
        cvae.save(model, tmp)
    ran = len(history["epoch"])
    run.log_metrics({f"final_{k}": v[-1] for k, v in history.items() if k != "epoch"} | {"epochs_run": ran})
    run.finish_model(output, step=ran)
    print(f"{output}: trained {ran} of at most {m.epochs} epochs on {len(df)} minima")


class DejongPredictSettings(Section):
    """``n_samples`` CVAE samples per test α with ``seed``; a sample within ``radius`` of a minimum is a hit."""

    n_samples: int
    seed: int
    radius: float
    test_alphas: tuple[float, ...]


def _predict_settings(cfg: Config, w: Wildcards) -> DejongPredictSettings:
    c = cfg.dejong_cvae
    return DejongPredictSettings(n_samples=c.n_samples, seed=c.seed, radius=c.radius,
                                 test_alphas=cfg.problems.dejong.alphas.test)


def run_predict(job: Job, run) -> None:
    import pandas as pd
    import torch

    from amorgs.alphas import alpha_label
    from amorgs.analysis.dejong_eval import prediction_metrics
    from amorgs.data.io import write_json, write_parquet
    from amorgs.models import cvae
    from amorgs.problems import get_problem

    s: DejongPredictSettings = job.settings
    names = list(get_problem("dejong").variable_names)
    model = cvae.load(job.input["model"])
    generator = torch.Generator().manual_seed(s.seed)
    frames, metrics = [], {}
    for alpha in s.test_alphas:
        samples = model.sample(alpha, s.n_samples, generator=generator).detach().cpu().numpy()
        frame = pd.DataFrame(samples, columns=names)
        frame.insert(0, "alpha", alpha)
        frame.insert(1, "sample", range(len(frame)))
        frames.append(frame)
        scores = prediction_metrics(samples, alpha, radius=s.radius)
        metrics[alpha_label(alpha)] = {"alpha": alpha, **scores}
        run.log_metrics({metric_key(k, alpha): v for k, v in scores.items() if k not in ("n_samples", "radius")})
    write_parquet(pd.concat(frames, ignore_index=True), job.output["samples"])
    write_json({"radius": s.radius, "n_samples": s.n_samples, "per_alpha": metrics}, job.output["metrics"])
    run.log_artifact(job.output["metrics"])
    print(f"{job.output['samples']}: {s.n_samples} samples at each of {len(s.test_alphas)} test α")


class NoSettings(Section):
    """A step that reads nothing from the config."""


class Fig16Settings(Section):
    """The training α (Fig. 16 shows the minima at these α only)."""

    train_alphas: tuple[float, ...]


def run_fig02(job: Job, run) -> None:
    use_agg()
    from amorgs.figures.dejong import fig02_foxholes

    write_png(fig02_foxholes(), job.output["figure"], run)
    print(f"{job.output['figure']}: written")


def run_fig16(job: Job, run) -> None:
    use_agg()
    import pandas as pd

    from amorgs.figures.dejong import fig16_dejong_predictions
    from amorgs.problems import get_problem

    names = list(get_problem("dejong").variable_names)
    samples = pd.read_parquet(job.input["samples"])
    by_alpha = {float(a): g[names].to_numpy() for a, g in samples.groupby("alpha", sort=True)}
    fig = fig16_dejong_predictions(pd.read_parquet(job.input["high_quality"]), by_alpha, job.settings.train_alphas)
    write_png(fig, job.output["figure"], run)
    print(f"{job.output['figure']}: written")


STAGE = 3
STEPS = (
    Step("train_dejong_cvae", DejongTrainSettings, _train_settings, run_train, once_if("dejong_cvae"),
         lambda w: {"model": layout.DEJONG_MODEL},
         resources=resources_of("train"),
         description="GMM-prior CVAE on the filtered De Jong minima → checkpoint"),
    Step("predict_dejong_cvae", DejongPredictSettings, _predict_settings, run_predict, once_if("dejong_cvae"),
         lambda w: {"samples": layout.DEJONG_SAMPLES, "metrics": layout.DEJONG_METRICS},
         resources=resources_of("predict"),
         description="CVAE samples at the test α + hit metrics"),
    Step("fig02_foxholes", NoSettings, lambda cfg, w: NoSettings(), run_fig02, once_if("problems.dejong"),
         lambda w: {"figure": layout.FIGURE.format(name="fig02_foxholes")},
         resources=resources_of("figure"),
         report=("fig02_foxholes", "De Jong"), description="Fig. 2: the classic 25-foxhole function"),
    Step("fig16_dejong_predictions", Fig16Settings,
         lambda cfg, w: Fig16Settings(train_alphas=cfg.problems.dejong.alphas.train_values()),
         run_fig16, once_if("dejong_cvae"),
         lambda w: {"figure": layout.FIGURE.format(name="fig16_dejong_predictions")},
         resources=resources_of("figure"),
         report=("fig16_dejong_predictions", "De Jong"), description="Fig. 16: training minima and CVAE samples"),
)
