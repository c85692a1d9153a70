"""The models as one table, :data:`MODELS` (one :class:`Model` per checkpoint), and their size presets — a light
registry (no torch import), so the config, the workflow rules, the arm table and the results layout take their
names from here.

CR3BP models (paper Sec. IV, Tables 4–5), one checkpoint ``<name>.pt`` each::

    cvae_gmm      GMM-prior CVAE on (τ_s, τ_i, τ_f, m_f) given α
    vanilla_cvae  standard-Gaussian CVAE on the whole decision vector given α
    lstm          control LSTM given (τ_s, τ_i, τ_f, m_f, α)

and one built to beat reuse (issue 21 §3), trained only when an ablation arm loads it::

    reuse_cvae    CVAE of a retrieved training-α solution's correction to the target α
                  (:mod:`amorgs.models.reuse_cvae`)

A :class:`Model` entry holds everything the package does with a model: its trainer, loader and saver as dotted
names ``"package.module:callable"``, resolved only when called (:func:`resolve`), so reading the table imports
no torch.  The train step, the arms' model loading, the shipped models and the tests all go through it: a new
learned arm is its model module, one :class:`Model` here and one ``Arm`` in :data:`amorgs.ablation.arms.ARMS`.

Presets pick layer widths: ``paper`` (Tables 4–5) or ``small`` (CPU-friendly) for the CR3BP models;
``dejong_paper`` (Table 3) or ``small`` for the De Jong GMM-prior CVAE.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

CR3BP_PRESETS = ("paper", "small")
DEJONG_PRESETS = ("dejong_paper", "small")

#: σ of the perturbed reuse arm (``nearest_alpha_perturbed``) in the box-normalised space (dimensionless): its
#: default in the arm's sampler, the arm inputs and the config (written here once).
PERTURBATION_SCALE = 0.02


def resolve(dotted: str) -> Any:
    """The object a ``"package.module:attr.attr"`` name points to (imports the module)."""
    module, _, qualname = dotted.partition(":")
    obj = importlib.import_module(module)
    for part in qualname.split("."):
        obj = getattr(obj, part)
    return obj


@dataclass(frozen=True)
class Model:
    """One CR3BP model: its checkpoint name and how it is trained, read and written.

    name: the checkpoint stem (``<name>.pt``), the ``{model}`` wildcard and the key arms load it by.
    trainer: ``(hq, preset, train_cfg, on_epoch) -> model`` on the high-quality rows of the training α
        (:mod:`amorgs.models.cr3bp_models` states the table's columns), returned on the CPU in eval mode.
    loader: ``(path) -> model`` (CPU, eval mode); ``ValueError`` naming the file if it holds another model.
    saver: ``(model, path) -> None``, the checkpoint the loader reads.
    paper: one of the paper's three, always trained (predictions, figures, shipped models); the others are
        trained only when an ablation arm loads them.
    """

    name: str
    description: str
    trainer: str
    loader: str
    saver: str
    paper: bool = False

    @property
    def checkpoint(self) -> str:
        """The checkpoint's file name inside a models directory."""
        return f"{self.name}.pt"

    def train(self, hq, preset: str, train_cfg, on_epoch: Callable[[int, dict], None] | None = None):
        return resolve(self.trainer)(hq, preset, train_cfg, on_epoch)

    def save(self, model, path: str | Path) -> None:
        resolve(self.saver)(model, path)

    def load(self, models_dir: str | Path):
        """The model from its checkpoint in ``models_dir``; ``FileNotFoundError`` naming the file if missing."""
        path = Path(models_dir) / self.checkpoint
        if not path.is_file():
            raise FileNotFoundError(f"{path}: checkpoint of the {self.name!r} model not found")
        return resolve(self.loader)(path)


_TRAINERS = "amorgs.models.cr3bp_models"

MODELS: tuple[Model, ...] = (
    Model("cvae_gmm", "GMM-prior CVAE of (τ_s, τ_i, τ_f, m_f) given α (paper Table 4)",
          f"{_TRAINERS}:train_time_mass_cvae", "amorgs.models.cvae:load_gmm_prior_cvae", "amorgs.models.cvae:save",
          paper=True),
    Model("vanilla_cvae", "standard-Gaussian CVAE of the whole decision vector given α (paper Table 5)",
          f"{_TRAINERS}:train_vanilla_cvae", "amorgs.models.cvae:load_vanilla_cvae", "amorgs.models.cvae:save",
          paper=True),
    Model("lstm", "control LSTM given (τ_s, τ_i, τ_f, m_f, α) (paper Table 4)",
          f"{_TRAINERS}:train_control_lstm", "amorgs.models.lstm:load", "amorgs.models.lstm:save", paper=True),
    # issue 21 §3: trained only when an arm loads it
    Model("reuse_cvae", "CVAE of a retrieved training-α solution's correction to the target α",
          "amorgs.models.reuse_cvae:train_reuse_cvae", "amorgs.models.reuse_cvae:load", "amorgs.models.cvae:save"),
)

#: Name → model.
BY_NAME: dict[str, Model] = {m.name: m for m in MODELS}
CR3BP_MODELS: tuple[str, ...] = tuple(BY_NAME)
#: The paper's three models: always trained (the prediction figures and the shipped models use them).
PAPER_MODELS: tuple[str, ...] = tuple(m.name for m in MODELS if m.paper)
#: Model name → checkpoint file name inside a models directory (written by the train step).
CHECKPOINTS: dict[str, str] = {m.name: m.checkpoint for m in MODELS}


def get_model(name: str) -> Model:
    """The table's entry ``name``; ``ValueError`` listing the known models otherwise."""
    try:
        return BY_NAME[name]
    except KeyError:
        raise ValueError(f"unknown model {name!r}; choose one of {', '.join(CR3BP_MODELS)}") from None


def load_model(models_dir: str | Path, name: str):
    """The model ``name`` from its checkpoint in ``models_dir`` (:meth:`Model.load`)."""
    return get_model(name).load(models_dir)
