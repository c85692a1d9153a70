"""Module layering of the package, checked statically: the packages in a declared order, bottom to top, and no
module imports one above its own (:data:`LAYERS`); besides, ``analysis``/``ablation`` return data, ``figures``
draws it, and a step calls both (:data:`RULES`).

Every module under ``src/amorgs`` is parsed with :mod:`ast`; every ``import``/``from … import`` statement counts,
also those inside functions and under ``if TYPE_CHECKING:`` (a layer should not need a type from above it
either).  ``from a.b import c`` counts as importing ``a.b`` and ``a.b.c`` (``c`` may be a submodule).
"""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[2] / "src"
PACKAGE = SRC / "amorgs"

#: (layer prefix, forbidden import prefixes, why)
RULES = (
    ("amorgs.figures", ("amorgs.ablation.statistics", "amorgs.ablation.running_time", "amorgs.ablation.report",
                        "amorgs.models", "torch", "amorgs.analysis.structure_report", "amorgs.steps", "amorgs.cli"),
     "figures draw data handed to them: no statistics, no models, no torch"),
    *((layer, ("matplotlib", "mpl_toolkits", "amorgs.figures"), "data layers do not draw")
      for layer in ("amorgs.analysis", "amorgs.data", "amorgs.ablation", "amorgs.models", "amorgs.problems",
                    "amorgs.solvers")),
)
#: The packages bottom to top: a module may import its own layer and those below it, never one above.  The
#: solvers sit below the problems (a problem family builds its local solver from the solvers' options and
#: protocol; the solvers need nothing of a family); the config gathers every registry (problems, presets,
#: arms) into the typed experiment, so it sits above them; the steps, ``amorgs design`` and the checks use
#: everything; the command line is on top.
LAYERS = (
    ("amorgs.alphas", "amorgs.errors", "amorgs.layout", "amorgs.checkout"),
    ("amorgs.solvers",),
    ("amorgs.problems",),
    ("amorgs.data",),
    ("amorgs.analysis",),
    ("amorgs.models",),
    ("amorgs.ablation",),
    ("amorgs.config",),
    ("amorgs.tracking", "amorgs.lifeline", "amorgs.trajectory_export"),
    ("amorgs.figures",),
    ("amorgs.steps", "amorgs.design", "amorgs.checks", "amorgs.reference", "amorgs.certification", "amorgs.frontier"),
    ("amorgs.tools", "amorgs.library_grow", "amorgs.cli", "amorgs.__main__", "amorgs"),
)

#: Only the top layer may import the command line and the workflow steps: the command line itself, the steps,
#: ``python -m amorgs``, ``amorgs check-outputs`` (:mod:`amorgs.checks`), which verifies what the steps declare,
#: ``amorgs reference-export`` (:mod:`amorgs.reference`), which copies what the steps made, and ``amorgs frontier``
#: (:mod:`amorgs.frontier`), which reads the cells the steps of each fold declare.
TOP = ("amorgs.cli", "amorgs.steps")
TOP_IMPORTERS = ("amorgs.cli", "amorgs.steps", "amorgs.__main__", "amorgs.checks", "amorgs.reference",
                 "amorgs.certification", "amorgs.frontier")


def _within(name: str, prefix: str) -> bool:
    return name == prefix or name.startswith(prefix + ".")


def module_name(path: Path) -> str:
    parts = list(path.relative_to(SRC).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def imported_modules(source: str, module: str, is_package: bool = False) -> set[str]:
    """Every module named by an import statement anywhere in ``source`` (module ``module``)."""
    package = module if is_package else module.rpartition(".")[0]
    names: set[str] = set()
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import):
            names.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:  # relative: resolve against the importing package
                base = ".".join(package.split(".")[: len(package.split(".")) - node.level + 1])
                base = f"{base}.{node.module}" if node.module else base
            else:
                base = node.module or ""
            names.add(base)
            names.update(f"{base}.{alias.name}" for alias in node.names if alias.name != "*")
    return names


def violations(modules: dict[str, set[str]]) -> list[str]:
    """Every import in ``modules`` (module name → imported names) that breaks a rule, as readable lines."""
    found = []
    for module, names in sorted(modules.items()):
        for layer, forbidden, why in RULES:
            if _within(module, layer):
                found += [f"{module} imports {n} ({why})" for n in sorted(names)
                          if any(_within(n, f) for f in forbidden)]
        if not any(_within(module, m) for m in TOP_IMPORTERS):
            found += [f"{module} imports {n} (only the CLI and the steps import the CLI and the steps)"
                      for n in sorted(names) if any(_within(n, t) for t in TOP)]
    return found


def layer_of(module: str) -> int:
    """The index in :data:`LAYERS` of the most specific prefix that holds ``module``."""
    best = max(((len(p), i) for i, layer in enumerate(LAYERS) for p in layer if _within(module, p)), default=None)
    if best is None:
        raise KeyError(f"{module} is in no layer of LAYERS: add its package there")
    return best[1]


def upward_imports(modules: dict[str, set[str]]) -> set[tuple[str, str]]:
    """(importer, imported) for every import of a package module from a layer above the importer's; the
    imported name is cut to its module in :data:`LAYERS` terms (``amorgs.config.load_config`` → ``amorgs.config``)."""
    found = set()
    for module, names in modules.items():
        own = layer_of(module)
        for name in names:
            if not _within(name, "amorgs") or name == "amorgs" or layer_of(name) <= own:
                continue
            parts = name.split(".")
            target = next(".".join(parts[:k]) for k in range(2, len(parts) + 1)
                          if layer_of(".".join(parts[:k])) == layer_of(name))
            found.add((module, target))
    return found


def package_imports() -> dict[str, set[str]]:
    return {module_name(p): imported_modules(p.read_text(), module_name(p), p.name == "__init__.py")
            for p in sorted(PACKAGE.rglob("*.py"))}


def test_no_module_imports_upward():
    modules = package_imports()
    assert "amorgs.figures.ablation" in modules and "amorgs.analysis.structure_report" in modules
    assert violations(modules) == []


def test_every_module_imports_only_its_own_layer_and_those_below():
    """The declared order of :data:`LAYERS`, without exceptions (the last links, issue 24 §1 and §3, are cut)."""
    modules = package_imports()
    for module in modules:
        layer_of(module)  # every module has a layer
    found = upward_imports(modules)
    assert sorted(found) == [], "upward imports (importer, imported)"


def test_the_solvers_import_nothing_of_the_problems():
    """The problems build on the solvers' interfaces (options, record, IPOPT on a transcription), never the reverse."""
    modules = package_imports()
    assert "amorgs.solvers.multistart" in modules and "amorgs.problems.cr3bp" in modules
    found = sorted((m, n) for m, names in modules.items() if _within(m, "amorgs.solvers")
                   for n in names if _within(n, "amorgs.problems"))
    assert found == []


@pytest.mark.parametrize("module, source, imported", [
    ("amorgs.solvers.ipopt", "from amorgs.problems.base import SolveRecord\n", "amorgs.problems"),
    ("amorgs.solvers.multistart", "def f():\n    from amorgs.problems import get_problem\n", "amorgs.problems"),
    ("amorgs.problems.cr3bp", "from amorgs.data.filter import high_quality\n", "amorgs.data"),
    ("amorgs.data.io", "def f():\n    from amorgs.models.shipped import verify_models\n", "amorgs.models"),
    ("amorgs.alphas", "from .config import load_config\n", "amorgs.config"),
    ("amorgs.figures.dejong", "import amorgs.steps.dejong\n", "amorgs.steps"),
])
def test_the_order_check_catches_an_upward_import(module, source, imported):
    found = upward_imports({module: imported_modules(source, module)})
    assert [(m, n) for m, n in found if _within(n, imported)] != [], found


@pytest.mark.parametrize("module, source, expected", [
    ("amorgs.figures.ablation", "def f():\n    from amorgs.ablation.statistics import high_quality\n",
     "amorgs.ablation.statistics"),
    ("amorgs.figures.structure", "from amorgs.analysis import structure_report\n", "amorgs.analysis.structure_report"),
    ("amorgs.figures.prediction", "import torch.nn\n", "torch.nn"),
    ("amorgs.analysis.structure_report", "from amorgs.figures import structure as figs\n", "amorgs.figures"),
    ("amorgs.ablation.report", "def draw():\n    import matplotlib.pyplot as plt\n", "matplotlib.pyplot"),
    ("amorgs.data.io", "from ..figures.dejong import fig02_foxholes\n", "amorgs.figures.dejong"),
    ("amorgs.layout", "from amorgs.steps import targets\n", "amorgs.steps"),
])
def test_the_check_catches_an_upward_import(module, source, expected):
    """The checker itself: an upward import, top-level or inside a function, absolute or relative, is reported."""
    found = violations({module: imported_modules(source, module)})
    assert any(line.startswith(f"{module} imports {expected} ") for line in found), found


def test_allowed_imports_pass_the_check():
    figures = "from amorgs.ablation.arms import SAMPLER_NAMES\nfrom amorgs.alphas import rows_at\n"
    step = "from amorgs.figures.structure import structure_figures\n"
    modules = {"amorgs.figures.ablation": imported_modules(figures, "amorgs.figures.ablation"),
               "amorgs.steps.analyze": imported_modules(step, "amorgs.steps.analyze")}
    assert violations(modules) == []


@pytest.mark.parametrize("module", ["amorgs.figures.ablation", "amorgs.figures.structure",
                                    "amorgs.figures.prediction", "amorgs.figures.dejong"])
def test_importing_a_figures_module_does_not_load_torch(module):
    code = f"import sys, {module}; print('torch' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "False"
