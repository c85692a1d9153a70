"""The workflow configuration: one typed model (pydantic) that is the schema.

A config file is the complete experiment: every key is required (except inside the solver sections, whose
defaults live in :mod:`amorgs.solvers.options`, and ``cr3bp_analysis.params``, whose defaults live in
:class:`amorgs.analysis.structure_params.StructureParams`), no other key is allowed, and no other file is
merged under it.  The JSON Schema ``workflow/schemas/config.schema.json`` is *generated* from these models
(``amorgs config-schema --write``; a test keeps it current), so types, ranges, enums and descriptions are
written once, here.  Enums come from the registries: samplers from :mod:`amorgs.ablation.arms`, problems
from :mod:`amorgs.problems`, presets from :mod:`amorgs.models.names`.

Checking happens at load, before any job: the model (types, ranges, enums, unknown keys), then the
cross-field rules (:meth:`Config._cross_field_rules`: α inside each problem's range and distinct at three
decimals, stages enabled together, iteration caps ≤ ``max_iter``).  Every failure is one
:class:`ConfigError` whose lines name the file and the dotted key, e.g.
``config/smoke.yaml: problems.dejong.generate.startz: Extra inputs are not permitted``.

α identity: :func:`amorgs.alphas.alpha_label` (three decimals, ``0.150``) in paths, wildcards and keys; the
exact float behind each label is kept here and passed to the solver.
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path
from typing import Annotated, Literal

import numpy as np
import yaml
from pydantic import BaseModel, ConfigDict, Field, StrictBool, ValidationError, field_validator, model_validator

from amorgs.ablation.arms import LEARNED_SAMPLER_NAMES, SAMPLER_NAMES, get_arm
from amorgs.alphas import alpha_label
from amorgs.analysis.structure_params import StructureParams
from amorgs.errors import ConfigError
from amorgs.models.names import CR3BP_PRESETS, DEJONG_PRESETS
from amorgs.problems import ALPHA_RANGES
from amorgs.solvers.options import BfgsOptions, IpoptOptions

#: The generated JSON Schema, relative to the repository root (the working directory of workflow and CLI).
SCHEMA_PATH = Path("workflow/schemas/config.schema.json")
#: The config a plain ``snakemake`` (no ``--configfile``) runs.
DEFAULT_CONFIG = Path("config/default.yaml")

PositiveInt = Annotated[int, Field(ge=1)]
Seed = Annotated[int, Field(ge=0, description="random seed (≥ 0)")]
PositiveFloat = Annotated[float, Field(gt=0)]
#: A switch: true or false only (a quoted "yes" is an error, not True).
Flag = StrictBool


class Section(BaseModel):
    """A config section: frozen, every field required unless it has a default, no unknown keys."""

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


class Library(Section):
    """The versioned solution library: with ``enabled``, the merge of every α also takes the committed files
    under ``path``/{problem}/alpha={label}/ (:mod:`amorgs.data.library`) — all of them, or with
    ``max_rows_per_alpha`` a fixed slice of the first rows in (shard, start) order."""

    enabled: Flag
    path: Annotated[str, Field(min_length=1, description="library root, relative to the working directory")]
    max_rows_per_alpha: PositiveInt | None = Field(
        description="null: every library row of each α; a number: only the first rows (a fixed slice)")


class DejongFilter(Section):
    """Keep converged solves with J ≤ ``max_objective`` (``null``: every converged solve)."""

    max_objective: float | None


class Cr3bpFilter(Section):
    """β: keep converged solves with final mass m_f ≥ ``min_final_mass_kg`` (kg)."""

    min_final_mass_kg: float


class ProblemConfig(Section):
    """What the generate → merge → filter stages do for one problem."""

    enabled: Flag
    alphas: Alphas
    generate: Generate
    library: Library

    def alpha_values(self) -> dict[str, float]:
        """Label → α for every generated α (train, then test), in config order."""
        return {alpha_label(a): a for a in (*self.alphas.train_values(), *self.alphas.test)}

    def filter_thresholds(self) -> dict:
        """The filter section as keyword arguments of :func:`amorgs.data.filter.high_quality`."""
        return self.filter.model_dump()  # type: ignore[attr-defined]


class DejongConfig(ProblemConfig):
    solver: BfgsOptions = Field(description="scipy BFGS options (amorgs.solvers.options.BfgsOptions)")
    filter: DejongFilter


class Cr3bpConfig(ProblemConfig):
    solver: IpoptOptions = Field(description="IPOPT options (amorgs.solvers.options.IpoptOptions)")
    filter: Cr3bpFilter


class Problems(Section):
    dejong: DejongConfig
    cr3bp: Cr3bpConfig

    def enabled(self) -> dict[str, ProblemConfig]:
        """Name → section of every enabled problem."""
        return {name: getattr(self, name) for name in type(self).model_fields if getattr(self, name).enabled}


class Mlflow(Section):
    """Mirror runs to MLflow in experiment ``experiment``; ``tracking_uri`` null means the SQLite store under
    ``results/mlflow``; the ``MLFLOW_TRACKING_URI`` environment variable overrides both."""

    enabled: Flag
    experiment: Annotated[str, Field(min_length=1)]
    tracking_uri: Annotated[str, Field(min_length=1)] | None


class Resources(Section):
    """Job resources of the rules other than generate and the ablation cells."""

    merge: Job
    filter: Job
    train: Job
    predict: Job
    figure: Job
    analyze: Job


class DejongCVAE(Section):
    """The GMM-prior CVAE on the De Jong minima (paper Sec. V.A, Table 3): ``preset`` widths; Adam with
    ``learning_rate`` for ``epochs`` epochs of ``batch_size`` rows; ``seed`` fixes weights, shuffling and
    sampling; ``n_samples`` samples per test α scored against the true minima within ``radius`` (units of x)."""

    enabled: Flag
    preset: Literal[DEJONG_PRESETS]  # type: ignore[valid-type]
    learning_rate: PositiveFloat
    epochs: PositiveInt
    batch_size: Annotated[int, Field(ge=2)]
    seed: Seed
    n_samples: PositiveInt
    radius: PositiveFloat


class Cr3bpAnalysis(Section):
    """The structure analysis of the CR3BP solutions (paper Sec. III.B, Figs. 3–13)."""

    enabled: Flag
    params: StructureParams = Field(description="StructureParams fields ({}: its defaults)")


class Cr3bpModels(Section):
    """The three CR3BP generative models (paper Sec. IV, Tables 4–5), trained on the training α only:
    ``preset`` widths; Adam with ``learning_rate`` for ``epochs`` epochs of ``batch_size`` rows; ``seed``
    fixes weights, shuffling, subsampling and sampling; ``extra_seeds``: further training seeds whose models
    serve the ablation's replicates; ``data_fractions``: extra GMM-CVAEs on these fractions (Fig. 18);
    ``n_samples``: samples per test α (Figs. 17–20)."""

    enabled: Flag
    preset: Literal[CR3BP_PRESETS]  # type: ignore[valid-type]
    epochs: PositiveInt
    batch_size: Annotated[int, Field(ge=2)]
    learning_rate: PositiveFloat
    seed: Seed
    extra_seeds: tuple[Seed, ...]
    data_fractions: tuple[Annotated[float, Field(gt=0, lt=1)], ...]
    n_samples: PositiveInt

    _unique_seeds = field_validator("extra_seeds", "data_fractions")(_unique)

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

    enabled: Flag
    samplers: Annotated[tuple[Literal[SAMPLER_NAMES], ...], Field(min_length=1)]  # type: ignore[valid-type]
    n_starts: PositiveInt
    seed: Seed
    workers: PositiveInt
    mem_mb: PositiveInt
    runtime_min: PositiveInt
    perturbation_scale: Annotated[float, Field(ge=0)]
    gmm_components: PositiveInt
    iteration_caps: tuple[PositiveInt, ...]
    beta_sweep_kg: tuple[float, ...]
    n_boot: PositiveInt
    break_even_solutions: tuple[PositiveInt, ...] = Field(
        description="high-quality solutions wanted per new α in the break-even table (none: no table)")
    fraction_samplers: tuple[Literal[LEARNED_SAMPLER_NAMES], ...] = Field(  # type: ignore[valid-type]
        description="learned arms run again with the models of every cr3bp_models.data_fractions (the "
                    "learning curve of the ablation's expected running time; none: no curve)")

    _unique_lists = field_validator("samplers", "iteration_caps", "beta_sweep_kg", "break_even_solutions",
                                    "fraction_samplers")(_unique)


class Config(Section):
    """The whole workflow configuration; ``seed`` is the base of every derived seed."""

    seed: Seed
    mlflow: Mlflow
    resources: Resources
    problems: Problems
    dejong_cvae: DejongCVAE
    cr3bp_analysis: Cr3bpAnalysis
    cr3bp_models: Cr3bpModels
    ablation: Ablation

    @property
    def hash(self) -> str:
        """12 hex digits of the SHA-256 of the canonical JSON of the whole config."""
        text = json.dumps(self.model_dump(mode="json"), sort_keys=True)
        return hashlib.sha256(text.encode()).hexdigest()[:12]

    @model_validator(mode="after")
    def _cross_field_rules(self) -> Config:
        """The rules a field alone cannot state (each error names its dotted key)."""
        for name in type(self.problems).model_fields:
            problem = getattr(self.problems, name)
            lo, hi = ALPHA_RANGES[name]
            seen: dict[str, float] = {}
            for a in (*problem.alphas.train_values(), *problem.alphas.test):
                if not lo - 1e-12 <= a <= hi + 1e-12:
                    raise ValueError(f"problems.{name}.alphas: α = {a!r} lies outside the problem's range [{lo:g}, {hi:g}]")
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
        for key in ("cr3bp_analysis", "cr3bp_models", "ablation"):
            if getattr(self, key).enabled and not cr3bp.enabled:
                raise ValueError(f"{key}.enabled needs problems.cr3bp.enabled: true")
        for key in ("cr3bp_models", "ablation"):
            if getattr(self, key).enabled and not cr3bp.alphas.test:
                raise ValueError(f"{key}.enabled needs test α in problems.cr3bp.alphas.test")
        learned = [s for s in self.ablation.samplers if get_arm(s).learned]
        if self.ablation.enabled and learned and not self.cr3bp_models.enabled:
            raise ValueError(f"ablation.samplers {learned} need cr3bp_models.enabled: true")
        too_big = [c for c in self.ablation.iteration_caps if c > cr3bp.solver.max_iter]
        if self.ablation.enabled and too_big:
            raise ValueError(f"ablation.iteration_caps {too_big} exceed problems.cr3bp.solver.max_iter = "
                             f"{cr3bp.solver.max_iter}: a cap above the solver's own is not a real cap")
        return self


# --------------------------------------------------------------------------------------------- loading


def read_yaml(path: str | Path) -> dict:
    """Read one YAML config file; ``ConfigError`` if it is missing, malformed or not a mapping."""
    p = Path(path)
    try:
        data = yaml.safe_load(p.read_text())
    except FileNotFoundError:
        raise ConfigError(f"{p}: config file not found") from None
    except yaml.YAMLError as exc:
        raise ConfigError(f"{p}: not valid YAML: {exc}") from None
    if not isinstance(data, dict):
        raise ConfigError(f"{p}: a config file must be a mapping of keys, got {type(data).__name__}")
    return data


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
    """Validate ``mapping`` and build the typed :class:`Config`; one ``ConfigError`` lists every problem."""
    try:
        return Config.model_validate(mapping)
    except ValidationError as exc:
        lines = _error_lines(exc, source)
        raise ConfigError(lines[0] if len(lines) == 1 else "invalid configuration\n  " + "\n  ".join(lines)) from None


def load_config(path: str | Path) -> Config:
    """Read, validate and build the config in one file."""
    return from_mapping(read_yaml(path), str(path))


def load_workflow_config(config: dict, configfiles: list) -> Config:
    """Validate Snakemake's ``config``: each of its ``configfiles`` alone (each must be a complete experiment,
    so an error names the file), then the mapping Snakemake built (files merged in the order given, then any
    ``--config`` overrides)."""
    for f in configfiles:
        load_config(f)
    return from_mapping(config, "merged config (" + " + ".join([*map(str, configfiles), "--config"]) + ")")


def json_schema() -> dict:
    """The JSON Schema (draft 2020-12) of a config file, generated from :class:`Config`."""
    schema = Config.model_json_schema()
    return {"$schema": "https://json-schema.org/draft/2020-12/schema",
            "$comment": "GENERATED from src/amorgs/config.py by `amorgs config-schema --write`; do not edit.",
            **schema}


def schema_text() -> str:
    """The generated schema as the text of :data:`SCHEMA_PATH`."""
    return json.dumps(json_schema(), indent=2, ensure_ascii=False) + "\n"
