"""The ablation's arms (initial-guess samplers) as one table, :data:`ARMS`: one :class:`Arm` per arm.

An entry says everything the package asks about an arm: its name (the ``{sampler}`` wildcard, the config's
``ablation.samplers``, the ``sampler`` column of the cell tables), its label (figures and tables), the
checkpoints it loads, whether it draws on the high-quality table of the training α (and whether it reuses that
table's rows as a finite pool), its role in the statistics, whether it is one of the paper's five, and how it
is built.  Everything else — the config's enums, the workflow's wildcard constraints and inputs, the models
trained for replicates and learning curves, the up-front CPU of the break-even table, the statistics' default
baselines, the order and labels of the figures — is derived from this table.

The builder is a dotted name ``"package.module:callable"`` resolved only by :func:`build_sampler`, so this
module imports neither torch nor the models: the config, the workflow and the figures read the table freely.
A builder is called as ``builder(problem, inputs)`` with an :class:`ArmInputs` and returns a sampler
(``sample(alpha, n, rng) -> ndarray (n, 3N+4)``, :mod:`amorgs.models.samplers`).

Adding an arm (a diffusion sampler, say): write the sampler class and its builder in a model module (a new
``amorgs/models/<arm>.py`` or :mod:`amorgs.models.samplers`), then add one :class:`Arm` to :data:`ARMS`.  If it
loads a model nobody trains yet, its trainer, loader and saver live in its model module and the model gets one
entry in the model table (:data:`amorgs.models.names.MODELS`).
``tests/unit/test_arms.py`` then builds and samples it with everything else; regenerate the config schema
(``amorgs config-schema --write``), whose sampler enum comes from here.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from amorgs.models.names import PERTURBATION_SCALE, get_model, resolve

#: Roles in the statistics (:mod:`amorgs.ablation.statistics`, :mod:`amorgs.ablation.running_time`).  One arm each holds ``baseline``, ``reuse`` and
#: ``headline``; every other arm is ``compared`` against them.
ROLES = {
    "baseline": "uniform multi-start: every speed-up, ratio of rates and break-even divides by it",
    "reuse": "reuse of known solutions: the versus_reuse ratios divide by it",
    "headline": "the paper's method: its median high-quality solve time is the Fig. 22 time cap and the "
                "numerator of the search acceleration; Fig. 23 draws its samples",
    "compared": "compared against the three above",
}


@dataclass(frozen=True)
class Arm:
    """One arm of the ablation.

    name: identifier (wildcard, config value, ``sampler`` column).   label: for figures and tables.
    builder: ``"package.module:callable"``, called as ``builder(problem, inputs: ArmInputs) -> sampler``.
    models: the checkpoints it loads (names of :data:`amorgs.models.names.CR3BP_MODELS`; none: model-free).
    high_quality: it needs the filtered high-quality table and the training α (rows at the training α only).
    pooled: its guesses are rows of that table, a finite pool: its cells of every model seed are slices of
        ONE seeded draw, so the pooled starts are drawn without replacement until the pool is exhausted.
    transfer: it loads the transfer selector trained on the run's transfer data (``transfer.enabled``;
        :mod:`amorgs.models.selector`, :data:`amorgs.layout.SELECTOR_MODEL`), as ``inputs.models["selector"]``.
    role: its role in the statistics, a key of :data:`ROLES`.   paper: one of the paper's five (Table 6).
    rng_free: its guesses are the same for every generator (one fixed order, e.g. a selector's ranking), so
        searches that differ only in their seed start from the same guesses.
    """

    name: str
    label: str
    builder: str
    models: tuple[str, ...] = ()
    high_quality: bool = False
    pooled: bool = False
    transfer: bool = False
    role: str = "compared"
    paper: bool = False
    rng_free: bool = False

    @property
    def learned(self) -> bool:
        """Whether it loads trained models (the arms a learning curve over data fractions applies to)."""
        return bool(self.models)

    @property
    def upfront(self) -> bool:
        """Whether it draws on anything computed before the first new α (the training-α solves, models)."""
        return self.high_quality or self.learned or self.transfer


_SAMPLERS = "amorgs.models.samplers"
_BASELINES = "amorgs.models.baselines"  # the model-free samplers: building them imports no torch

ARMS: tuple[Arm, ...] = (
    Arm("uniform", "Uniform", f"{_BASELINES}:UniformSampler.build", role="baseline", paper=True),
    Arm("cvae_uniform_control", "CVAE time & mass, uniform control", f"{_SAMPLERS}:CVAETimeMassUniformControl.build",
        models=("cvae_gmm",), paper=True),
    Arm("uniform_lstm_control", "Uniform time & mass, LSTM control", f"{_SAMPLERS}:UniformTimeMassLSTMControl.build",
        models=("lstm",), paper=True),
    Arm("vanilla_cvae", "Vanilla CVAE", f"{_SAMPLERS}:VanillaCVAESampler.build", models=("vanilla_cvae",),
        paper=True),
    Arm("amorgs", "AmorGS", f"{_SAMPLERS}:AmorGSSampler.build", models=("cvae_gmm", "lstm"), role="headline",
        paper=True),
    Arm("nearest_alpha", "Nearest training α, reused", f"{_BASELINES}:NearestAlphaSampler.build",
        high_quality=True, pooled=True, role="reuse"),
    Arm("nearest_alpha_perturbed", "Nearest training α + noise", f"{_BASELINES}:NearestAlphaPerturbedSampler.build",
        high_quality=True, pooled=True),
    Arm("gmm_lstm", "GMM time & mass, LSTM control", f"{_SAMPLERS}:GMMLSTMSampler.build", models=("lstm",),
        high_quality=True),
    # issue 21 §3: reuse moved along α by a secant between neighbouring training α (built to beat reuse)
    Arm("continuation", "Nearest training α moved by a secant in α", f"{_BASELINES}:ContinuationSampler.build",
        high_quality=True, pooled=True),
    # issue 21 §3: reuse's retrieved solutions, each corrected to α by a CVAE conditioned on it
    Arm("reuse_cvae", "Nearest training α + learned correction (reuse-conditioned CVAE)",
        "amorgs.models.reuse_cvae:ReuseCVAESampler.build", models=("reuse_cvae",), high_quality=True, pooled=True),
    # issue 38 §2: every training α's solutions, in the order a selector trained on transfer data ranks them
    Arm("selector", "Known solutions ranked by a learned transfer selector", "amorgs.models.selector:SelectorSampler.build",
        high_quality=True, pooled=True, transfer=True, rng_free=True),
    # issue 41: the same candidates in a random order weighted by the selector (independent global searches)
    Arm("selector_sampled", "Known solutions drawn in proportion to the transfer selector's predicted rate",
        "amorgs.models.selector:SampledSelectorSampler.build", high_quality=True, pooled=True, transfer=True),
    # issue 38 §3: AmorGS draws several times the budget, the selector picks which proposals to solve
    Arm("amorgs_selected", "AmorGS proposals ranked by the transfer selector",
        "amorgs.models.selector:SelectedProposalSampler.build_amorgs", models=("cvae_gmm", "lstm"), transfer=True),
)

#: Name → arm.
BY_NAME: dict[str, Arm] = {arm.name: arm for arm in ARMS}
#: Every arm's name, in table order (the order of figures and tables).
SAMPLER_NAMES: tuple[str, ...] = tuple(BY_NAME)
#: The arms a config runs unless it names its own: every arm but those that need the transfer data.
DEFAULT_SAMPLER_NAMES: tuple[str, ...] = tuple(arm.name for arm in ARMS if not arm.transfer)
#: The arms that load models.
LEARNED_SAMPLER_NAMES: tuple[str, ...] = tuple(arm.name for arm in ARMS if arm.learned)


def _the(role: str) -> str:
    holders = [arm.name for arm in ARMS if arm.role == role]
    if len(holders) != 1:
        raise RuntimeError(f"exactly one arm must have the role {role!r}, got {holders}")
    return holders[0]


#: The arms of the three roles the statistics take as their defaults.
BASELINE_ARM = _the("baseline")
REUSE_ARM = _the("reuse")
HEADLINE_ARM = _the("headline")


def get_arm(name: str) -> Arm:
    """The arm called ``name``; ``ValueError`` naming the choices otherwise."""
    if name not in BY_NAME:
        raise ValueError(f"unknown sampler {name!r}; choose one of {SAMPLER_NAMES}")
    return BY_NAME[name]


def arm_label(name: str) -> str:
    """The arm's label, or ``name`` itself for a name not in the table."""
    return BY_NAME[name].label if name in BY_NAME else name


def models_loaded(samplers: Iterable[str]) -> list[str]:
    """The checkpoints any of ``samplers`` loads, sorted (none for uniform and the reuse baselines)."""
    return sorted({m for s in samplers for m in get_arm(s).models})


# ---------------------------------------------------------------------------------------- building one


@dataclass(frozen=True)
class ArmInputs:
    """What a builder gets besides the problem.

    models: model name → the loaded model, exactly the arm's ``models``.
    high_quality: the filtered high-quality table (arms with ``high_quality``; None otherwise).
    train_alphas: the training α, the only α whose rows may be used (arms with ``high_quality``).
    perturbation_scale: σ of the perturbed reuse arm, in the box-normalised space (dimensionless).
    gmm_components: mixture components per training α of the GMM arm.
    selection_oversample: proposals drawn per start by the arms that select among a generator's proposals.
    """

    models: Mapping[str, Any]
    high_quality: Any = None
    train_alphas: tuple[float, ...] | None = None
    perturbation_scale: float = PERTURBATION_SCALE
    gmm_components: int = 5
    selection_oversample: int = 5


def build_sampler(
    name: str,
    problem,
    models_dir: str | Path | None = None,
    high_quality=None,
    train_alphas=None,
    perturbation_scale: float = PERTURBATION_SCALE,
    gmm_components: int = 5,
    selector: str | Path | None = None,
    selection_oversample: int = 5,
):
    """The sampler of arm ``name`` for ``problem``: its models loaded (on the CPU) from the checkpoints in
    ``models_dir`` (the model table's loaders, :data:`amorgs.models.names.MODELS`), the high-quality table and training α handed
    over if it needs them, and for a ``transfer`` arm the selector file ``selector`` (default: the one in
    ``models_dir``).  ``ValueError`` for an unknown arm or a missing input; ``FileNotFoundError`` for a missing
    checkpoint."""
    arm = get_arm(name)
    if (arm.models or (arm.transfer and selector is None)) and models_dir is None:
        raise ValueError(f"sampler {name!r} needs a models directory")
    if arm.high_quality and (high_quality is None or train_alphas is None):
        raise ValueError(f"sampler {name!r} needs the high-quality table and the training α")
    models = {}
    if arm.models:
        models = {m: get_model(m).load(models_dir) for m in arm.models}
    if arm.transfer:
        from amorgs.models.selector import SELECTOR_FILE, TransferSelector

        path = Path(selector) if selector is not None else Path(models_dir) / SELECTOR_FILE
        if not path.is_file():
            raise FileNotFoundError(f"{path}: transfer selector not found (sampler {name!r} needs one: "
                                    "transfer.enabled, the train_selector step)")
        models["selector"] = TransferSelector.load(path)
    inputs = ArmInputs(models=models, high_quality=high_quality if arm.high_quality else None,
                       train_alphas=tuple(train_alphas) if arm.high_quality else None,
                       perturbation_scale=perturbation_scale, gmm_components=gmm_components,
                       selection_oversample=selection_oversample)
    return resolve(arm.builder)(problem, inputs)
