"""What the structure analysis returns (paper Sec. III.B): plain data for the tables, metrics and figures.

:func:`amorgs.analysis.structure_report.analyze` computes a :class:`StructureResult`;
:func:`amorgs.figures.structure.structure_figures` draws Figs. 3–13 from it.  This module holds only the data
types (numpy, pandas and the standard library), so the figures can name them without loading the solver
stack that computes them.  Units: times TU, final mass m_f kg, positions DU in the Earth–Moon rotating frame.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from amorgs.alphas import rows_at
from amorgs.analysis.structure_params import StructureParams


@dataclass
class TransferPath:
    """One solution's trajectory for plotting: ``label``, ``tof`` (TU), ``m_f`` (kg), ``alpha`` (N),
    ``t`` (TU, shape (n,)) and ``positions`` (3, n) in DU, plus the solution's ``row`` index."""

    label: str
    tof: float
    m_f: float
    alpha: float
    t: np.ndarray
    positions: np.ndarray
    row: int


@dataclass
class StructureResult:
    """The structure analysis of one solution set.

    metrics: flat ``{key: float}`` (MLflow-ready; keys from :func:`amorgs.alphas.metric_key`).
    tables: ``modes``, ``funnels``, ``control_statistics``, ``moving_average``, ``diversity``,
        ``diverse_subset``, ``trajectories`` (:data:`amorgs.layout.ANALYSIS_TABLES`).
    params, beta_kg: the parameters and the β (kg) the analysis ran with.
    modes: α → TOF T (TU) of each detected hyperplane, for every α with converged solutions.
    converged: the converged solutions of every α with ``tof`` (TU), the transformed coordinates ``tau1p``,
        ``tau2p``, ``tau3p`` (TU, Eq. 33), the nearest ``plane`` and its ``plane_tof``, and ``on_plane`` (Eq. 32).
    shown_alphas: the α of Figs. 3–4.
    focus_alpha: α of Figs. 5–13 (None without converged solutions).
    focus_high_quality: the β-filtered solutions at the focus α, with the same columns as ``converged``.
    near_plane: those of them within δ of a hyperplane, projected onto it (Figs. 5c, 6, 9–12).
    fig06_planes: T (TU) of the hyperplanes of Fig. 6, ascending.
    micro_center: centre (TU) of the Fig. 8 zoom.
    funnel_planes: (rows of ``near_plane`` on the plane with their ``funnel`` letter, T in TU) of Figs. 11–12.
    paths_across, paths_within: the re-propagated transfers of Figs. 9 and 10.
    reference_arcs: ``halo`` and ``manifold`` positions (3, n), DU.
    boundary: the boundary-condition resource (μ, ξ₀, ξ_f, L1) the transfers were propagated with.
    """

    metrics: dict[str, float]
    tables: dict[str, pd.DataFrame]
    params: StructureParams
    beta_kg: float
    modes: dict[float, np.ndarray]
    converged: pd.DataFrame
    shown_alphas: list[float]
    focus_alpha: float | None
    focus_high_quality: pd.DataFrame
    near_plane: pd.DataFrame
    fig06_planes: list[float]
    micro_center: float
    funnel_planes: list[tuple[pd.DataFrame, float]]
    paths_across: list[TransferPath]
    paths_within: list[TransferPath]
    reference_arcs: dict[str, np.ndarray]
    boundary: dict

    @property
    def focus_converged(self) -> pd.DataFrame:
        """The converged solutions at the focus α (empty without one)."""
        return self.converged.iloc[:0] if self.focus_alpha is None else rows_at(self.converged, self.focus_alpha)
