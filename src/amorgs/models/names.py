"""The names of the models and their size presets — a light registry (no torch import), so the config, the
workflow rules and the results layout take their names from here.

CR3BP models (paper Sec. IV, Tables 4–5), one checkpoint ``<name>.pt`` each::

    cvae_gmm      GMM-prior CVAE on (τ_s, τ_i, τ_f, m_f) given α
    vanilla_cvae  standard-Gaussian CVAE on the whole decision vector given α
    lstm          control LSTM given (τ_s, τ_i, τ_f, m_f, α)

and one built to beat reuse (issue 21 §3), trained only when an ablation arm loads it::

    reuse_cvae    CVAE of a retrieved training-α solution's correction to the target α
                  (:mod:`amorgs.models.reuse_cvae`)

Presets pick layer widths: ``paper`` (Tables 4–5) or ``small`` (CPU-friendly) for the CR3BP models;
``dejong_paper`` (Table 3) or ``small`` for the De Jong GMM-prior CVAE.
"""

from __future__ import annotations

#: The paper's three models: always trained (the prediction figures and the shipped models use them).
PAPER_MODELS = ("cvae_gmm", "vanilla_cvae", "lstm")
CR3BP_MODELS = (*PAPER_MODELS, "reuse_cvae")
#: Model name → checkpoint file name inside a models directory (written by the train step).
CHECKPOINTS = {name: f"{name}.pt" for name in CR3BP_MODELS}
CR3BP_PRESETS = ("paper", "small")
DEJONG_PRESETS = ("dejong_paper", "small")


#: σ of the perturbed reuse arm (``nearest_alpha_perturbed``) in the box-normalised space (dimensionless): its
#: default in the arm's sampler, the arm inputs and the config (written here once).
PERTURBATION_SCALE = 0.02
