"""The CR3BP models (paper Sec. IV): each trained on the high-quality rows at the training α only (the test α
are generated for the ground truth, never trained on); Fig. 18's GMM-CVAEs on fractions of the data; and the
models of every extra training seed (the ablation's replicates)."""

from __future__ import annotations

import time
from typing import Annotated, Literal

from pydantic import Field

from amorgs import layout
from amorgs.alphas import alpha_label, rows_at_any
from amorgs.config import Config, Cr3bpModels, Section
from amorgs.models.names import CR3BP_MODELS, PAPER_MODELS, get_model
from amorgs.steps import Job, Step, Wildcards, resources_of


class TrainSettings(Section):
    """One CR3BP model: the ``cr3bp_models`` section, the training ``seed`` of this job (the section's seed,
    or an extra seed for a replicate), the training α, and the data ``fraction`` (1: every row)."""

    models: Cr3bpModels
    model: Literal[CR3BP_MODELS]  # type: ignore[valid-type]
    seed: Annotated[int, Field(ge=0)]
    fraction: Annotated[float, Field(gt=0, le=1)] = 1.0
    train_alphas: tuple[float, ...]


def _settings(cfg: Config, w: Wildcards) -> TrainSettings:
    m = cfg.cr3bp_models
    return TrainSettings(models=m, model=w.get("model", "cvae_gmm"), seed=int(w.get("mseed", m.seed)),
                         fraction=float(w.get("fraction", 1.0)), train_alphas=cfg.problems.cr3bp.alphas.train_values())


def _outputs(checkpoint: str) -> dict[str, str]:
    """The checkpoint and its training report (rows, epochs, training CPU seconds)."""
    return {"model": checkpoint, "report": layout.training_report(checkpoint)}


def run_train(job: Job, run) -> None:
    import pandas as pd
    import torch

    from amorgs.alphas import cap_per_alpha
    from amorgs.data.io import atomic_path, write_json
    from amorgs.models.cr3bp_models import subsample
    from amorgs.models.training import TrainConfig

    s: TrainSettings = job.settings
    m = s.models
    torch.set_num_threads(job.threads)
    data, output = job.input["high_quality"], job.output["model"]
    hq = rows_at_any(pd.read_parquet(data), s.train_alphas).reset_index(drop=True)
    if len(hq) < 2:
        labels = sorted(alpha_label(a) for a in s.train_alphas)
        raise ValueError(f"{data}: {len(hq)} high-quality row(s) at the training α {labels}; need ≥ 2")
    available = len(hq)
    hq = cap_per_alpha(hq, m.max_rows_per_alpha, s.seed)
    if s.fraction < 1.0:
        hq = subsample(hq, s.fraction, s.seed)
    cfg = TrainConfig(epochs=m.epochs, batch_size=m.batch_size, lr=m.learning_rate, seed=s.seed, device="cpu",
                      validation_fraction=m.validation_fraction, patience=m.patience)
    run.log_params({"rows": len(hq), "rows_available": available, "threads": job.threads})
    run.log_dataset(hq, data, "training")
    run.start_model(s.model, {"preset": m.preset, "fraction": s.fraction, **vars(cfg)})
    torch.manual_seed(s.seed)
    cpu0, wall0 = time.process_time(), time.perf_counter()
    epochs = []
    def on_epoch(epoch: int, metrics: dict) -> None:
        epochs.append(epoch)
        run.log_metrics(metrics, step=epoch)

    entry = get_model(s.model)
    model = entry.train(hq, m.preset, cfg, on_epoch)
    cpu_s, wall_s = time.process_time() - cpu0, time.perf_counter() - wall0
    with atomic_path(output) as tmp:
        entry.save(model, tmp)
    ran = len(epochs)
    write_json({"model": s.model, "seed": s.seed, "fraction": s.fraction, "rows": len(hq), "rows_available": available,
                "epochs": ran, "max_epochs": m.epochs, "threads": job.threads, "train_cpu_s": cpu_s,
                "train_wall_s": wall_s}, job.output["report"])
    run.log_metrics({"train_cpu_s": cpu_s, "train_wall_s": wall_s, "epochs_run": ran})
    run.finish_model(output, step=ran)  # the checkpoint as a logged model and under models/
    print(f"{output}: {s.model} trained {ran} of at most {m.epochs} epochs on {len(hq)} of {available} solutions")


def fraction_model_jobs(cfg: Config) -> list[dict[str, str]]:
    """Per data fraction: the GMM-CVAE (Fig. 18) and the models of the ablation's learning-curve arms."""
    if not cfg.cr3bp_models.enabled:
        return []
    from amorgs.ablation.arms import models_loaded

    curve = models_loaded(cfg.ablation.fraction_samplers) if cfg.ablation.enabled else []
    models = [m for m in CR3BP_MODELS if m == "cvae_gmm" or m in curve]
    return [{"fraction": layout.fraction_label(f), "model": m} for f in cfg.cr3bp_models.data_fractions for m in models]


def main_models(cfg: Config) -> list[str]:
    """The models of the main training seed: the paper's three (predictions, figures) and any other model
    an ablation arm loads (the reuse-conditioned CVAE only when its arm is in ``ablation.samplers``)."""
    if not cfg.cr3bp_models.enabled:
        return []
    needed = set(PAPER_MODELS) | set(replicate_models_needed(cfg))
    return [m for m in CR3BP_MODELS if m in needed]


def replicate_models_needed(cfg: Config) -> list[str]:
    """The models the ablation's arms load (only those are trained for the extra seeds)."""
    from amorgs.ablation.arms import models_loaded

    return models_loaded(cfg.ablation.samplers) if cfg.ablation.enabled else []


STAGE = 5
STEPS = (
    Step("train_cr3bp", TrainSettings, _settings, run_train,
         lambda cfg: [{"model": m} for m in main_models(cfg)],
         lambda w: _outputs(layout.CR3BP_MODEL.format_map(w)),
         resources=resources_of("train"),
         description="one CR3BP model on the high-quality rows at the training α → checkpoint"),
    Step("train_cr3bp_fraction", TrainSettings, _settings, run_train, fraction_model_jobs,
         lambda w: _outputs(layout.CR3BP_FRACTION_MODEL.format_map(w)),
         resources=resources_of("train"),
         description="a model on a seeded fraction of the rows of every training α (Fig. 18, learning curve)"),
    Step("train_cr3bp_replicate", TrainSettings, _settings, run_train,
         lambda cfg: [{"mseed": str(s), "model": m} for s in cfg.cr3bp_models.extra_seeds for m in replicate_models_needed(cfg)],
         lambda w: _outputs(layout.CR3BP_REPLICATE_MODEL.format_map(w)),
         resources=resources_of("train"),
         description="one model of an extra training seed (the ablation's replicates)"),
)
