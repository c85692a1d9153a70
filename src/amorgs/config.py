"""The workflow configuration: one typed model (pydantic) that is the schema and holds every default.

The defaults of :class:`Config` are the main job (a plain ``snakemake``; each problem's ``solver`` and
``filter`` sections are its family's types, with the family's defaults — :mod:`amorgs.problems`: the options of
:mod:`amorgs.solvers.options`, the quality filters of the families —, ``cr3bp_analysis.params`` from
:class:`amorgs.analysis.structure_params.StructureParams`).  A config file holds only what its experiment
changes: it is merged over the defaults (:func:`effective_mapping`) — nested mappings key by key, anything
else (a list, a number, a string, null) replaces the default — and the merged mapping is validated.  No other
key is allowed.  What runs, is hashed (:attr:`Config.hash`) and is recorded (MLflow, the library's and the
models' manifests) is always that merged, *effective* config.  The JSON Schema
``workflow/schemas/config.schema.json`` is *generated* from these models (``amorgs config-schema --write``; a
test keeps it current), so types, ranges, enums, defaults and descriptions are written once, here.  Enums come
from the registries: samplers from :mod:`amorgs.ablation.arms`, problems (and each one's α range) from
:data:`amorgs.problems.FAMILIES`, presets from :mod:`amorgs.models.names`.

Checking happens at load, before any job: the model (types, ranges, enums, unknown keys), then the
cross-field rules (:meth:`Config._cross_field_rules`: α inside each problem's range and distinct at three
decimals, stages enabled together, iteration caps ≤ ``max_iter``).  Every failure is one
:class:`ConfigError` whose lines name the file and the dotted key, e.g.
``config/smoke.yaml: problems.dejong.generate.startz: unknown key``.

α identity: :func:`amorgs.alphas.alpha_label` (three decimals, ``0.150``) in paths, wildcards and keys; the
exact float behind each label is kept here and passed to the solver.
"""

from __future__ import annotations

import copy
import hashlib
import json
from pathlib import Path
from typing import Annotated, Literal

import numpy as np
import yaml
from pydantic import BaseModel, ConfigDict, Field, StrictBool, ValidationError, field_validator, model_validator

from amorgs.ablation.arms import DEFAULT_SAMPLER_NAMES, HEADLINE_ARM, LEARNED_SAMPLER_NAMES, SAMPLER_NAMES, get_arm
from amorgs.alphas import alpha_label
from amorgs.analysis.structure_params import StructureParams
from amorgs.errors import ConfigError
from amorgs.models.names import CR3BP_PRESETS, DEJONG_PRESETS, PERTURBATION_SCALE
from amorgs.problems import FAMILIES
from amorgs.problems.cr3bp import Cr3bpFilter
from amorgs.problems.dejong import DejongFilter
from amorgs.solvers.basin_hopping import HOP_DISTRIBUTIONS, STRATEGIES, HopSettings
from amorgs.solvers.options import BfgsOptions, IpoptOptions

#: The generated JSON Schema, relative to the repository root (the working directory of workflow and CLI).
SCHEMA_PATH = Path("workflow/schemas/config.schema.json")
#: The config a plain ``snakemake`` (no ``--configfile``) runs: ``{}``, the typed defaults.
DEFAULT_CONFIG = Path("config/default.yaml")

PositiveInt = Annotated[int, Field(ge=1)]
Seed = Annotated[int, Field(ge=0, description="random seed (≥ 0)")]
PositiveFloat = Annotated[float, Field(gt=0)]
#: A switch: true or false only (a quoted "yes" is an error, not True).
Flag = StrictBool


class Section(BaseModel):
    """A config section: frozen, no unknown keys.  A field without a default here gets one from the section
    that holds it (e.g. each problem's ``generate``), so that every key of :class:`Config` has a default."""

    model_config = ConfigDict(extra="forbid", frozen=True)


def _unique(values: tuple) -> tuple:
    if len(set(values)) != len(values):
        raise ValueError(f"values must be unique, got {list(values)}")
    return values


# --------------------------------------------------------------------------------------------- sections


class AlphaGrid(Section):
    """``num`` evenly spaced α from ``start`` to ``stop``, both included (numpy.linspace)."""

    start: float
    stop: float
    num: PositiveInt

    def values(self) -> tuple[float, ...]:
        return tuple(float(a) for a in np.linspace(self.start, self.stop, self.num))


class Alphas(Section):
    """α values solved by the generate stage: ``train`` (a list or a grid) and held-out ``test``."""

    train: Annotated[tuple[float, ...], Field(min_length=1)] | AlphaGrid = Field(
        description="training α: a list, or {start, stop, num} (numpy.linspace)")
    test: tuple[float, ...] = Field(description="held-out α: generated for the ground truth, never trained on")

    def train_values(self) -> tuple[float, ...]:
        return self.train.values() if isinstance(self.train, AlphaGrid) else self.train


class Job(Section):
    """Resources of one job: ``threads`` (cores), ``mem_mb`` (MB), ``runtime_min`` (wall minutes)."""

    threads: PositiveInt
    mem_mb: PositiveInt
    runtime_min: PositiveInt


class Generate(Section):
    """Per α: ``shards`` jobs × ``starts_per_shard`` uniform starts, ``workers`` solver processes per job
    (= the job's threads), with the job's ``mem_mb`` (MB) and ``runtime_min`` (minutes)."""

    shards: PositiveInt
    starts_per_shard: PositiveInt
    workers: PositiveInt
    mem_mb: PositiveInt
    runtime_min: PositiveInt

    def job(self) -> Job:
        """The resources of one generate job: ``workers`` threads, ``mem_mb`` MB, ``runtime_min`` minutes."""
        return Job(threads=self.workers, mem_mb=self.mem_mb, runtime_min=self.runtime_min)


class Library(Section):
    """The versioned solution library: with ``enabled``, the merge of every α also takes the committed files
    under ``path``/{problem}/alpha={label}/ (:mod:`amorgs.data.library`) — all of them, or with
    ``max_rows_per_alpha`` a fixed slice of the first rows in (shard, start) order."""

    enabled: Flag
    path: Annotated[str, Field(min_length=1, description="library root, relative to the working directory")]
    max_rows_per_alpha: PositiveInt | None = Field(
        description="null: every library row of each α; a number: only the first rows (a fixed slice)")


class ProblemConfig(Section):
    """What the generate → merge → filter stages do for one problem; a subclass per family adds its ``solver``
    (the family's ``options_type``) and its ``filter`` (the family's ``quality_type``)."""

    enabled: Flag
    alphas: Alphas
    generate: Generate
    library: Library

    def alpha_values(self) -> dict[str, float]:
        """Label → α for every generated α (train, then test), in config order."""
        return {alpha_label(a): a for a in (*self.alphas.train_values(), *self.alphas.test)}


class DejongConfig(ProblemConfig):
    solver: BfgsOptions = Field(description="scipy BFGS options (amorgs.solvers.options.BfgsOptions)")
    filter: DejongFilter = Field(description="what high quality means (amorgs.problems.dejong.DejongFilter)")


class Cr3bpConfig(ProblemConfig):
    solver: IpoptOptions = Field(description="IPOPT options (amorgs.solvers.options.IpoptOptions)")
    filter: Cr3bpFilter = Field(description="β: what high quality means (amorgs.problems.cr3bp.Cr3bpFilter)")


#: Where the committed solution library lives (``problems.<name>.library.path``).
LIBRARY_PATH = "data/library"


class Problems(Section):
    """The problem families (one field per family of :data:`amorgs.problems.FAMILIES`, of its name), each with
    the defaults of the main job: its solver options and quality filter at the family's defaults."""

    #: De Jong's 5th function rotated by α (spec §7, paper Sec. V.A): the grid iπ/100, i = 0 … 50, tested at
    #: π/9, 2π/9, π/3, 4π/9; minima of the holes have J ≈ 1, stationary points on the plateau J ≈ 500.
    dejong: DejongConfig = DejongConfig(
        enabled=True,
        alphas=Alphas(train=AlphaGrid(start=0.0, stop=1.5707963267948966, num=51),
                      test=(0.3490658503988659, 0.6981317007977318, 1.0471975511965976, 1.3962634015954636)),
        generate=Generate(shards=1, starts_per_shard=200, workers=1, mem_mb=2000, runtime_min=30),
        library=Library(enabled=False, path=LIBRARY_PATH, max_rows_per_alpha=None),
        solver=BfgsOptions(),
        filter=DejongFilter(),
    )
    #: Low-thrust GTO → L1-halo transfer (spec §1–6, paper Sec. V.B): the paper's 12 training and 2 test α;
    #: the whole library merged with a fresh slice of 8 starts per α (column ``source``); β of the paper.
    cr3bp: Cr3bpConfig = Cr3bpConfig(
        enabled=True,
        alphas=Alphas(train=(0.1, 0.13, 0.16, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9, 1.0), test=(0.15, 0.85)),
        generate=Generate(shards=1, starts_per_shard=8, workers=2, mem_mb=4000, runtime_min=120),
        library=Library(enabled=True, path=LIBRARY_PATH, max_rows_per_alpha=None),
        solver=IpoptOptions(),
        filter=Cr3bpFilter(),
    )

    def enabled(self) -> dict[str, ProblemConfig]:
        """Name → section of every enabled problem."""
        return {name: getattr(self, name) for name in type(self).model_fields if getattr(self, name).enabled}


class Mlflow(Section):
    """Mirror runs to MLflow in experiment ``experiment``; ``tracking_uri`` null means the SQLite store under
    ``results/mlflow``; the ``MLFLOW_TRACKING_URI`` environment variable overrides both."""

    enabled: Flag = True
    experiment: Annotated[str, Field(min_length=1)] = "amorgs"
    tracking_uri: Annotated[str, Field(min_length=1)] | None = None


class Resources(Section):
    """Job resources of the rules other than generate and the ablation cells."""

    merge: Job = Job(threads=1, mem_mb=2000, runtime_min=10)
    filter: Job = Job(threads=1, mem_mb=4000, runtime_min=30)
    train: Job = Job(threads=2, mem_mb=8000, runtime_min=240)
    predict: Job = Job(threads=1, mem_mb=4000, runtime_min=30)
    figure: Job = Job(threads=1, mem_mb=2000, runtime_min=10)
    analyze: Job = Job(threads=1, mem_mb=4000, runtime_min=30)


def _needs_validation_share(section):
    """``patience`` needs a held-out share to watch (``validation_fraction`` > 0)."""
    if section.patience and not section.validation_fraction:
        raise ValueError(f"patience {section.patience} needs validation_fraction > 0 (the held-out rows it watches)")
    return section


class DejongCVAE(Section):
    """The GMM-prior CVAE on the De Jong minima (paper Sec. V.A, Table 3): ``preset`` widths; Adam with
    ``learning_rate`` for ``epochs`` epochs of ``batch_size`` rows; ``seed`` fixes weights, shuffling and
    sampling; ``n_samples`` samples per test α scored against the true minima within ``radius`` (units of x)."""

    enabled: Flag = True
    #: Table 3 encoder/decoder, K = 2, 2-D latent, except a (64, 64) prior network: the full (512³) prior
    #: trained worse.  Measured (tests/integration/test_dejong_amortized.py recipe): full batch, lr 5e-3,
    #: 1500 epochs → 97.7–98.6 % within 3 units, 8/8 minima at all 4 test α; mini-batches of 64–512 with batch
    #: norm reached only 50–97 %.
    preset: Literal[DEJONG_PRESETS] = "small"  # type: ignore[valid-type]
    learning_rate: PositiveFloat = 5.0e-3
    epochs: PositiveInt = 1500
    batch_size: Annotated[int, Field(ge=2)] = 16384
    seed: Seed = 7
    max_rows_per_alpha: PositiveInt | None = Field(None, description=(
        "train on at most this many minima of each training α, a seeded sample (the seed's; null: every row)"))
    validation_fraction: Annotated[float, Field(ge=0, lt=1, description=(
        "share of the minima held out, seeded, for the validation loss of early stopping (0: none)"))] = 0.0
    patience: Annotated[int, Field(ge=0, description=(
        "stop after this many epochs without a better validation loss and keep the best epoch's weights "
        "(0: train every epoch; needs validation_fraction)"))] = 0
    n_samples: PositiveInt = 1000  # per test α, as in Fig. 16b
    radius: PositiveFloat = 3.0  # a sample within 3 units of a true minimum is a hit

    _early_stopping = model_validator(mode="after")(_needs_validation_share)


class Cr3bpAnalysis(Section):
    """The structure analysis of the CR3BP solutions (paper Sec. III.B, Figs. 3–13)."""

    enabled: Flag = True
    params: StructureParams = Field(StructureParams(), description="StructureParams fields ({}: its defaults)")


class Cr3bpModels(Section):
    """The three CR3BP generative models (paper Sec. IV, Tables 4–5), trained on the training α only:
    ``preset`` widths; Adam with ``learning_rate`` for ``epochs`` epochs of ``batch_size`` rows; ``seed``
    fixes weights, shuffling, subsampling and sampling; ``extra_seeds``: further training seeds whose models
    serve the ablation's replicates; ``data_fractions``: extra GMM-CVAEs on these fractions (Fig. 18);
    ``n_samples``: samples per test α (Figs. 17–20)."""

    enabled: Flag = True
    preset: Literal[CR3BP_PRESETS] = "small"  # type: ignore[valid-type]
    epochs: PositiveInt = 500  # full batch, Adam 5e-3 on the CPU
    batch_size: Annotated[int, Field(ge=2)] = 4096
    learning_rate: PositiveFloat = 5.0e-3
    seed: Seed = 11
    extra_seeds: tuple[Seed, ...] = ()
    data_fractions: tuple[Annotated[float, Field(gt=0, lt=1)], ...] = (0.1, 0.5)  # Fig. 18
    n_samples: PositiveInt = 1000  # per test α, Figs. 17–20
    max_rows_per_alpha: PositiveInt | None = Field(None, description=(
        "train on at most this many high-quality rows of each training α, a seeded sample (the seed's); the "
        "data fractions are taken of that sample (null: every row)"))
    validation_fraction: Annotated[float, Field(ge=0, lt=1, description=(
        "share of the training rows held out, seeded, for the validation loss of early stopping (0: none)"))] = 0.0
    patience: Annotated[int, Field(ge=0, description=(
        "stop after this many epochs without a better validation loss and keep the best epoch's weights "
        "(0: train every epoch; needs validation_fraction)"))] = 0

    _unique_seeds = field_validator("extra_seeds", "data_fractions")(_unique)
    _early_stopping = model_validator(mode="after")(_needs_validation_share)

    @property
    def seeds(self) -> tuple[int, ...]:
        """Every model-training seed: ``seed`` (models under results/cr3bp/models/) then ``extra_seeds``."""
        return (self.seed, *self.extra_seeds)


class Ablation(Section):
    """The warm-start ablation at the CR3BP test α (paper Sec. V.B.7, Table 6; issue 11): per (test α,
    sampler, model seed) one job solving ``n_starts`` guesses with ``workers`` processes and the CR3BP solver
    options; ``perturbation_scale`` is σ of nearest_alpha_perturbed (box-normalised), ``gmm_components`` the
    mixture size of gmm_lstm per training α, ``iteration_caps`` the Fig. 22 caps fixed before the solves,
    ``beta_sweep_kg`` extra β (kg) of the rate sweep, ``n_boot`` bootstrap resamples, ``break_even_solutions``
    the high-quality solutions wanted per new α of the break-even table (issue 11 §5), ``fraction_samplers``
    the learned arms of the learning curve (issue 11 §4)."""

    enabled: Flag = True
    #: Every arm of the table (:data:`amorgs.ablation.arms.ARMS`) but those that need the transfer data
    #: (``selector``, ``amorgs_selected``: name them, with ``transfer.enabled``).
    samplers: Annotated[tuple[Literal[SAMPLER_NAMES], ...], Field(min_length=1)] = DEFAULT_SAMPLER_NAMES  # type: ignore[valid-type]
    n_starts: PositiveInt = 24
    seed: Seed = 13
    workers: PositiveInt = 2
    mem_mb: PositiveInt = 4000
    runtime_min: PositiveInt = 60
    perturbation_scale: Annotated[float, Field(ge=0)] = PERTURBATION_SCALE  # σ in the box-normalised space
    gmm_components: PositiveInt = 5  # mixture components per training α
    selection_oversample: PositiveInt = Field(
        5, description="proposals drawn per start by amorgs_selected: the transfer selector solves the best "
                       "1/selection_oversample of them (issue 38 §3)")
    iteration_caps: tuple[PositiveInt, ...] = (25, 50, 100, 200, 400, 1000)  # fixed before the solves, ≤ max_iter
    beta_sweep_kg: tuple[float, ...] = (425.0, 430.0, 435.0)  # the filter's β is always included
    n_boot: PositiveInt = 2000
    break_even_solutions: tuple[PositiveInt, ...] = Field(
        (10, 100), description="high-quality solutions wanted per new α in the break-even table (none: no table)")
    fraction_samplers: tuple[Literal[LEARNED_SAMPLER_NAMES], ...] = Field(  # type: ignore[valid-type]
        (HEADLINE_ARM,), description="learned arms run again with the models of every cr3bp_models.data_fractions "
                                 "(the learning curve of the ablation's expected running time; none: no curve)")

    _unique_lists = field_validator("samplers", "iteration_caps", "beta_sweep_kg", "break_even_solutions",
                                    "fraction_samplers")(_unique)

    def job(self) -> Job:
        """The resources of one cell job: ``workers`` threads, ``mem_mb`` MB, ``runtime_min`` minutes."""
        return Job(threads=self.workers, mem_mb=self.mem_mb, runtime_min=self.runtime_min)


class Transfer(Section):
    """Transfer data (issue 38 §1): the high-quality solutions of one CR3BP training α solved as warm starts at
    another training α — never a test α —, for every ordered pair (α_from → α_to) with |α_to − α_from| / α_to ≤
    ``max_relative_gap``, both directions; per pair ``shards`` jobs of ``starts_per_pair`` solutions each, drawn
    as the reuse arm draws (without replacement while the pool lasts), seeded from ``seed``, solved with the
    CR3BP solver options (those of the ablation: warm starts) by ``workers`` processes.  Each row is labelled
    with what the solve gave (status, iterations, m_f, the landing solution): the selector's training data."""

    enabled: Flag = False
    max_relative_gap: Annotated[float, Field(gt=0, description=(
        "pairs (α_from → α_to) of training α with |α_to − α_from| / α_to at most this"))] = 0.7
    starts_per_pair: PositiveInt = 12
    shards: PositiveInt = 1
    seed: Seed = 19
    workers: PositiveInt = 1
    mem_mb: PositiveInt = 4000
    runtime_min: PositiveInt = 60

    def job(self) -> Job:
        """The resources of one transfer job: ``workers`` threads, ``mem_mb`` MB, ``runtime_min`` minutes."""
        return Job(threads=self.workers, mem_mb=self.mem_mb, runtime_min=self.runtime_min)


#: The hop defaults (:class:`~amorgs.solvers.basin_hopping.HopSettings`), the one place they are written.
HOPS = HopSettings()


class GlobalSearch(Section):
    """Global search at the CR3BP test α (issue 41): per (test α, strategy, sampler) one job running ``searches``
    seeded searches of ``budget`` IPOPT iterations each — multi-start, or monotonic basin hopping from the
    sampler's starts (hops of ``hop_distribution`` × ``hop_scale`` of each variable's box width, Pareto tail
    ``hop_shape``, of the ``hop_variables`` only where named; a restart after ``patience`` hops that do not
    improve m_f) — with the CR3BP solver options; then the report: expected iterations to come within each of
    ``deltas_kg`` of the best known m_f, with bootstrap intervals (``ablation.n_boot``), the runtime ECDF and the
    distinct near-best trajectories.  The best known is the best verified m_f at that α of the run's searches and
    of the solution library."""

    enabled: Flag = False
    samplers: Annotated[tuple[Literal[SAMPLER_NAMES], ...], Field(min_length=1)] = (  # type: ignore[valid-type]
        "uniform", "nearest_alpha")
    strategies: Annotated[tuple[Literal[tuple(STRATEGIES)], ...], Field(min_length=1)] = (  # type: ignore[valid-type]
        "multistart", "mbh")
    searches: PositiveInt = 30
    budget: Annotated[int, Field(ge=1, description="IPOPT iterations per search")] = 5000
    deltas_kg: Annotated[tuple[Annotated[float, Field(gt=0)], ...], Field(min_length=1, description=(
        "targets: within δ kg of the best known m_f"))] = (0.1, 0.5, 2.0)
    hop_distribution: Literal[tuple(HOP_DISTRIBUTIONS)] = HOPS.distribution  # type: ignore[valid-type]
    hop_scale: Annotated[float, Field(gt=0, le=1, description="hop step per unit draw, fraction of the box width")] = (
        HOPS.scale)
    hop_shape: Annotated[float, Field(gt=0, description="tail index of the Pareto hops")] = HOPS.shape
    patience: PositiveInt = HOPS.patience
    hop_variables: Annotated[tuple[str, ...], Field(description=(
        "the CR3BP's stored variables a hop moves (e.g. [tau_s, tau_i, tau_f]: the times); empty: every one"))] = (
        HOPS.variables)
    seed: Seed = 23
    mem_mb: PositiveInt = 4000
    runtime_min: PositiveInt = 120

    _unique_lists = field_validator("samplers", "strategies", "deltas_kg", "hop_variables")(_unique)

    @field_validator("hop_variables")
    @classmethod
    def _known_variables(cls, names: tuple[str, ...]) -> tuple[str, ...]:
        if names:
            from amorgs.problems.cr3bp.transcription import variable_names

            HopSettings(variables=names).movable(variable_names())  # ValueError naming the unknown ones
        return names

    def job(self) -> Job:
        """The resources of one cell job (its searches run one after another in one process): one thread,
        ``mem_mb`` MB, ``runtime_min`` minutes."""
        return Job(threads=1, mem_mb=self.mem_mb, runtime_min=self.runtime_min)


class Config(Section):
    """The whole workflow configuration, every default that of the main job (2 cores: the README's time);
    ``seed`` is the base of every derived seed."""

    seed: Seed = 20240917
    mlflow: Mlflow = Mlflow()
    resources: Resources = Resources()
    problems: Problems = Problems()
    dejong_cvae: DejongCVAE = DejongCVAE()
    cr3bp_analysis: Cr3bpAnalysis = Cr3bpAnalysis()
    cr3bp_models: Cr3bpModels = Cr3bpModels()
    ablation: Ablation = Ablation()
    transfer: Transfer = Transfer()
    global_search: GlobalSearch = GlobalSearch()

    @property
    def hash(self) -> str:
        """12 hex digits of the SHA-256 of the canonical JSON of the whole effective config (every key, the
        defaults included: a file that spells out a default and one that leaves it out hash alike)."""
        text = json.dumps(self.model_dump(mode="json"), sort_keys=True)
        return hashlib.sha256(text.encode()).hexdigest()[:12]

    @model_validator(mode="after")
    def _cross_field_rules(self) -> Config:
        """The rules a field alone cannot state (each error names its dotted key)."""
        for name in type(self.problems).model_fields:
            problem, family = getattr(self.problems, name), FAMILIES[name]
            lo, hi = family.alpha_range
            seen: dict[str, float] = {}
            for a in (*problem.alphas.train_values(), *problem.alphas.test):
                if not lo - 1e-12 <= a <= hi + 1e-12:
                    raise ValueError(f"problems.{name}.alphas: α = {a!r} lies outside the problem's range "
                                     f"[{lo:g}, {hi:g}] {family.alpha_unit}")
                label = alpha_label(a)
                if label in seen:
                    raise ValueError(f"problems.{name}.alphas: α values {seen[label]!r} and {a!r} share the label "
                                     f"{label} (train and test must be distinct at three decimals)")
                seen[label] = a
        dejong, cr3bp = self.problems.dejong, self.problems.cr3bp
        if self.dejong_cvae.enabled and not dejong.enabled:
            raise ValueError("dejong_cvae.enabled needs problems.dejong.enabled: true")
        if self.dejong_cvae.enabled and not dejong.alphas.test:
            raise ValueError("dejong_cvae.enabled needs test α in problems.dejong.alphas.test")
        for key in ("cr3bp_analysis", "cr3bp_models", "ablation", "transfer", "global_search"):
            if getattr(self, key).enabled and not cr3bp.enabled:
                raise ValueError(f"{key}.enabled needs problems.cr3bp.enabled: true")
        for key in ("cr3bp_models", "ablation", "global_search"):
            if getattr(self, key).enabled and not cr3bp.alphas.test:
                raise ValueError(f"{key}.enabled needs test α in problems.cr3bp.alphas.test")
        learned = [s for s in self.ablation.samplers if get_arm(s).learned]
        if self.ablation.enabled and learned and not self.cr3bp_models.enabled:
            raise ValueError(f"ablation.samplers {learned} need cr3bp_models.enabled: true")
        too_big = [c for c in self.ablation.iteration_caps if c > cr3bp.solver.max_iter]
        if self.ablation.enabled and too_big:
            raise ValueError(f"ablation.iteration_caps {too_big} exceed problems.cr3bp.solver.max_iter = "
                             f"{cr3bp.solver.max_iter}: a cap above the solver's own is not a real cap")
        needs_transfer = [s for s in self.ablation.samplers if get_arm(s).transfer]
        if self.ablation.enabled and needs_transfer and not self.transfer.enabled:
            raise ValueError(f"ablation.samplers {needs_transfer} need transfer.enabled: true (their selector learns "
                             "from the transfer data)")
        gs = self.global_search
        learned = [s for s in gs.samplers if get_arm(s).learned]
        if gs.enabled and learned and not self.cr3bp_models.enabled:
            raise ValueError(f"global_search.samplers {learned} need cr3bp_models.enabled: true")
        needs_transfer = [s for s in gs.samplers if get_arm(s).transfer]
        if gs.enabled and needs_transfer and not self.transfer.enabled:
            raise ValueError(f"global_search.samplers {needs_transfer} need transfer.enabled: true")
        if self.transfer.enabled and len(cr3bp.alphas.train_values()) < 2:
            raise ValueError("transfer.enabled needs at least 2 α in problems.cr3bp.alphas.train (pairs of them)")
        return self


# --------------------------------------------------------------------------------------------- loading


def read_yaml(path: str | Path) -> dict:
    """Read one YAML config file (overrides of the defaults; ``{}`` for none); ``ConfigError`` if it is
    missing, malformed or not a mapping."""
    p = Path(path)
    try:
        data = yaml.safe_load(p.read_text())
    except FileNotFoundError:
        raise ConfigError(f"{p}: config file not found") from None
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f" at line {mark.line + 1}, column {mark.column + 1}" if mark is not None else ""
        raise ConfigError(f"{p}: not valid YAML{where}: {getattr(exc, 'problem', None) or exc}") from None
    if not isinstance(data, dict):
        raise ConfigError(f"{p}: a config file must be a mapping of keys ({{}} for the defaults), got "
                          f"{type(data).__name__}")
    return data


def deep_merge(base: dict, override: dict) -> dict:
    """``override`` over ``base``, neither modified: a key whose value is a mapping on both sides merges
    recursively; any other value (a list, a number, a string, null) replaces the one in ``base``."""
    out = dict(base)
    for key, value in override.items():
        both = isinstance(value, dict) and isinstance(out.get(key), dict)
        out[key] = deep_merge(out[key], value) if both else value
    return out


def defaults() -> dict:
    """The typed defaults (the main job) as plain JSON data: every key of the config."""
    return Config().model_dump(mode="json")


def effective_mapping(*overrides: dict) -> dict:
    """The config a run uses: the defaults with each of ``overrides`` merged over them in turn (:func:`deep_merge`),
    unvalidated (unknown keys stay, for the validation to name)."""
    out = defaults()
    for override in overrides:
        out = deep_merge(out, override)
    return out


def _error_lines(exc: ValidationError, source: str) -> list[str]:
    """One line per pydantic error: ``source: dotted.key: message (got value)``."""
    lines = []
    for err in exc.errors():
        # keys are lower-case; union branches appear in the location as type names (AlphaGrid, tuple[...])
        loc = ".".join(str(p) for p in err["loc"] if not (isinstance(p, str) and (p[:1].isupper() or "[" in p)))
        message = err["msg"].removeprefix("Value error, ")
        if err["type"] in ("extra_forbidden", "unexpected_keyword_argument"):
            message = "unknown key"
        elif err["type"] == "missing":
            message = "required key is missing"
        elif isinstance(err.get("input"), (int, float, str)) and err["type"] != "value_error":
            message += f" (got {err['input']!r})"
        if not loc and ": " in message:
            lines.append(f"{source}: {message}")  # a cross-field rule names its own key
        else:
            lines.append(f"{source}: {loc or '(top level)'}: {message}")
    return list(dict.fromkeys(lines))


def from_mapping(mapping: dict, source: str = "config") -> Config:
    """Merge ``mapping`` (overrides) over the defaults, validate, and build the typed :class:`Config`; one
    ``ConfigError`` lists every problem, each line naming ``source`` and the dotted key."""
    try:
        return Config.model_validate(effective_mapping(mapping))
    except ValidationError as exc:
        lines = _error_lines(exc, source)
        raise ConfigError(lines[0] if len(lines) == 1 else "invalid configuration\n  " + "\n  ".join(lines)) from None


def load_config(path: str | Path) -> Config:
    """The effective config of one file: its overrides merged over the defaults, validated."""
    return from_mapping(read_yaml(path), str(path))


def load_workflow_config(config: dict, configfiles: list) -> Config:
    """Validate Snakemake's ``config``: each of its ``configfiles`` alone over the defaults (so an error names
    the file), then the mapping Snakemake built — the files merged in the order given, then any ``--config``
    overrides, with the same semantics as :func:`deep_merge` (Snakemake's ``update_config``) — over the
    defaults."""
    for f in configfiles:
        load_config(f)
    try:
        return Config.model_validate(effective_mapping(config))
    except ValidationError as exc:  # validated again below, to name every problem in one ConfigError
        config = _command_line_switches(config, exc)
    return from_mapping(config, "merged config (" + " + ".join([*map(str, configfiles), "--config"]) + ")")


def _command_line_switches(config: dict, exc: ValidationError) -> dict:
    """``config`` with the strings 'true' / 'false' (any case) that ``exc`` found where a switch (:data:`Flag`) is
    expected turned into booleans.  Snakemake reads a nested ``--config`` value with YAML's base loader, so
    ``--config "mlflow={'enabled': false}"`` arrives as the string 'false'; a config *file* is validated on its
    own first (:func:`load_workflow_config`), so a quoted switch in a file is still an error."""
    out = copy.deepcopy(config)
    for err in exc.errors():
        text = err.get("input")
        if err["type"] != "bool_type" or not isinstance(text, str) or text.lower() not in ("true", "false"):
            continue
        node = out
        for key in err["loc"][:-1]:
            if isinstance(node, dict) and key in node:
                node = node[key]  # else: a union branch's type name in the location, not a key
        if isinstance(node, dict) and node.get(err["loc"][-1]) == text:
            node[err["loc"][-1]] = text.lower() == "true"
    return out


def _optional(node):
    """``node`` (a JSON Schema) with no key required anywhere: a config file holds overrides."""
    if isinstance(node, dict):
        return {k: _optional(v) for k, v in node.items() if k != "required"}
    if isinstance(node, list):
        return [_optional(v) for v in node]
    return node


def json_schema() -> dict:
    """The JSON Schema (draft 2020-12) of a config file, generated from :class:`Config`: types, ranges, enums,
    defaults; no key is required, since a file holds only what it changes from the defaults."""
    schema = _optional(Config.model_json_schema())
    return {"$schema": "https://json-schema.org/draft/2020-12/schema",
            "$comment": "GENERATED from src/amorgs/config.py by `amorgs config-schema --write`; do not edit. A config "
                        "file holds overrides of the defaults: mappings merge into them key by key, anything else "
                        "(a list, a number, a string, null) replaces the default.",
            **schema}


def schema_text() -> str:
    """The generated schema as the text of :data:`SCHEMA_PATH`."""
    return json.dumps(json_schema(), indent=2, ensure_ascii=False) + "\n"
