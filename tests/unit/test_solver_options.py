"""The typed solver options (amorgs.solvers.options): validation naming the field, one default per option,
dict round trip, and option hashes that match the rows already stored."""

import dataclasses
import json
import math
import pickle

import numpy as np
import pydantic
import pytest
import scipy.optimize

import amorgs.problems.dejong as dj
from amorgs.problems import get_problem
from amorgs.solvers.multistart import UNCAPPED_TIMEOUT_S, resolve_options, worker_timeout_s
from amorgs.solvers.options import BfgsOptions, IpoptOptions, TranscriptionOptions, as_options

#: options_hash of the options before issue 22 (RK8 coasts, Sherman–Morrison L-BFGS), computed before the
#: options became typed (issue 10): the hashes of the first library generation's rows must not change — those
#: options, spelled out, still hash like this.
HASH_RK8_DEFAULT_CONFIG = "42bf7b6dd566"  # cr3bp, config/default.yaml & library.yaml: max_iter 1000, max_wall_s 300.0
HASH_RK8_SMOKE_CONFIG = "c6fd4f9f0bf5"  # cr3bp, config/smoke.yaml: max_iter 50, max_wall_s 60.0
HASH_RK8_PAPER_CONFIG = "4fd020ee7912"  # cr3bp, config/paper.yaml: max_iter 1000, max_wall_s 500.0
#: The same configs with today's solver (issue 22: interpolated coasts, Sherman–Morrison L-BFGS, history 30).
HASH_DEFAULT_CONFIG = "5589dd21c0ef"
HASH_SMOKE_CONFIG = "cc78d27683b5"
HASH_PAPER_CONFIG = "087b38db5767"
#: The library's generation-2 solver: today's with L-BFGS history 6 (cold starts only).
HASH_LIBRARY_CONFIG = "e2d640cc3c36"
#: config/library.yaml's solver since generation 3: the same with Cartesian controls below α = 0.25.
HASH_LIBRARY_GEN3_CONFIG = "f3ab6821eb09"
GEN3 = {"lbfgs_memory": 6, "transcription": {"controls": "cartesian", "controls_switch_alpha": 0.25}}
HASH_DEJONG_CONFIG = "817e088f0114"  # dejong, every config: gtol 1e-6, maxiter 500
RK8 = {"lbfgs_aug_solver": "sherman-morrison", "lbfgs_memory": 30, "transcription": {"coast": "rk8"}}


@pytest.mark.parametrize(
    ("options_type", "mapping", "expected"),
    [
        (IpoptOptions, {"max_iter": 1000, "max_wall_s": 300.0, **RK8}, HASH_RK8_DEFAULT_CONFIG),
        (IpoptOptions, {"max_iter": 50, "max_wall_s": 60.0, **RK8}, HASH_RK8_SMOKE_CONFIG),
        (IpoptOptions, {"max_iter": 1000, "max_wall_s": 500.0, **RK8}, HASH_RK8_PAPER_CONFIG),
        (IpoptOptions, {"max_iter": 1000, "max_wall_s": 300.0}, HASH_DEFAULT_CONFIG),
        (IpoptOptions, {"max_iter": 50, "max_wall_s": 60.0}, HASH_SMOKE_CONFIG),
        (IpoptOptions, {"max_iter": 1000, "max_wall_s": 500.0}, HASH_PAPER_CONFIG),
        (IpoptOptions, {"max_iter": 1000, "max_wall_s": 300.0, "lbfgs_memory": 6}, HASH_LIBRARY_CONFIG),
        (IpoptOptions, {"max_iter": 1000, "max_wall_s": 300.0, **GEN3}, HASH_LIBRARY_GEN3_CONFIG),
        (BfgsOptions, {"gtol": 1.0e-6, "maxiter": 500}, HASH_DEJONG_CONFIG),
    ],
)
def test_hash_of_todays_config_options_is_unchanged(options_type, mapping, expected):
    assert options_type.from_mapping(mapping).digest() == expected


def test_the_options_of_the_coast_kind_not_in_use_are_not_hashed():
    rk8 = IpoptOptions.from_mapping(RK8)
    assert rk8.digest() == IpoptOptions.from_mapping(
        {**RK8, "transcription": {"coast": "rk8", "coast_grid_step": 0.01}}).digest()
    spline = IpoptOptions(transcription=TranscriptionOptions(coast="interpolant"))
    assert spline.digest() == IpoptOptions(transcription=TranscriptionOptions(
        coast="interpolant", steps_per_coast=640, coast_pieces=16)).digest()
    assert spline.digest() != IpoptOptions(transcription=TranscriptionOptions(
        coast="interpolant", coast_grid_step=0.002)).digest()
    for opts in (rk8, spline):  # the settings a job receives rebuild the same options (and hash)
        assert IpoptOptions.from_mapping(opts.to_dict()) == opts


def test_spherical_controls_hash_as_before_the_option_and_cartesian_ones_apart():
    """``controls`` enters the hash only when it is not the stored layout's own 'spherical': every solver from
    before the option existed keeps its hash (the library's generations 1 and 2 above)."""
    spherical = IpoptOptions.from_mapping({"lbfgs_memory": 6, "transcription": {"controls": "spherical"}})
    assert "controls" not in spherical.transcription.hash_dict()
    assert spherical.digest() == HASH_LIBRARY_CONFIG
    cartesian = IpoptOptions.from_mapping({"lbfgs_memory": 6, "transcription": {"controls": "cartesian"}})
    assert cartesian.transcription.hash_dict()["controls"] == "cartesian"
    assert cartesian.digest() != HASH_LIBRARY_CONFIG
    assert IpoptOptions.from_mapping(cartesian.to_dict()) == cartesian


def test_defaults_are_the_default_config_and_hash_like_it():
    assert IpoptOptions().digest() == HASH_DEFAULT_CONFIG
    assert BfgsOptions().digest() == HASH_DEJONG_CONFIG
    # the same effective options hash the same however they are spelled
    assert IpoptOptions.from_mapping({"max_wall_s": 300}).digest() == HASH_DEFAULT_CONFIG
    assert IpoptOptions.from_mapping(None) == IpoptOptions.from_mapping({}) == IpoptOptions()


def test_hash_changes_with_any_field():
    base = IpoptOptions()
    changed = [
        IpoptOptions(compile_flags="-O2"),
        IpoptOptions(stall_window=300),
        IpoptOptions(ipopt_options={"mu_strategy": "monotone"}),
        IpoptOptions(transcription=TranscriptionOptions(steps_per_segment=30)),
        IpoptOptions(lbfgs_aug_solver="extended"),
        IpoptOptions(transcription=TranscriptionOptions(coast="rk8")),
        IpoptOptions(lbfgs_memory=6),
    ]
    assert len({base.digest(), *(o.digest() for o in changed)}) == 1 + len(changed)
    assert BfgsOptions(maxiter=5).digest() != BfgsOptions().digest()


def test_one_default_is_what_the_solve_uses_when_the_caller_gives_nothing(monkeypatch):
    defaults = IpoptOptions()
    cr3bp = get_problem("cr3bp")
    for given in (None, {}):
        solver = cr3bp.make_local_solver(given)  # builds no NLP until the first solve
        assert solver.options == defaults
        assert solver._ipopt["max_wall_time"] == defaults.max_wall_s
        assert solver._ipopt["max_iter"] == defaults.max_iter
        assert resolve_options(cr3bp, given) == defaults
    assert worker_timeout_s(resolve_options(cr3bp, None)) == 2 * defaults.max_wall_s + 30.0

    seen = {}

    def spy(*args, options, **kwargs):
        seen.update(options)
        raise FloatingPointError("stop here")

    monkeypatch.setattr(scipy.optimize, "minimize", spy)  # the solver imports it when it solves
    dj.DeJong5().make_local_solver(None).solve(np.array([1.0, 2.0]), 0.5)
    assert seen == {"gtol": BfgsOptions().gtol, "maxiter": BfgsOptions().maxiter}
    assert worker_timeout_s(BfgsOptions()) == worker_timeout_s(None) == UNCAPPED_TIMEOUT_S


@pytest.mark.parametrize("options_type", [IpoptOptions, BfgsOptions, TranscriptionOptions])
def test_unknown_key_is_rejected_naming_it(options_type):
    with pytest.raises(pydantic.ValidationError, match="no_such_option"):
        options_type.from_mapping({"no_such_option": 1})
    with pytest.raises(pydantic.ValidationError, match="no_such_option"):
        options_type(no_such_option=1)


@pytest.mark.parametrize(
    ("options_type", "bad", "field"),
    [
        (IpoptOptions, {"max_iter": 0}, "max_iter"),
        (IpoptOptions, {"max_iter": 2.5}, "max_iter"),
        (IpoptOptions, {"max_wall_s": 0.0}, "max_wall_s"),
        (IpoptOptions, {"max_wall_s": "soon"}, "max_wall_s"),
        (IpoptOptions, {"tol": -1e-6}, "tol"),
        (IpoptOptions, {"lbfgs_memory": 0}, "lbfgs_memory"),
        (IpoptOptions, {"hessian": "bfgs"}, "hessian"),
        (IpoptOptions, {"compile": "always"}, "compile"),
        (IpoptOptions, {"compile_flags": " "}, "compile_flags"),
        (IpoptOptions, {"stall_window": -1}, "stall_window"),
        (IpoptOptions, {"stall_window": 1.5}, "stall_window"),
        (IpoptOptions, {"stall_factor": 0.0}, "stall_factor"),
        (IpoptOptions, {"stall_factor": 2.0}, "stall_factor"),
        (IpoptOptions, {"stall_floor": -1e-6}, "stall_floor"),
        (IpoptOptions, {"ipopt_options": ["mu_strategy"]}, "ipopt_options"),
        (IpoptOptions, {"transcription": {"min_steps_per_segment": 0}}, r"transcription\.min_steps_per_segment"),
        (IpoptOptions, {"transcription": {"no_such_option": 1}}, r"transcription\.no_such_option"),
        (IpoptOptions, {"transcription": {"steps_per_coast": 100, "coast_pieces": 8}}, "coast_pieces"),
        (IpoptOptions, {"transcription": {"coast": "cvodes"}}, r"transcription\.coast"),
        (IpoptOptions, {"lbfgs_aug_solver": "dense"}, "lbfgs_aug_solver"),
        (IpoptOptions, {"transcription": {"coast_grid_step": 0.0}}, r"transcription\.coast_grid_step"),
        (BfgsOptions, {"gtol": 0.0}, "gtol"),
        (BfgsOptions, {"maxiter": 0}, "maxiter"),
    ],
)
def test_bad_value_is_rejected_naming_the_field(options_type, bad, field):
    with pytest.raises(pydantic.ValidationError, match=field) as err:
        options_type.from_mapping(bad)
    assert isinstance(err.value, ValueError)  # callers that catch ValueError keep working


def test_to_dict_from_mapping_round_trip_and_json():
    opts = IpoptOptions(max_iter=77, max_wall_s=12.5, stall_window=40, ipopt_options={"mu_strategy": "monotone"},
                        transcription=TranscriptionOptions(steps_per_segment=30, scale_down=True))
    d = opts.to_dict()
    assert isinstance(d["transcription"], dict) and d["transcription"]["steps_per_segment"] == 30
    assert json.loads(json.dumps(d)) == d
    assert IpoptOptions.from_mapping(d) == opts and IpoptOptions.from_mapping(d).to_dict() == d
    assert set(d) == {f.name for f in dataclasses.fields(IpoptOptions)}
    assert set(d["transcription"]) == {f.name for f in dataclasses.fields(TranscriptionOptions)}
    b = BfgsOptions(gtol=1e-8, maxiter=20)
    assert BfgsOptions.from_mapping(b.to_dict()) == b and b.to_dict() == {"gtol": 1e-8, "maxiter": 20}


def test_frozen_picklable_and_passed_through():
    opts = IpoptOptions(max_iter=5)
    with pytest.raises(dataclasses.FrozenInstanceError):
        opts.max_iter = 6
    assert pickle.loads(pickle.dumps(opts)) == opts  # the worker pipe
    assert as_options(IpoptOptions, opts) is opts
    with pytest.raises(TypeError, match="IpoptOptions"):
        as_options(IpoptOptions, BfgsOptions())
    with pytest.raises(TypeError, match="BfgsOptions"):
        dj.DeJong5().make_local_solver(IpoptOptions())


def test_usable_as_config_model_field_with_a_documented_schema():
    class Solvers(pydantic.BaseModel):
        model_config = pydantic.ConfigDict(extra="forbid")
        cr3bp: IpoptOptions
        dejong: BfgsOptions

    cfg = Solvers.model_validate({"cr3bp": {"max_iter": 50, "max_wall_s": 60.0}, "dejong": {}})
    assert cfg.cr3bp.digest() == HASH_SMOKE_CONFIG and cfg.dejong == BfgsOptions()
    with pytest.raises(pydantic.ValidationError, match=r"cr3bp\.max_iters"):
        Solvers.model_validate({"cr3bp": {"max_iters": 50}, "dejong": {}})
    schema = Solvers.model_json_schema()
    for name in ("IpoptOptions", "BfgsOptions", "TranscriptionOptions"):
        definition = schema["$defs"][name]
        assert definition["additionalProperties"] is False
        undocumented = [k for k, v in definition["properties"].items() if not v.get("description")]
        assert not undocumented, f"{name}: fields without a description {undocumented}"
    ipopt = schema["$defs"]["IpoptOptions"]["properties"]
    assert ipopt["max_wall_s"]["default"] == IpoptOptions().max_wall_s and "(s)" in ipopt["max_wall_s"]["description"]
    assert ipopt["max_iter"]["minimum"] == 1 and math.isclose(ipopt["tol"]["default"], 1e-6)


def test_constraint_violation_counts_equalities_both_ways_and_inequalities_above_their_bound():
    from amorgs.solvers.ipopt import constraint_violation

    lbg, ubg = np.array([0.0, 0.0, -np.inf]), np.array([0.0, 0.0, 0.0])
    assert constraint_violation(np.array([1e-3, -2e-3, -0.9]), lbg, ubg) == 2e-3  # a slack inequality is 0
    assert constraint_violation(np.array([0.0, 0.0, 5e-3]), lbg, ubg) == 5e-3
    assert constraint_violation(np.array([0.0, np.nan, 0.0]), lbg, ubg) == math.inf
    assert constraint_violation(np.zeros(0), np.zeros(0), np.zeros(0)) == 0.0
