"""The workflow configuration as typed, frozen dataclasses mirroring ``workflow/schemas/config.schema.yaml``.

A config file is checked in two steps: the JSON Schema (every key required, no unknown key, types and
ranges), then the cross-field rules the schema cannot express (α labels unique per problem, the CVAE needs
the De Jong data and test α).  Every failure is a :class:`ConfigError` whose message names the file and the
dotted key, e.g. ``config/smoke.yaml: problems.dejong.generate: Additional properties are not allowed
('startz' was unexpected)``.

α values appear in file names and Snakemake wildcards as fixed three-decimal labels (:func:`alpha_label`,
``0.150``); the exact float behind each label is kept here and passed to the solver.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import types
import typing
from dataclasses import dataclass
from pathlib import Path

import jsonschema
import numpy as np
import yaml

#: The schema, relative to the repository root (the working directory of the workflow and the CLI).
SCHEMA_PATH = Path("workflow/schemas/config.schema.yaml")


class ConfigError(ValueError):
    """An invalid configuration; the message names the file and the key."""


def alpha_label(alpha: float) -> str:
    """The stable string form of α used in paths and wildcards: three fixed decimals (``0.150``)."""
    return f"{alpha:.3f}"


@dataclass(frozen=True)
class AlphaGrid:
    """``num`` evenly spaced α from ``start`` to ``stop`` inclusive (numpy.linspace)."""

    start: float
    stop: float
    num: int

    def values(self) -> tuple[float, ...]:
        return tuple(float(a) for a in np.linspace(self.start, self.stop, self.num))


@dataclass(frozen=True)
class Alphas:
    """α values of a problem: ``train`` (a list or a grid) and held-out ``test``; both are generated."""

    train: tuple[float, ...] | AlphaGrid
    test: tuple[float, ...]

    def train_values(self) -> tuple[float, ...]:
        return self.train.values() if isinstance(self.train, AlphaGrid) else self.train


@dataclass(frozen=True)
class Job:
    """Resources of one job: ``threads`` (cores), ``mem_mb`` (MB), ``runtime_min`` (wall minutes)."""

    threads: int
    mem_mb: int
    runtime_min: int


@dataclass(frozen=True)
class Generate:
    """Per α: ``shards`` jobs × ``starts_per_shard`` uniform starts, ``workers`` solver processes per job."""

    shards: int
    starts_per_shard: int
    workers: int
    mem_mb: int
    runtime_min: int


@dataclass(frozen=True)
class DejongSolver:
    """scipy BFGS: ``gtol`` (gradient ∞-norm tolerance, dimensionless), ``maxiter`` (iteration cap)."""

    gtol: float
    maxiter: int


@dataclass(frozen=True)
class DejongFilter:
    """Keep converged solves with J ≤ ``max_objective`` (``None``: every converged solve)."""

    max_objective: float | None


@dataclass(frozen=True)
class Cr3bpSolver:
    """IPOPT caps: ``max_iter`` (the primary limit) and ``max_wall_s`` (seconds, a safety net)."""

    max_iter: int
    max_wall_s: float


@dataclass(frozen=True)
class Cr3bpFilter:
    """β: keep converged solves with final mass m_f ≥ ``min_final_mass_kg`` (kg)."""

    min_final_mass_kg: float


@dataclass(frozen=True)
class Library:
    """The versioned solution library: with ``enabled``, the merge of every α also takes the committed files
    under ``path``/{problem}/alpha={label}/ (see :mod:`amorgs.data.library`) — all of them, or with
    ``max_rows_per_alpha`` a fixed slice of the first rows in (shard, start) order."""

    enabled: bool
    path: str
    max_rows_per_alpha: int | None


@dataclass(frozen=True)
class ProblemConfig:
    """What the generate → merge → filter stages do for one problem."""

    enabled: bool
    alphas: Alphas
    generate: Generate
    library: Library

    def alpha_values(self) -> dict[str, float]:
        """Label → α for every generated α (train, then test), in config order."""
        return {alpha_label(a): a for a in (*self.alphas.train_values(), *self.alphas.test)}

    def solver_options(self) -> dict:
        """The solver section as the plain dict the multistart takes."""
        return dataclasses.asdict(self.solver)  # type: ignore[attr-defined]

    def filter_thresholds(self) -> dict:
        """The filter section as keyword arguments of :func:`amorgs.data.filter.high_quality`."""
        return dataclasses.asdict(self.filter)  # type: ignore[attr-defined]


@dataclass(frozen=True)
class DejongConfig(ProblemConfig):
    solver: DejongSolver
    filter: DejongFilter


@dataclass(frozen=True)
class Cr3bpConfig(ProblemConfig):
    solver: Cr3bpSolver
    filter: Cr3bpFilter


@dataclass(frozen=True)
class Problems:
    dejong: DejongConfig
    cr3bp: Cr3bpConfig

    def enabled(self) -> dict[str, ProblemConfig]:
        """Name → section of every enabled problem."""
        return {f.name: getattr(self, f.name) for f in dataclasses.fields(self) if getattr(self, f.name).enabled}


@dataclass(frozen=True)
class Mlflow:
    """Mirror runs to MLflow in experiment ``experiment``.

    ``tracking_uri`` None means the SQLite store under ``results/mlflow``; otherwise any MLflow tracking URI
    (``http://host:5000``, ``sqlite:////abs/path.db``).  The ``MLFLOW_TRACKING_URI`` environment variable, when
    set, overrides both (see :func:`amorgs.tracking.resolve_tracking_uri`).
    """

    enabled: bool
    experiment: str
    tracking_uri: str | None


@dataclass(frozen=True)
class Resources:
    """Job resources of the rules other than generate."""

    merge: Job
    filter: Job
    train: Job
    predict: Job
    figure: Job
    analyze: Job


@dataclass(frozen=True)
class DejongCVAE:
    """The GMM-prior CVAE on the De Jong minima (paper Sec. V.A, Table 3).

    ``preset`` names a :class:`amorgs.models.cvae.CVAEConfig` constructor; Adam with ``learning_rate`` for
    ``epochs`` epochs of ``batch_size`` rows; ``seed`` fixes weights, shuffling and sampling;
    ``n_samples`` samples are drawn per test α and scored against the true minima within ``radius``
    (units of x).
    """

    enabled: bool
    preset: str
    learning_rate: float
    epochs: int
    batch_size: int
    seed: int
    n_samples: int
    radius: float


@dataclass(frozen=True)
class Cr3bpAnalysis:
    """The structure analysis of the CR3BP solutions (paper Sec. III.B, Figs. 3–13); ``params`` are the
    fields of :class:`amorgs.analysis.structure_report.StructureParams` (empty: its defaults)."""

    enabled: bool
    params: dict


@dataclass(frozen=True)
class Cr3bpModels:
    """The three CR3BP generative models (paper Sec. IV, Tables 4–5), trained on the training α only.

    ``preset`` (``paper`` or ``small``) picks the layer widths; Adam with ``learning_rate`` for ``epochs``
    epochs of ``batch_size`` rows; ``seed`` fixes weights, shuffling, subsampling and sampling;
    ``data_fractions``: extra GMM-CVAEs trained on these fractions of the data (Fig. 18); ``n_samples``:
    samples drawn per test α for the prediction study (Figs. 17–20); ``extra_seeds``: further training seeds
    whose models serve the ablation's replicates (results/cr3bp/models/seed={s}/).
    """

    enabled: bool
    preset: str
    epochs: int
    batch_size: int
    learning_rate: float
    seed: int
    extra_seeds: tuple[int, ...]
    data_fractions: tuple[float, ...]
    n_samples: int

    @property
    def seeds(self) -> tuple[int, ...]:
        """Every model-training seed: ``seed`` (models under results/cr3bp/models/) then ``extra_seeds``."""
        return (self.seed, *self.extra_seeds)


@dataclass(frozen=True)
class Ablation:
    """The warm-start ablation at the CR3BP test α (paper Sec. V.B.7, Table 6): per (test α, sampler) one job
    solving ``n_starts`` guesses with ``workers`` processes, the CR3BP solver options and a seed derived from
    ``seed``; ``mem_mb`` and ``runtime_min`` are that job's resources.  Every arm runs once per model seed
    (``cr3bp_models.seeds``), so each (α, arm) has ``n_starts × len(seeds)`` starts.

    Issue 11: ``perturbation_scale`` (σ of nearest_alpha_perturbed, box-normalised), ``gmm_components``
    (gmm_lstm), ``iteration_caps`` (the Fig. 22 study, fixed before the solves), ``beta_sweep_kg`` (extra β
    of the rate sweep), ``n_boot`` (bootstrap resamples of the speed-up intervals)."""

    enabled: bool
    samplers: tuple[str, ...]
    n_starts: int
    seed: int
    workers: int
    mem_mb: int
    runtime_min: int
    perturbation_scale: float
    gmm_components: int
    iteration_caps: tuple[int, ...]
    beta_sweep_kg: tuple[float, ...]
    n_boot: int


@dataclass(frozen=True)
class Config:
    """The whole workflow configuration; ``seed`` is the base of every derived seed."""

    seed: int
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
        text = json.dumps(dataclasses.asdict(self), sort_keys=True)
        return hashlib.sha256(text.encode()).hexdigest()[:12]


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


def validate_mapping(mapping: dict, schema_path: str | Path = SCHEMA_PATH, source: str = "config") -> None:
    """Check ``mapping`` against the JSON Schema; one ``ConfigError`` lists every violation by key."""
    schema = yaml.safe_load(Path(schema_path).read_text())
    validator = jsonschema.Draft202012Validator(schema)
    errors = sorted(validator.iter_errors(mapping), key=lambda e: [str(p) for p in e.absolute_path])
    if errors:
        lines = [f"{source}: {'.'.join(str(p) for p in e.absolute_path) or '(top level)'}: {e.message}" for e in errors]
        raise ConfigError("invalid configuration\n  " + "\n  ".join(lines))


def from_mapping(mapping: dict, source: str = "config") -> Config:
    """Build the typed :class:`Config` from a schema-valid mapping and apply the cross-field rules."""
    cfg = _build(Config, mapping)
    _check(cfg, source)
    return cfg


def load_config(path: str | Path, schema_path: str | Path = SCHEMA_PATH) -> Config:
    """Read, validate and build the config in one file."""
    mapping = read_yaml(path)
    validate_mapping(mapping, schema_path, str(path))
    return from_mapping(mapping, str(path))


def load_workflow_config(config: dict, configfiles: list, schema_path: str | Path) -> Config:
    """Validate Snakemake's ``config``: each of its ``configfiles`` alone (so errors name the file), then
    the merged mapping, which also carries ``--config`` overrides."""
    for f in configfiles:
        validate_mapping(read_yaml(f), schema_path, str(f))
    source = "merged config (" + ", ".join(str(f) for f in configfiles) + ", --config)"
    validate_mapping(config, schema_path, source)
    return from_mapping(config, source)


def _build(tp: object, value: object) -> object:
    """Convert schema-valid YAML data to the annotated type ``tp`` (dataclass, tuple, union, scalar)."""
    if dataclasses.is_dataclass(tp):
        hints = typing.get_type_hints(tp)
        return tp(**{k: _build(hints[k], v) for k, v in value.items()})
    origin = typing.get_origin(tp)
    if origin is types.UnionType:  # X | None, or tuple[float, ...] | AlphaGrid (a list or a mapping)
        if value is None:
            return None
        options = [t for t in typing.get_args(tp) if t is not type(None)]
        return next(_build(t, value) for t in options if dataclasses.is_dataclass(t) == isinstance(value, dict))
    if tp is dict:
        return dict(value)
    if origin is tuple:
        return tuple(_build(typing.get_args(tp)[0], v) for v in value)
    if tp is float:
        return float(value)
    return value


def _check(cfg: Config, source: str) -> None:
    """Cross-field rules the schema cannot express."""
    from amorgs.problems import ALPHA_RANGES

    for field in dataclasses.fields(cfg.problems):
        name, problem = field.name, getattr(cfg.problems, field.name)
        seen: dict[str, float] = {}
        lo, hi = ALPHA_RANGES[name]
        for a in (*problem.alphas.train_values(), *problem.alphas.test):
            if not lo - 1e-12 <= a <= hi + 1e-12:
                raise ConfigError(f"{source}: problems.{name}.alphas: α = {a!r} lies outside the problem's range [{lo:g}, {hi:g}]")
            label = alpha_label(a)
            if label in seen:
                raise ConfigError(
                    f"{source}: problems.{name}.alphas: α values {seen[label]!r} and {a!r} share the label "
                    f"{label} (train and test must be distinct at three decimals)"
                )
            seen[label] = a
    cvae = cfg.dejong_cvae
    if cvae.enabled and not cfg.problems.dejong.enabled:
        raise ConfigError(f"{source}: dejong_cvae.enabled needs problems.dejong.enabled: true")
    if cvae.enabled and not cfg.problems.dejong.alphas.test:
        raise ConfigError(f"{source}: dejong_cvae.enabled needs test α in problems.dejong.alphas.test")
    cr3bp = cfg.problems.cr3bp
    for key in ("cr3bp_analysis", "cr3bp_models", "ablation"):
        if getattr(cfg, key).enabled and not cr3bp.enabled:
            raise ConfigError(f"{source}: {key}.enabled needs problems.cr3bp.enabled: true")
    for key in ("cr3bp_models", "ablation"):
        if getattr(cfg, key).enabled and not cr3bp.alphas.test:
            raise ConfigError(f"{source}: {key}.enabled needs test α in problems.cr3bp.alphas.test")
    from amorgs.ablation.arms import NEEDS_MODELS, SAMPLER_NAMES

    unknown = [s for s in cfg.ablation.samplers if s not in SAMPLER_NAMES]
    if unknown:
        raise ConfigError(f"{source}: ablation.samplers {unknown} are not registered arms {SAMPLER_NAMES}")
    learned = [s for s in cfg.ablation.samplers if NEEDS_MODELS[s]]
    if cfg.ablation.enabled and learned and not cfg.cr3bp_models.enabled:
        raise ConfigError(f"{source}: ablation.samplers {learned} need cr3bp_models.enabled: true")
    too_big = [c for c in cfg.ablation.iteration_caps if c > cr3bp.solver.max_iter]
    if cfg.ablation.enabled and too_big:
        raise ConfigError(
            f"{source}: ablation.iteration_caps {too_big} exceed problems.cr3bp.solver.max_iter = "
            f"{cr3bp.solver.max_iter}: a cap above the solver's own is not a real cap"
        )
