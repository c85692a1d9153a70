"""Problem families: ``dejong`` (De Jong's 5th function) and ``cr3bp`` (low-thrust Earth–Moon transfer).

Each family owns its contract (:class:`~amorgs.problems.base.Family`: α range, solver-options type, quality
filter and their defaults, how to build the problem), declared as ``FAMILY`` in its module; :data:`FAMILIES`
registers them.  The config, the workflow's wildcards and the contract test
(``tests/unit/test_problem_contract.py``) all read this one table.
"""

from __future__ import annotations

import importlib

from amorgs.problems import cr3bp, dejong
from amorgs.problems.base import Family, LocalSolver, Problem, QualityFilter, SolveRecord

#: Every registered family by name, in the workflow's order.
FAMILIES: dict[str, Family] = {f.name: f for f in (dejong.FAMILY, cr3bp.FAMILY)}
PROBLEMS = tuple(FAMILIES)


def get_family(name: str) -> Family:
    """The registered family called ``name``; raises ``ValueError`` naming the valid choices."""
    if name not in FAMILIES:
        raise ValueError(f"unknown problem {name!r}; choose one of {PROBLEMS}")
    return FAMILIES[name]


def get_problem(name: str) -> Problem:
    """Build the problem of the family called ``name``; raises ``ValueError`` naming the valid choices.

    Besides the registered names, ``"package.module:ClassName"`` loads a stand-in problem class that follows
    :class:`Problem` (instantiated without arguments), for the multistart pool alone: the tests' crashing
    problem uses it.  A family the workflow runs is registered in :data:`FAMILIES`.
    """
    if ":" in name:
        module_name, _, class_name = name.partition(":")
        try:
            cls = getattr(importlib.import_module(module_name), class_name)
        except (ImportError, AttributeError) as exc:
            raise ValueError(f"cannot load problem {name!r}: {exc}") from None
        return cls()
    return get_family(name).build()


__all__ = ["FAMILIES", "PROBLEMS", "Family", "LocalSolver", "Problem", "QualityFilter", "SolveRecord",
           "get_family", "get_problem"]
