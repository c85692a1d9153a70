"""The registry of ablation arms (samplers): names, labels and what each needs — no torch import, so the
config, the workflow and the figures can use it.  The implementations live in
:mod:`amorgs.models.samplers`.
"""

from __future__ import annotations

#: The paper's five arms (Sec. V.B.7, Table 6).
PAPER_SAMPLER_NAMES = ("uniform", "cvae_uniform_control", "uniform_lstm_control", "vanilla_cvae", "amorgs")
#: Arms added to ask whether learning beats reusing known solutions (issue 11).
BASELINE_SAMPLER_NAMES = ("nearest_alpha", "nearest_alpha_perturbed", "gmm_lstm")
#: Arms built to beat reuse (issue 21 §3).
BEAT_REUSE_SAMPLER_NAMES = ("continuation",)
SAMPLER_NAMES = PAPER_SAMPLER_NAMES + BASELINE_SAMPLER_NAMES + BEAT_REUSE_SAMPLER_NAMES
SAMPLER_LABELS = {
    "uniform": "Uniform",
    "uniform_lstm_control": "Uniform time & mass, LSTM control",
    "cvae_uniform_control": "CVAE time & mass, uniform control",
    "vanilla_cvae": "Vanilla CVAE",
    "amorgs": "AmorGS",
    "nearest_alpha": "Nearest training α, reused",
    "nearest_alpha_perturbed": "Nearest training α + noise",
    "gmm_lstm": "GMM time & mass, LSTM control",
    "continuation": "Nearest training α moved by a secant in α",
}
#: Arms that read the filtered high-quality table (restricted to the training α).
NEEDS_HIGH_QUALITY = BASELINE_SAMPLER_NAMES + ("continuation",)
#: Arms that reuse that table's rows as guesses, drawn from a finite pool (issue 21): their cells of every
#: model seed are slices of ONE seeded draw, so the pooled starts are drawn without replacement until the
#: pool is exhausted.
REUSE_SAMPLER_NAMES = ("nearest_alpha", "nearest_alpha_perturbed", "continuation")
#: Arm → the checkpoints (keys of ``amorgs.models.samplers.CHECKPOINTS``) it loads.
NEEDS_MODELS = {
    "uniform": (),
    "cvae_uniform_control": ("cvae_gmm",),
    "uniform_lstm_control": ("lstm",),
    "vanilla_cvae": ("vanilla_cvae",),
    "amorgs": ("cvae_gmm", "lstm"),
    "nearest_alpha": (),
    "nearest_alpha_perturbed": (),
    "gmm_lstm": ("lstm",),
    "continuation": (),
}


def models_loaded(samplers) -> list[str]:
    """The checkpoints any of ``samplers`` loads, sorted (none for uniform and the reuse baselines)."""
    return sorted({m for s in samplers for m in NEEDS_MODELS[s]})
