"""The problem contract: one set of tests looped over every registered family (:data:`amorgs.problems.FAMILIES`).

A family registered there is checked here with nothing else to write but its example rows for the quality
filter (:data:`QUALITY_EXAMPLES`): the layout and bounds agree, uniform guesses are inside the bounds and
seeded, a bad guess names its field, the solver options and the quality filter round-trip and have defaults,
α outside the family's range is refused (by the problem and by the config), the config's sections are the
family's types at the family's defaults, the problem pickles (the multistart pool sends it to its workers),
and (slow) one real solve through the pool gives a valid solution table.
"""

from __future__ import annotations

import dataclasses
import json
import math
import pickle
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pydantic
import pytest

from amorgs.config import Config, ConfigError, from_mapping
from amorgs.problems import FAMILIES, PROBLEMS, QualityFilter, get_family, get_problem
from amorgs.solvers.multistart import resolve_options
from amorgs.solvers.options import as_options

#: Per family: rows of a tiny solution table (the columns its quality filter reads) and, per row, whether the
#: filter at its default thresholds keeps it.  Every row that would pass but did not converge must fail.
QUALITY_EXAMPLES: dict[str, tuple[list[dict], list[bool]]] = {
    "dejong": (
        [{"converged": True, "objective": 0.998}, {"converged": True, "objective": 10.0},
         {"converged": True, "objective": 499.9}, {"converged": False, "objective": 0.998}],
        [True, True, False, False],
    ),
    "cr3bp": (
        [{"converged": True, "m_f": 430.0, "objective": -430.0},
         {"converged": True, "m_f": 415.0, "objective": -415.0},
         {"converged": True, "m_f": 414.9, "objective": -414.9},
         {"converged": False, "m_f": 430.0, "objective": -430.0}],
        [True, True, False, False],
    ),
}


@pytest.fixture(scope="module", params=PROBLEMS)
def family(request):
    return FAMILIES[request.param]


@pytest.fixture(scope="module")
def problem(family):
    return family.build()


def _alphas(family) -> tuple[float, float, float]:
    lo, hi = family.alpha_range
    return lo, 0.5 * (lo + hi), hi


# ------------------------------------------------------------------------------------------- the registry


def test_the_registry_names_every_family_once():
    assert PROBLEMS == tuple(FAMILIES) and len(set(PROBLEMS)) == len(PROBLEMS)
    assert all(name == f.name for name, f in FAMILIES.items())
    with pytest.raises(ValueError, match=re.escape(f"unknown problem 'nope'; choose one of {PROBLEMS}")):
        get_family("nope")
    with pytest.raises(ValueError, match="unknown problem 'nope'"):
        get_problem("nope")


def test_the_config_has_one_section_per_family():
    assert set(type(Config().problems).model_fields) == set(FAMILIES)


def test_every_family_has_quality_examples():
    assert set(QUALITY_EXAMPLES) == set(FAMILIES), "add the new family's example rows to QUALITY_EXAMPLES"


def test_importing_the_registry_and_the_config_loads_no_solver():
    """The families' contracts are read by the config (every CLI call, every job): no CasADi, no scipy there."""
    code = ("import sys, amorgs.problems, amorgs.config; "
            "print(sorted(m for m in ('casadi', 'scipy', 'torch') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"


# ---------------------------------------------------------------------------------------- the problem


def test_the_problem_is_its_familys(family, problem):
    assert get_problem(family.name).name == problem.name == family.name
    assert tuple(problem.alpha_range) == tuple(family.alpha_range)
    assert problem.options_type is family.options_type


def test_layout_and_bounds_agree(problem):
    names = problem.variable_names
    assert isinstance(names, tuple) and names and all(isinstance(n, str) and n for n in names)
    assert len(set(names)) == len(names), "variable names must be unique (they are table columns)"
    for bound in (problem.lower, problem.upper):
        assert isinstance(bound, np.ndarray) and bound.dtype == float and bound.shape == (len(names),)
        assert np.isfinite(bound).all()
    assert (problem.lower < problem.upper).all()


def test_sample_uniform_is_inside_the_bounds_and_seeded(family, problem):
    n_var = len(problem.variable_names)
    for alpha in _alphas(family):
        x = problem.sample_uniform(alpha, 40, np.random.default_rng(5))
        assert x.shape == (40, n_var)
        assert (x >= problem.lower).all() and (x <= problem.upper).all()
        for row in x:
            np.testing.assert_array_equal(problem.check_guess(row), row)
        np.testing.assert_array_equal(x, problem.sample_uniform(alpha, 40, np.random.default_rng(5)))
        assert not np.array_equal(x, problem.sample_uniform(alpha, 40, np.random.default_rng(6)))
    assert problem.sample_uniform(_alphas(family)[1], 0, np.random.default_rng(0)).shape == (0, n_var)


def test_alpha_outside_the_range_is_refused(family, problem):
    lo, hi = family.alpha_range
    assert math.isfinite(lo) and math.isfinite(hi) and lo < hi and family.alpha_unit
    for alpha in (lo - 1e-3 * (hi - lo), hi + 1e-3 * (hi - lo), math.nan):
        with pytest.raises(ValueError, match=family.name):
            problem.sample_uniform(alpha, 1, np.random.default_rng(0))
    outside = hi + 0.1 * (hi - lo)
    with pytest.raises(ConfigError, match=re.escape(f"problems.{family.name}.alphas: α = {outside!r} lies outside "
                                                    f"the problem's range [{lo:g}, {hi:g}] {family.alpha_unit}")):
        from_mapping({"problems": {family.name: {"alphas": {"test": [outside]}}}})


def test_a_bad_guess_names_its_field(problem):
    good = problem.sample_uniform(problem.alpha_range[1], 1, np.random.default_rng(1))[0]
    with pytest.raises(ValueError, match="length"):
        problem.check_guess(good[:-1])
    for i, name in enumerate(problem.variable_names):
        cases = ((math.nan, "not finite"), (problem.upper[i] + 1.0, "bounds"), (problem.lower[i] - 1.0, "bounds"))
        for value, why in cases:
            bad = good.copy()
            bad[i] = value
            with pytest.raises(ValueError, match=rf"{problem.name}: .*{re.escape(repr(name))}.*{why}"):
                problem.check_guess(bad)


def test_the_problem_pickles(family, problem):
    """The multistart pool pickles the problem object to every worker."""
    back = pickle.loads(pickle.dumps(problem))
    assert back.name == problem.name and back.variable_names == problem.variable_names
    np.testing.assert_array_equal(back.lower, problem.lower)
    alpha = _alphas(family)[1]
    np.testing.assert_array_equal(back.sample_uniform(alpha, 3, np.random.default_rng(2)),
                                  problem.sample_uniform(alpha, 3, np.random.default_rng(2)))


# ------------------------------------------------------------------------------------ solver options


def test_solver_options_round_trip_with_defaults(family, problem):
    options_type = family.options_type
    defaults = options_type()
    assert options_type.from_mapping(defaults.to_dict()) == defaults
    assert options_type.from_mapping(json.loads(json.dumps(defaults.to_dict()))) == defaults
    assert pickle.loads(pickle.dumps(defaults)) == defaults
    assert re.fullmatch(r"[0-9a-f]{12}", defaults.digest()) and defaults.digest() == options_type().digest()
    assert as_options(options_type, None) == resolve_options(problem, None) == resolve_options(problem, {}) == defaults
    with pytest.raises(ValueError, match="no_such_option"):
        options_type.from_mapping({"no_such_option": 1})


# ------------------------------------------------------------------------------------- quality filter


def test_quality_filter_on_a_tiny_table(family):
    quality = family.quality_type()
    rows, expected = QUALITY_EXAMPLES[family.name]
    table = pd.DataFrame(rows, index=[10 + i for i in range(len(rows))])
    assert isinstance(quality, QualityFilter)
    mask = quality.mask(table)
    assert mask.dtype == bool and mask.index.equals(table.index) and mask.tolist() == expected
    kept = quality.select(table)
    assert kept.index.tolist() == list(range(sum(expected))) and kept.columns.equals(table.columns)
    pd.testing.assert_frame_equal(kept, table[expected].reset_index(drop=True))
    assert not quality.mask(table.assign(converged=False)).any(), "a solve that did not converge never passes"
    assert quality.select(table.iloc[:0]).empty


def test_quality_filter_round_trips_and_documents_its_thresholds(family):
    quality_type = family.quality_type
    defaults = quality_type()
    assert dataclasses.fields(quality_type), "a quality filter has thresholds"
    assert quality_type.from_mapping(defaults.to_dict()) == quality_type.from_mapping(None) == defaults
    assert pickle.loads(pickle.dumps(defaults)) == defaults
    with pytest.raises(ValueError, match="no_such_threshold"):
        quality_type.from_mapping({"no_such_threshold": 1.0})
    properties = pydantic.TypeAdapter(quality_type).json_schema()["properties"]
    undocumented = [k for k, v in properties.items() if not v.get("description")]
    assert not undocumented, f"{quality_type.__name__}: thresholds without a description (and unit) {undocumented}"


# ------------------------------------------------------------------------------------------- defaults


def test_the_config_sections_are_the_familys_types_at_its_defaults(family):
    section = getattr(Config().problems, family.name)
    assert type(section.solver) is family.options_type and section.solver == family.options_type()
    assert type(section.filter) is family.quality_type and section.filter == family.quality_type()
    lo, hi = family.alpha_range
    assert all(lo <= a <= hi for a in section.alpha_values().values())


def test_the_workflow_steps_carry_the_familys_types(family):
    """The filter and generate jobs get the family's quality filter and options back from their settings JSON."""
    from amorgs.steps.filter import FilterSettings
    from amorgs.steps.generate import GenerateSettings

    quality = family.quality_type()
    settings = FilterSettings(problem=family.name, **quality.to_dict())
    assert FilterSettings.model_validate(json.loads(settings.model_dump_json())).quality() == quality
    options = family.options_type()
    generate = GenerateSettings(problem=family.name, alpha=family.alpha_range[0], seed=0, starts=1,
                                solver=options.to_dict())
    assert type(generate.solver) is family.options_type and generate.solver == options
    again = GenerateSettings.model_validate(json.loads(generate.model_dump_json()))
    assert again.solver == options


def test_the_filter_step_applies_the_familys_filter(family, tmp_path, monkeypatch):
    from amorgs import steps

    monkeypatch.chdir(tmp_path)  # no results/mlflow here: tracking is a no-op
    rows, expected = QUALITY_EXAMPLES[family.name]
    pd.DataFrame(rows).assign(problem=family.name, alpha=family.alpha_range[0], start=range(len(rows)),
                              iterations=10, wall_s=0.1).to_parquet("a.parquet")
    w = {"problem": family.name}
    outputs = steps.registry()["filter"].outputs(w)
    steps.run_step("filter", Config(), w, {"tables": ["a.parquet"]}, outputs)
    assert pd.read_parquet(outputs["table"])["start"].tolist() == [i for i, keep in enumerate(expected) if keep]
    report = json.loads(Path(outputs["report"]).read_text())
    assert report["thresholds"] == family.quality_type().to_dict() and report["high_quality"] == sum(expected)


def test_a_filter_job_refuses_another_familys_threshold():
    from amorgs.steps.filter import FilterSettings

    with pytest.raises(pydantic.ValidationError, match=r"\['max_objective'\] are thresholds of another problem"):
        FilterSettings(problem="cr3bp", min_final_mass_kg=415.0, max_objective=10.0)


# ----------------------------------------------------------------------------------------- a real solve


@pytest.mark.slow
def test_one_real_solve_through_the_pool(family, problem):
    """One uniform start at the top of the α range, the family's default options, one spawned worker."""
    from amorgs.data.tables import validate_solutions
    from amorgs.solvers.multistart import run_multistart

    alpha = family.alpha_range[1]
    df = run_multistart(problem, alpha, seed=0, starts=1, workers=1, progress=False)
    df.insert(int(df.columns.get_loc("seed")) + 1, "shard", 0)
    validate_solutions(df, problem.variable_names, where=f"{family.name} solve")
    row = df.iloc[0]
    assert (row["problem"], row["alpha"], row["start"]) == (family.name, alpha, 0)
    assert row["options_hash"] == family.options_type().digest()
    assert row["status"] not in ("exception", "crashed", "timeout"), row["message"]
    assert row["iterations"] >= 1 and row["wall_s"] > 0
    guess = df[[f"guess_{v}" for v in problem.variable_names]].to_numpy()
    np.testing.assert_array_equal(guess, problem.sample_uniform(alpha, 1, np.random.default_rng(0)))
    if row["converged"]:
        problem.check_guess(df[list(problem.variable_names)].to_numpy()[0])
        assert math.isfinite(row["objective"])
    assert family.quality_type().mask(df).tolist() in ([True], [False])
