"""The typed options of the local solvers: one frozen class per solver, every default defined here and only here.

* :class:`IpoptOptions` — IPOPT on the CR3BP forward–backward transcription (:mod:`amorgs.solvers.ipopt`),
  with the transcription's own choices nested as :class:`TranscriptionOptions`;
* :class:`BfgsOptions` — scipy BFGS on De Jong's 5th function (:mod:`amorgs.problems.dejong`).

They are pydantic dataclasses: a wrong type, a value out of range or an unknown key raises a
``pydantic.ValidationError`` (a ``ValueError``) that names the field, and they can serve directly as the types
of the config keys ``problems.cr3bp.solver`` / ``problems.dejong.solver`` of a pydantic config model (their
JSON Schema comes from the field annotations below).  ``to_dict`` gives the plain JSON-able dict that is
hashed into every solution row (``digest``, stored as ``options_hash``); ``from_mapping`` builds an object
from such a dict (a config section, a CLI JSON string once parsed).
"""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import json
import math
from collections.abc import Mapping
from typing import Annotated, Any, Literal, Protocol, TypeVar

import pydantic
from pydantic import Field
from pydantic.dataclasses import dataclass

_CONFIG = pydantic.ConfigDict(extra="forbid")
_T = TypeVar("_T")


def _sha12(obj: Any) -> str:
    """First 12 hex digits of the SHA-256 of ``obj`` as sorted-key JSON."""
    return hashlib.sha256(json.dumps(obj, sort_keys=True, default=str).encode()).hexdigest()[:12]


class _Options:
    """``to_dict`` / ``from_mapping`` shared by the options classes below."""

    def to_dict(self) -> dict[str, Any]:
        """The options as a plain JSON-able dict (nested options as nested dicts); ``from_mapping`` inverts it."""
        return dataclasses.asdict(self)  # type: ignore[call-overload]

    def hash_dict(self) -> dict[str, Any]:
        """What the options hash covers: :meth:`to_dict`, less what a nested class declares not in play."""
        return {f.name: (v.hash_dict() if isinstance(v := getattr(self, f.name), _Options) else v)
                for f in dataclasses.fields(self)}  # type: ignore[arg-type]

    @classmethod
    def from_mapping(cls: type[_T], mapping: Mapping[str, Any] | None) -> _T:
        """Build from a plain mapping (e.g. a config section); missing keys take their defaults."""
        return _adapter(cls).validate_python(dict(mapping or {}))


@functools.cache
def _adapter(cls: type) -> pydantic.TypeAdapter:
    return pydantic.TypeAdapter(cls)


@dataclass(frozen=True, config=_CONFIG)
class TranscriptionOptions(_Options):
    """Integration and layout choices of the CR3BP transcription (:mod:`amorgs.problems.cr3bp.transcription`);
    they never change the stored 64-vector.  Use :meth:`for_alpha` to resolve the α-dependent step count and
    controls."""

    steps_per_segment: Annotated[int, Field(ge=1, description=(
        "RK8 steps per thrust segment (length τ_s/N) at α = step_scaling_alpha; below it the count grows as "
        "ceil(steps_per_segment · sqrt(step_scaling_alpha / α)) because low thrust means long thrust arcs"))] = 24
    coast: Annotated[Literal["rk8", "interpolant"], Field(description=(
        "how the two coast arcs (τ_i from ξ₀, τ_f back from ξ_f) are evaluated: 'rk8' integrates them with "
        "steps_per_coast fixed steps at every evaluation; 'interpolant' reads them off a cubic B-spline of the "
        "ballistic flow from the fixed boundary state, sampled every coast_grid_step TU (RK8 at ≤ 0.001 TU) "
        "once when the NLP is built — the coasts start from fixed states, so the flow is a function of one "
        "scalar each (the library's generation 2; 'rk8' is generation 1; docs/performance.md)"))] = "interpolant"
    coast_grid_step: Annotated[float, Field(gt=0, le=0.1, description=(
        "'interpolant' coasts: spacing of the B-spline's samples of the ballistic flow (TU)"))] = 0.001
    steps_per_coast: Annotated[int, Field(ge=1, description=(
        "'rk8' coasts: RK8 steps per coast arc (τ_i or τ_f), split evenly over coast_pieces"))] = 320
    coast_pieces: Annotated[int, Field(ge=1, description=(
        "'rk8' coasts: sub-arcs per coast (each a shooting node with multiple_shooting); must divide "
        "steps_per_coast ('interpolant' coasts are one piece)"))] = 8
    multiple_shooting: Annotated[bool, Field(description=(
        "node states at every piece boundary (the exact Hessian becomes sparse and cheap)"))] = False
    step_scaling_alpha: Annotated[float, Field(ge=0, description=(
        "α (N) at which steps_per_segment applies; 0 switches the α scaling off"))] = 0.3
    scale_down: Annotated[bool, Field(description=(
        "apply the step law above step_scaling_alpha too (fewer steps at high thrust), never below "
        "min_steps_per_segment"))] = False
    min_steps_per_segment: Annotated[int, Field(ge=1, description="floor of the scaled step count")] = 1
    controls: Annotated[Literal["spherical", "cartesian"], Field(description=(
        "the NLP's control variables per segment: 'spherical' solves on the stored (θ, φ, ρ); 'cartesian' on "
        "a direction v ∈ [−1, 1]³ with ‖v‖² ≤ 1 (one inequality per segment) and the throttle ρ ∈ [0, 1]: thrust "
        "ρ·v, fuel flow ρ, so ‖v‖ = 1 wherever ρ > 0 at a fuel optimum — no azimuth wrap and no singular "
        "elevation; stored solutions keep the (θ, φ, ρ) layout"))] = "spherical"
    controls_switch_alpha: Annotated[float, Field(ge=0, description=(
        "with controls 'cartesian': the α (N) from which on the solve uses the spherical controls instead "
        "(Cartesian controls converge more often at low thrust and less often at high thrust, "
        "docs/performance.md); 0 = Cartesian at every α"))] = 0.0

    def hash_dict(self) -> dict[str, Any]:
        """The options that determine the solve: the keys of the coast kind not in use are left out, so
        'rk8' transcriptions keep the ``options_hash`` they had before 'interpolant' existed."""
        unused = ("coast", "coast_grid_step") if self.coast == "rk8" else ("steps_per_coast", "coast_pieces")
        if self.controls == "spherical":  # the hash of every solver from before the option existed
            unused += ("controls", "controls_switch_alpha")
        return {k: v for k, v in self.to_dict().items() if k not in unused}

    @pydantic.model_validator(mode="after")
    def _pieces_divide_coast(self) -> TranscriptionOptions:
        if self.steps_per_coast % self.coast_pieces:
            raise ValueError(f"transcription option steps_per_coast={self.steps_per_coast} must be a multiple of "
                             f"coast_pieces={self.coast_pieces}")
        return self

    def for_alpha(self, alpha: float) -> TranscriptionOptions:
        """The options with ``steps_per_segment`` and ``controls`` resolved for this α (the scaling and the
        switch off)."""
        steps = self.steps_per_segment
        if self.step_scaling_alpha > 0 and (alpha < self.step_scaling_alpha or self.scale_down):
            steps = math.ceil(self.steps_per_segment * math.sqrt(self.step_scaling_alpha / alpha) - 1e-9)
            steps = max(steps, self.min_steps_per_segment)
        controls = self.controls
        if controls == "cartesian" and 0 < self.controls_switch_alpha <= alpha:
            controls = "spherical"
        return dataclasses.replace(self, steps_per_segment=steps, step_scaling_alpha=0.0, scale_down=False,
                                   min_steps_per_segment=1, controls=controls, controls_switch_alpha=0.0)


@dataclass(frozen=True, config=_CONFIG)
class IpoptOptions(_Options):
    """Everything that determines a CR3BP local solve with IPOPT; hashed into every solution row.

    ``max_iter`` is the primary cap (deterministic); ``max_wall_s`` is only a safety net.  Tolerances on
    defects are in the transcription's internal units: position DU, velocity VU, fuel tonnes.

    Stall abort (deterministic: iteration counts and infeasibility only, never wall time): with
    ``stall_window`` = W > 0 a solve stops with status ``aborted_stalled`` at the first iteration i ≥ W where
    the best primal infeasibility so far (max |g| of the match point; an inequality only where it is violated)
    is above ``stall_floor`` and above ``stall_factor`` × the best up to iteration i − W.  The rule was chosen from the infeasibility traces of converged vs failed starts
    (docs/performance.md) and is off by default.
    """

    hessian: Annotated[Literal["limited-memory", "exact"], Field(description=(
        "IPOPT hessian_approximation: L-BFGS ('limited-memory') or the exact Lagrangian Hessian"))] = "limited-memory"
    lbfgs_memory: Annotated[int, Field(ge=1, description=(
        "L-BFGS history length in update pairs (IPOPT limited_memory_max_history). 30 re-converges from near "
        "a solution (warm starts); 6 is ≈ 1.4× faster from uniform starts but converges slowly near a "
        "solution at low α, so only the library config (cold starts) uses it (docs/performance.md)"))] = 30
    lbfgs_aug_solver: Annotated[Literal["sherman-morrison", "extended"], Field(description=(
        "IPOPT limited_memory_aug_solver: how the L-BFGS low-rank term enters the linear system — "
        "'sherman-morrison' (IPOPT's default: 2 × history extra back-solves per factorisation) or 'extended' "
        "(the low-rank factors as extra rows of one sparse system; ≈ 3 ms less IPOPT work per iteration "
        "here, but re-solves from converged solutions fail far more often, docs/performance.md)"))] = "sherman-morrison"
    max_iter: Annotated[int, Field(ge=1, description=(
        "IPOPT iteration cap (iterations): the primary, deterministic limit"))] = 1000
    max_wall_s: Annotated[float, Field(gt=0, description=(
        "IPOPT wall-clock cap per solve (s), a safety net only: under load it changes outcomes; the multistart "
        "pool kills a worker stuck past 2 × max_wall_s + 30 s"))] = 300.0
    tol: Annotated[float, Field(gt=0, description="IPOPT tol: scaled NLP error tolerance (dimensionless)")] = 1e-6
    acceptable_tol: Annotated[float, Field(gt=0, description=(
        "IPOPT acceptable_tol: the looser 'acceptable' NLP error (dimensionless)"))] = 1e-4
    acceptable_iter: Annotated[int, Field(ge=0, description=(
        "IPOPT acceptable_iter: consecutive acceptable iterations that end a solve (iterations; 0: never)"))] = 10
    feasibility_tol: Annotated[float, Field(gt=0, description=(
        "bound on the NLP's own match-point defect max|g| (DU, VU, tonnes) for a solve to count; IPOPT "
        "constr_viol_tol and acceptable_constr_viol_tol"))] = 1e-8
    verify_tol: Annotated[float, Field(gt=0, description=(
        "bound on the independent DOP853 re-propagation defect (DU, VU, tonnes) for a solve to be "
        "'converged' (spec §6)"))] = 1e-5
    linear_solver: Annotated[str, Field(min_length=1, description=(
        "IPOPT linear_solver ('mumps' or 'spral' in the pip casadi build)"))] = "mumps"
    stall_window: Annotated[int, Field(ge=0, description=(
        "stall abort window W (IPOPT iterations); 0 switches the abort off"))] = 0
    stall_factor: Annotated[float, Field(gt=0, le=1, description=(
        "stall abort: the best max|g| must fall below this fraction of its value W iterations earlier "
        "(dimensionless)"))] = 0.5
    stall_floor: Annotated[float, Field(ge=0, description=(
        "stall abort: never abort once the best max|g| is at or below this (DU, VU, tonnes)"))] = 1e-6
    compile: Annotated[Literal["cache", "jit", "none"], Field(description=(
        "how the NLP functions are compiled: 'cache' (C code built once per machine, "
        ":mod:`amorgs.solvers.codegen`), 'jit' (per process) or 'none' (CasADi's virtual machine, ≈ 6× slower)"
    ))] = "cache"
    compile_flags: Annotated[str, Field(pattern=r"\S", description=(
        "gcc flags of the compiled NLP (part of the cache key, with the CPU model under -march=native); "
        "-ffp-contract=off keeps the floating-point results of -O2 bit for bit, only the speed changes"
    ))] = "-O3 -march=native -ffp-contract=off"
    ipopt_options: Annotated[dict[str, str | int | float], Field(description=(
        "extra IPOPT options, applied last (they override the ones derived from the fields above)"
    ))] = dataclasses.field(default_factory=dict)
    transcription: Annotated[TranscriptionOptions, Field(description=(
        "integration and layout of the transcription"))] = dataclasses.field(default_factory=TranscriptionOptions)

    def hash_dict(self) -> dict[str, Any]:
        """:meth:`to_dict` as hashed: ``lbfgs_aug_solver`` at IPOPT's own default is left out, so options from
        before the field existed keep their ``options_hash``."""
        d = super().hash_dict()
        if d["lbfgs_aug_solver"] == "sherman-morrison":
            del d["lbfgs_aug_solver"]
        return d

    def digest(self) -> str:
        """Short stable hash of :meth:`hash_dict` (stored in every row as ``options_hash``)."""
        return _sha12(self.hash_dict())


@dataclass(frozen=True, config=_CONFIG)
class BfgsOptions(_Options):
    """scipy BFGS with the analytic gradient on De Jong's 5th function; hashed into every solution row."""

    gtol: Annotated[float, Field(gt=0, description=(
        "scipy gtol: stop when the ∞-norm of the gradient of J is below this (J and x are dimensionless)"))] = 1e-6
    maxiter: Annotated[int, Field(ge=1, description="BFGS iteration cap (iterations)")] = 500

    def digest(self) -> str:
        """Short stable hash of :meth:`to_dict`, keyed ``{"problem": "dejong", "options": …}`` as De Jong rows
        have always been (so the hash of the same options does not change)."""
        return _sha12({"problem": "dejong", "options": self.to_dict()})


class Options(Protocol):
    """What the multistart pool needs of a solver's options (both classes above)."""

    def to_dict(self) -> dict[str, Any]: ...

    def digest(self) -> str: ...


def as_options(options_type: type[_T], options: _T | Mapping[str, Any] | None) -> _T:
    """``options`` as an ``options_type``: an instance as it is, ``None`` as the defaults, a mapping through
    ``from_mapping`` (the path of plain config dicts); anything else raises ``TypeError``."""
    if isinstance(options, options_type):
        return options
    if options is None or isinstance(options, Mapping):
        return options_type.from_mapping(options)  # type: ignore[attr-defined]
    raise TypeError(f"solver options must be {options_type.__name__} or a mapping, got {type(options).__name__}")
