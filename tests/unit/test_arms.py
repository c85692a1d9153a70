"""The table of arms (:mod:`amorgs.ablation.arms`): every entry is consistent, and every registered arm builds
a working sampler from tiny real models and a synthetic high-quality table with exactly the inputs it
declares — one test looped over every arm, so a new arm is checked by adding its entry."""

from __future__ import annotations

import math
import shutil
import subprocess
import sys

import numpy as np
import pytest
from cr3bp_synthetic import TRAIN_ALPHAS

from amorgs import layout
from amorgs.ablation import arms as A
from amorgs.models.names import CHECKPOINTS, CR3BP_MODELS, resolve
from amorgs.models.selector import SELECTOR_FILE
from amorgs.problems import get_problem


@pytest.fixture(scope="module")
def problem():
    return get_problem("cr3bp")


def test_the_table_is_consistent():
    names = [arm.name for arm in A.ARMS]
    assert len(set(names)) == len(names) and A.SAMPLER_NAMES == tuple(names)
    labels = [arm.label for arm in A.ARMS]
    assert all(labels) and len(set(labels)) == len(labels)
    for arm in A.ARMS:
        assert arm.role in A.ROLES, arm
        assert set(arm.models) <= set(CR3BP_MODELS) and len(set(arm.models)) == len(arm.models), arm
        assert not arm.pooled or arm.high_quality, f"{arm.name}: a pooled arm draws from the high-quality table"
        assert callable(resolve(arm.builder)), arm.builder
    assert sum(arm.paper for arm in A.ARMS) == 5  # the paper's five (Table 6)
    assert (A.BASELINE_ARM, A.REUSE_ARM, A.HEADLINE_ARM) == ("uniform", "nearest_alpha", "amorgs")
    assert A.LEARNED_SAMPLER_NAMES == tuple(arm.name for arm in A.ARMS if arm.models)


def test_the_table_imports_no_torch():
    """The config, the workflow and the figures read the table: it must not load the models."""
    code = "import sys, amorgs.ablation.arms, amorgs.config; print('torch' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "False"


@pytest.mark.parametrize("arm", A.ARMS, ids=lambda arm: arm.name)
def test_every_arm_builds_a_valid_sampler_from_what_it_declares(arm, problem, tiny_hq, tiny_models_dir, tmp_path):
    """Only the declared checkpoints in the models folder, the table only if declared: the arm builds, and its
    guesses are valid decision vectors at a test α between the training α."""
    for model in arm.models:
        shutil.copyfile(tiny_models_dir / CHECKPOINTS[model], tmp_path / CHECKPOINTS[model])
    if arm.transfer:
        shutil.copyfile(tiny_models_dir / SELECTOR_FILE, tmp_path / SELECTOR_FILE)
    sampler = A.build_sampler(arm.name, problem, tmp_path if arm.models or arm.transfer else None,
                              high_quality=tiny_hq if arm.high_quality else None,
                              train_alphas=TRAIN_ALPHAS if arm.high_quality else None,
                              perturbation_scale=0.02, gmm_components=2)
    assert sampler.name == arm.name
    x = sampler.sample(0.55, 12, np.random.default_rng(0))
    assert x.shape == (12, len(problem.variable_names)) == (12, 64)
    assert np.all(np.isfinite(x)) and np.all(x >= problem.lower) and np.all(x <= problem.upper)
    assert np.all(x[:, 4::3] < 2 * math.pi)
    for row in x:
        problem.check_guess(row)
    np.testing.assert_array_equal(x, sampler.sample(0.55, 12, np.random.default_rng(0)))  # seeded
    assert np.array_equal(x, sampler.sample(0.55, 12, np.random.default_rng(1))) == arm.rng_free  # as declared


@pytest.mark.parametrize("arm", A.ARMS, ids=lambda arm: arm.name)
def test_every_arm_refuses_to_build_without_what_it_declares(arm, problem, tiny_hq, tiny_models_dir, tmp_path):
    if arm.models:
        with pytest.raises(ValueError, match="needs a models directory"):
            A.build_sampler(arm.name, problem, None, high_quality=tiny_hq, train_alphas=TRAIN_ALPHAS)
        with pytest.raises(FileNotFoundError):  # an empty folder: its first checkpoint is missing
            A.build_sampler(arm.name, problem, tmp_path, high_quality=tiny_hq, train_alphas=TRAIN_ALPHAS)
    if arm.transfer:  # its checkpoints present, the selector missing
        for model in arm.models:
            shutil.copyfile(tiny_models_dir / CHECKPOINTS[model], tmp_path / CHECKPOINTS[model])
        with pytest.raises(FileNotFoundError, match="transfer selector not found"):
            A.build_sampler(arm.name, problem, tmp_path, high_quality=tiny_hq, train_alphas=TRAIN_ALPHAS)
    if arm.high_quality:
        with pytest.raises(ValueError, match="high-quality table"):
            A.build_sampler(arm.name, problem, tiny_models_dir)


@pytest.mark.parametrize("arm", A.ARMS, ids=lambda arm: arm.name)
def test_the_workflow_gives_every_arm_what_it_declares(arm):
    """A cell's Snakemake inputs come from the arm's entry: its checkpoints, and the table if it needs it."""
    from amorgs.steps.ablation import cell_inputs

    inputs = cell_inputs(arm.name, layout.CR3BP_MODEL, {"alpha": "0.150", "sampler": arm.name})
    assert inputs["models"] == [layout.CR3BP_MODEL.format(model=m) for m in arm.models]
    assert ("high_quality" in inputs) == arm.high_quality
    assert A.arm_label(arm.name) == arm.label and A.models_loaded([arm.name]) == sorted(arm.models)


def test_unknown_arms():
    with pytest.raises(ValueError, match="unknown sampler 'diffusion'"):
        A.get_arm("diffusion")
    assert A.arm_label("amorgs@seed=12") == "amorgs@seed=12"
