"""Problem families: ``dejong`` (De Jong's 5th function) and ``cr3bp`` (low-thrust Earth–Moon transfer)."""

from __future__ import annotations

import importlib
import math

from amorgs.problems.base import LocalSolver, Problem, SolveRecord

PROBLEMS = ("dejong", "cr3bp")
#: The α each built-in family is defined for (inclusive): De Jong's rotation angle in rad, the CR3BP's
#: maximum thrust in N.  The config check rejects any α outside before the first job starts.
ALPHA_RANGES = {"dejong": (0.0, math.pi / 2), "cr3bp": (0.1, 1.0)}


def get_problem(name: str) -> Problem:
    """Return the problem family called ``name``; raises ``ValueError`` naming the valid choices.

    Besides the built-in names, ``"package.module:ClassName"`` loads a user-defined problem class that
    follows :class:`Problem` (instantiated without arguments) — the extension point for new families.
    """
    if ":" in name:
        module_name, _, class_name = name.partition(":")
        try:
            cls = getattr(importlib.import_module(module_name), class_name)
        except (ImportError, AttributeError) as exc:
            raise ValueError(f"cannot load problem {name!r}: {exc}") from None
        return cls()
    if name == "dejong":
        from amorgs.problems.dejong import DeJong5

        return DeJong5()
    if name == "cr3bp":
        from amorgs.problems.cr3bp.problem import LowThrustTransfer

        return LowThrustTransfer.from_resource()
    raise ValueError(f"unknown problem {name!r}; choose one of {PROBLEMS}")


__all__ = ["ALPHA_RANGES", "PROBLEMS", "LocalSolver", "Problem", "SolveRecord", "get_problem"]
