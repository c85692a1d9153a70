"""The low-thrust Earth–Moon transfer (LT-CR3BP) family: the contract (:data:`FAMILY`) here, the rest in the
modules of this package (:mod:`.problem` the problem, :mod:`.transcription` the NLP, :mod:`.dynamics`,
:mod:`.boundary`, :mod:`.propagation`, :mod:`.frames`, :mod:`.controls`, :mod:`.constants`).

The contract: α is the maximum thrust, in [0.1, 1.0] N; the local solver is IPOPT with
:class:`~amorgs.solvers.options.IpoptOptions`; "high quality" is converged with final mass m_f ≥ β, the paper's
β = 415 kg (:class:`Cr3bpFilter`).  This module loads neither CasADi nor the boundary conditions: the problem
is built by :func:`build` when it is asked for.
"""

from __future__ import annotations

from typing import Annotated

import pandas as pd
from pydantic import ConfigDict, Field, model_validator
from pydantic.dataclasses import dataclass

from amorgs.problems.base import Family, Problem, QualityFilter
from amorgs.solvers.options import IpoptOptions


#: β (kg): the paper's threshold of a high-quality solution's final fuel mass m_f — defined here only.
BETA_KG = 415.0


@dataclass(frozen=True, config=ConfigDict(extra="forbid"))
class Cr3bpFilter(QualityFilter):
    """High quality (β): converged with final mass m_f ≥ ``min_final_mass_kg`` (kg)."""

    min_final_mass_kg: Annotated[float, Field(description=(
        "β (kg): keep converged solves whose final mass m_f is at least this (the paper's β: 415 kg)"))] = BETA_KG

    @model_validator(mode="after")
    def _reachable(self) -> Cr3bpFilter:
        """β within [0, the initial fuel]: above it no transfer could count (m_f ≤ the fuel at the start)."""
        from amorgs.problems.cr3bp.boundary import load_boundary_conditions

        fuel = float(load_boundary_conditions()["initial_state"][6])
        if not 0.0 <= self.min_final_mass_kg <= fuel:
            raise ValueError(f"β = {self.min_final_mass_kg:g} kg lies outside [0, {fuel:.1f}] kg: a transfer keeps at "
                             "most its initial fuel, so no solution could count")
        return self

    def passes(self, table: pd.DataFrame) -> pd.Series:
        return table["m_f"] >= self.min_final_mass_kg


def build() -> Problem:
    """The problem with the committed boundary conditions (``resources/boundary_conditions.json``)."""
    from amorgs.problems.cr3bp.problem import LowThrustTransfer

    return LowThrustTransfer.from_resource()


FAMILY = Family(name="cr3bp", alpha_range=(0.1, 1.0), alpha_unit="N", options_type=IpoptOptions,
                quality_type=Cr3bpFilter, build=build)
