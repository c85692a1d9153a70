"""Problem families: ``dejong`` (De Jong's 5th function) and ``cr3bp`` (low-thrust Earth–Moon transfer)."""

from __future__ import annotations

from amorgs.problems.base import LocalSolver, Problem, SolveRecord

PROBLEMS = ("dejong", "cr3bp")


def get_problem(name: str) -> Problem:
    """Return the problem family called ``name``; raises ``ValueError`` naming the valid choices."""
    if name == "dejong":
        from amorgs.problems.dejong import DeJong5

        return DeJong5()
    if name == "cr3bp":
        from amorgs.problems.cr3bp.problem import LowThrustTransfer

        return LowThrustTransfer.from_resource()
    raise ValueError(f"unknown problem {name!r}; choose one of {PROBLEMS}")


__all__ = ["PROBLEMS", "LocalSolver", "Problem", "SolveRecord", "get_problem"]
