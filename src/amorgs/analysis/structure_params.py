"""Parameters of the structure analysis (paper Sec. III.B): frozen dataclasses, standard library only.

This module imports nothing beyond the standard library, so the config (``cr3bp_analysis.params``, validated
by pydantic as a stdlib-dataclass field) and the CLI can build and check the parameters without loading the
numerical stack.  Every field has a default; ``__post_init__`` checks ranges and raises a ``ValueError`` that
names the field; ``__pydantic_config__`` makes pydantic reject unknown keys.  :func:`StructureParams.from_dict`
builds the same objects from a plain (YAML/JSON) dict without pydantic.

Units: times TU (1 TU ≈ 4.34 days, the Earth–Moon time unit), masses kg, α in the problem's own unit (N for
the CR3BP thrust).  The analysis modules re-export their own parameter class from here
(:class:`ModeParams` from :mod:`amorgs.analysis.hyperplanes`, …).
"""

from __future__ import annotations

from dataclasses import dataclass, fields

#: Interval kinds of the per-segment control statistics (:mod:`amorgs.analysis.controls`).
INTERVALS = ("mean_ci", "percentile")
#: Feature sets of the diversity surrogate metric (:mod:`amorgs.analysis.diversity`).
FEATURE_SETS = ("times", "full")
#: Most trajectories drawn in each of Figs. 9 and 10 (labelled I … VI and A … F).
MAX_TRAJECTORIES = 6

#: Pydantic reads this class attribute of a stdlib dataclass: unknown keys are errors.
_FORBID_EXTRA = {"extra": "forbid"}


def _positive(owner: object, *names: str) -> None:
    for name in names:
        value = getattr(owner, name)
        if not value > 0:
            raise ValueError(f"{type(owner).__name__}.{name} must be > 0, got {value!r}")


def _at_least_one(owner: object, *names: str) -> None:
    for name in names:
        value = getattr(owner, name)
        if not value >= 1:
            raise ValueError(f"{type(owner).__name__}.{name} must be ≥ 1, got {value!r}")


def _all_positive(owner: object, name: str, values) -> None:
    bad = [v for v in values if not v > 0]
    if bad:
        raise ValueError(f"{type(owner).__name__}.{name} must hold values > 0, got {tuple(values)!r}")


@dataclass(frozen=True)
class ModeParams:
    """Mode detection of the TOF density (all lengths in TU).

    bandwidth: standard deviation of the Gaussian kernel.
    grid_step: spacing of the grid the density is evaluated on.
    min_prominence: peak prominence as a fraction of the largest density value, in [0, 1).
    min_separation: smallest distance between two reported modes.
    min_members: fewest solutions within ``delta`` of a mode for it to count as a hyperplane.
    delta: half-width of a hyperplane in TOF, Eq. 32 (paper: 0.25 TU).
    """

    __pydantic_config__ = _FORBID_EXTRA

    bandwidth: float = 0.1
    grid_step: float = 0.005
    min_prominence: float = 0.02
    min_separation: float = 1.0
    min_members: int = 3
    delta: float = 0.25

    def __post_init__(self) -> None:
        _positive(self, "bandwidth", "grid_step", "min_separation", "delta")
        if not 0 <= self.min_prominence < 1:
            raise ValueError(f"ModeParams.min_prominence must be in [0, 1), got {self.min_prominence!r}")
        _at_least_one(self, "min_members")


@dataclass(frozen=True)
class FunnelParams:
    """Gaussian-mixture funnel clustering.

    max_funnels: largest number of mixture components tried.
    min_per_funnel: fewest members of a funnel; fits with a smaller cluster are not admissible.
    use_mass: add m_f to the in-plane coordinates as a clustering feature.
    seed: random_state of the mixture fits (≥ 0).
    n_init: initialisations per fit (best likelihood kept).
    """

    __pydantic_config__ = _FORBID_EXTRA

    max_funnels: int = 4
    min_per_funnel: int = 3
    use_mass: bool = False
    seed: int = 0
    n_init: int = 5

    def __post_init__(self) -> None:
        _at_least_one(self, "max_funnels", "min_per_funnel", "n_init")
        if self.seed < 0:
            raise ValueError(f"FunnelParams.seed must be ≥ 0, got {self.seed!r}")


#: η of Eq. 12 (dimensionless, on (τ_s/40, τ_i/15, τ_f/15)) — defined here only.
ETA = 0.02


@dataclass(frozen=True)
class DiversityParams:
    """Diversity surrogate of Eq. 12.

    eta: threshold η (dimensionless, in the scaled coordinates of ``features``); the default 0.02 is 0.8 TU of
        τ_s or 0.3 TU of τ_i or τ_f — about the width 2δ of a hyperplane band.
    features: ``"times"`` or ``"full"`` (see :mod:`amorgs.analysis.diversity`).
    time_scale: divisors of (τ_s, τ_i, τ_f) in TU — the decision-box upper bounds of spec §5.
    """

    __pydantic_config__ = _FORBID_EXTRA

    eta: float = ETA
    features: str = "times"
    time_scale: tuple[float, float, float] = (40.0, 15.0, 15.0)

    def __post_init__(self) -> None:
        if self.features not in FEATURE_SETS:
            raise ValueError(f"DiversityParams.features must be one of {FEATURE_SETS}, got {self.features!r}")
        _positive(self, "eta")
        if len(self.time_scale) != 3:
            raise ValueError(f"DiversityParams.time_scale must hold 3 values (TU), got {self.time_scale!r}")
        _all_positive(self, "time_scale", self.time_scale)


_NESTED = {"modes": ModeParams, "funnels": FunnelParams, "diversity": DiversityParams}
_TUPLES = ("fig03_alphas", "ma_windows_macro", "ma_windows_micro", "funnel_planes")


@dataclass(frozen=True)
class StructureParams:
    """Parameters of the structure analysis (times in TU, masses in kg).

    modes, funnels, diversity: parameters of those steps (see their modules).
    focus_alpha: α of the in-depth analysis (Figs. 5–13); the largest α present if it has no solutions.
    fig03_alphas: α shown in Figs. 3–4; each is replaced by the nearest α with converged solutions that is not
        already shown (so the paper's (0.1, 0.3, 1.0) becomes (0.1, 0.5, 1.0) on data at 0.1, 0.5, 1.0).
    histogram_bin: TOF bin width of Fig. 4.
    ma_windows_macro, ma_windows_micro: moving-average widths of Figs. 7 and 8.
    micro_center: centre of the Fig. 8 zoom; None → the mode with the most converged solutions at focus α.
    micro_half_width: half-width of the Fig. 8 zoom.
    funnel_planes: T of the hyperplanes of Figs. 11–12 (snapped to the nearest detected mode); None → the two
        hyperplanes with the most β-filtered solutions at focus α.
    fig06_max_planes: most hyperplanes shown in Fig. 6 (the most populated ones, in TOF order).
    contour_levels: filled contour levels of Figs. 6, 11, 12.
    control_interval: ``"mean_ci"`` or ``"percentile"`` (see :mod:`amorgs.analysis.controls`).
    n_trajectories: solutions drawn in each of Figs. 9 and 10, 0 … :data:`MAX_TRAJECTORIES`.
    """

    __pydantic_config__ = _FORBID_EXTRA

    modes: ModeParams = ModeParams()
    funnels: FunnelParams = FunnelParams()
    diversity: DiversityParams = DiversityParams()
    focus_alpha: float = 1.0
    fig03_alphas: tuple[float, ...] = (0.1, 0.3, 1.0)
    histogram_bin: float = 0.1
    ma_windows_macro: tuple[float, ...] = (0.25, 0.5, 1.0)
    ma_windows_micro: tuple[float, ...] = (0.01, 0.05, 0.1)
    micro_center: float | None = None
    micro_half_width: float = 1.0
    funnel_planes: tuple[float, ...] | None = None
    fig06_max_planes: int = 8
    contour_levels: int = 10
    control_interval: str = "mean_ci"
    n_trajectories: int = 3

    def __post_init__(self) -> None:
        if self.control_interval not in INTERVALS:
            raise ValueError(f"StructureParams.control_interval must be one of {INTERVALS}, "
                             f"got {self.control_interval!r}")
        if not 0 <= self.n_trajectories <= MAX_TRAJECTORIES:
            raise ValueError(f"StructureParams.n_trajectories must be in [0, {MAX_TRAJECTORIES}], "
                             f"got {self.n_trajectories!r}")
        _positive(self, "focus_alpha", "histogram_bin", "micro_half_width")
        if self.micro_center is not None:
            _positive(self, "micro_center")
        for name in ("fig03_alphas", "ma_windows_macro", "ma_windows_micro", "funnel_planes"):
            _all_positive(self, name, getattr(self, name) or ())
        _at_least_one(self, "fig06_max_planes", "contour_levels")

    @classmethod
    def from_dict(cls, values: dict | None) -> StructureParams:
        """Build from a plain (e.g. YAML/JSON) dict; nested ``modes``/``funnels``/``diversity`` dicts and lists
        for tuples allowed.  Unknown keys (also nested ones) raise a ``ValueError`` naming them."""
        values = dict(values or {})
        _reject_unknown(cls, values, "")
        for key, kind in _NESTED.items():
            if isinstance(values.get(key), dict):
                _reject_unknown(kind, values[key], f"{key}.")
                values[key] = kind(**{k: tuple(v) if isinstance(v, list) else v for k, v in values[key].items()})
        for key in _TUPLES:
            if isinstance(values.get(key), list):
                values[key] = tuple(values[key])
        return cls(**values)


def _reject_unknown(kind: type, values: dict, prefix: str) -> None:
    unknown = sorted(set(values) - {f.name for f in fields(kind)})
    if unknown:
        raise ValueError(f"unknown structure-analysis parameter(s) {[prefix + k for k in unknown]}")
