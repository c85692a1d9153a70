"""Time-of-flight hyperplanes of the LT-CR3BP solution set (paper Sec. III.B.3, Eq. 32–33, Figs. 3–5).

Every solution has time coordinates τ = (τ_s, τ_i, τ_f) in TU (shooting, initial coast, final coast) and a
time of flight TOF = τ_s + τ_i + τ_f = ‖τ‖₁ (all three are ≥ 0).  Local optima bunch on a few values of TOF,
so in τ-space they lie on planes ``H_T = {τ : |‖τ‖₁ − T| ≤ δ}`` (Eq. 32), T a mode of the TOF density.

Modes: a Gaussian kernel density estimate of TOF with a *fixed* bandwidth (default 0.1 TU, below half the
paper's δ = 0.25 TU; rules of thumb scale with the overall spread instead — Scott's rule gives 2.6 TU on our
156 converged solutions at α = 1, which merges planes 1.4 TU apart and blurs those 6.5 TU apart),
evaluated on a grid of ``grid_step`` TU; its local maxima are peaks when their prominence is at least
``min_prominence`` × the highest density value, they are at least ``min_separation`` TU apart, and at least
``min_members`` solutions lie within δ of them.  The last rule is what keeps a lone
solution from being called a plane on small data sets; the rest only matter for large, noisy ones.

Frame (Eq. 33): the paper picks three random points of H_T and orthonormalises their span.  Every H_T has the
same exact normal (1, 1, 1)/√3, so we construct the frame deterministically instead:

    τ̂1 = (2, −1, −1)/√6   in-plane; shooting time against total coast time,
    τ̂2 = (0, 1, −1)/√2    in-plane; initial against final coast,
    τ̂3 = (1, 1, 1)/√3     normal,  τ̂1 × τ̂2 = τ̂3 (right-handed),

and τ' = R τ with R = [τ̂1; τ̂2; τ̂3].  The frame is the same for every plane, so in-plane coordinates are
comparable across planes and across runs, and τ3' = TOF/√3 stacks the planes along τ3' (Figs. 4–5).  A point
is transformed "in the frame of its nearest hyperplane"; with one rotation for all planes that choice only
matters for the signed normal offset ``(TOF − T)/√3`` (TU) that :func:`transform` returns alongside.

Spacing: :func:`hyperplane_spacing` is the median gap between consecutive modes; :func:`hyperplane_period`
is the most frequent difference between any two modes, which stays the plane spacing when several ladders of
planes interleave (as they do in our data).

Membership follows Eq. 32 literally: |TOF − T| ≤ δ (a difference of TOFs, i.e. a normal distance of δ/√3).
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
from scipy.signal import find_peaks

from amorgs.analysis.structure_params import ModeParams  # noqa: F401  (re-exported)

TIME_COLUMNS = ("tau_s", "tau_i", "tau_f")

#: Rows τ̂1, τ̂2, τ̂3 of the rotation R of Eq. 33 (see the module docstring).
FRAME = np.array(
    [
        [2.0, -1.0, -1.0],
        [0.0, 1.0, -1.0],
        [1.0, 1.0, 1.0],
    ]
) / np.array([[math.sqrt(6.0)], [math.sqrt(2.0)], [math.sqrt(3.0)]])


def time_coordinates(df: pd.DataFrame) -> np.ndarray:
    """τ = (τ_s, τ_i, τ_f) of every row, shape (n, 3), TU."""
    return df[list(TIME_COLUMNS)].to_numpy(dtype=float)


def time_of_flight(df: pd.DataFrame) -> np.ndarray:
    """TOF = τ_s + τ_i + τ_f of every row, shape (n,), TU."""
    return time_coordinates(df).sum(axis=1)


def tof_density(tof: np.ndarray, bandwidth: float, grid: np.ndarray) -> np.ndarray:
    """Gaussian KDE of ``tof`` (TU) with a fixed ``bandwidth`` (TU) on ``grid``; integrates to 1 (1/TU)."""
    tof = np.asarray(tof, float)
    z = (grid[:, None] - tof[None, :]) / bandwidth
    return np.exp(-0.5 * z**2).sum(axis=1) / (len(tof) * bandwidth * math.sqrt(2 * math.pi))


def detect_modes(tof: np.ndarray, params: ModeParams = ModeParams()) -> np.ndarray:
    """Modes T of the TOF density (TU, ascending) that qualify as hyperplanes; empty if none.

    See the module docstring for the rules; non-finite TOFs are ignored.
    """
    tof = np.asarray(tof, float)
    tof = tof[np.isfinite(tof)]
    if tof.size == 0:
        return np.empty(0)
    pad = 4 * params.bandwidth
    grid = np.arange(tof.min() - pad, tof.max() + pad + params.grid_step, params.grid_step)
    density = tof_density(tof, params.bandwidth, grid)
    # Pad with zeros so a peak at the grid edge is still a local maximum for find_peaks.
    padded = np.r_[0.0, density, 0.0]
    peaks, _ = find_peaks(
        padded,
        prominence=params.min_prominence * density.max(),
        distance=max(1, int(round(params.min_separation / params.grid_step))),
    )
    modes = grid[peaks - 1]
    members = np.abs(tof[None, :] - modes[:, None]) <= params.delta
    return np.sort(modes[members.sum(axis=1) >= params.min_members])


def nearest_mode(tof: np.ndarray, modes: np.ndarray) -> np.ndarray:
    """Index into ``modes`` of the mode nearest to each TOF; −1 where there are no modes or TOF is NaN."""
    tof = np.asarray(tof, float)
    modes = np.asarray(modes, float)
    if modes.size == 0:
        return np.full(tof.shape, -1, dtype=int)
    idx = np.abs(tof[:, None] - modes[None, :]).argmin(axis=1)
    return np.where(np.isfinite(tof), idx, -1)


def assign_hyperplane(tof: np.ndarray, modes: np.ndarray, delta: float) -> np.ndarray:
    """Eq. 32 membership: index of the nearest mode T with |TOF − T| ≤ δ, else −1."""
    tof = np.asarray(tof, float)
    idx = nearest_mode(tof, modes)
    ok = idx >= 0
    inside = np.zeros(tof.shape, dtype=bool)
    inside[ok] = np.abs(tof[ok] - np.asarray(modes, float)[idx[ok]]) <= delta
    return np.where(inside, idx, -1)


def hyperplane_spacing(modes: np.ndarray) -> float:
    """Median gap (TU) between consecutive modes; NaN with fewer than two modes."""
    modes = np.sort(np.asarray(modes, float))
    return float(np.median(np.diff(modes))) if modes.size >= 2 else math.nan


def hyperplane_period(modes: np.ndarray, delta: float) -> float:
    """Most frequent difference (TU) between any two modes: the period of a lattice of planes.

    The consecutive-gap median of :func:`hyperplane_spacing` is the plane spacing only when the modes form a
    single ladder; when two ladders of the same period interleave (on our α = 1 data: planes near 11.5, 18.2,
    24.5, 31.1 TU and near 13.1, 19.6, 26.0, 32.5 TU) it reports the offset between them instead.  Here every
    positive pairwise difference votes with a Gaussian of width ``delta``; the highest-voted difference is
    refined to the mean of the differences within ``delta`` of it.  NaN with fewer than two modes.
    """
    modes = np.sort(np.asarray(modes, float))
    if modes.size < 2:
        return math.nan
    diff = (modes[None, :] - modes[:, None])[np.triu_indices(modes.size, k=1)]
    grid = np.arange(diff.min(), diff.max() + delta / 10, delta / 10)
    peak = grid[tof_density(diff, delta, grid).argmax()]
    return float(diff[np.abs(diff - peak) <= delta].mean())


def transform(tau: np.ndarray, modes: np.ndarray) -> pd.DataFrame:
    """Eq. 33 for points ``tau`` (n, 3) in TU, each in the frame of its nearest hyperplane.

    Columns: ``tau1p``, ``tau2p`` (in-plane, TU), ``tau3p`` = TOF/√3 (TU, along the normal), ``plane`` (index
    of the nearest mode, −1 if ``modes`` is empty), ``plane_tof`` (that mode's T, NaN if none) and
    ``normal_offset`` = (TOF − T)/√3, the signed distance (TU) from the point to the plane ‖τ‖₁ = T.
    """
    tau = np.asarray(tau, float).reshape(-1, 3)
    rotated = tau @ FRAME.T
    tof = tau.sum(axis=1)
    plane = nearest_mode(tof, modes)
    plane_tof = np.full(tof.shape, np.nan)
    plane_tof[plane >= 0] = np.asarray(modes, float)[plane[plane >= 0]]
    return pd.DataFrame(
        {
            "tau1p": rotated[:, 0],
            "tau2p": rotated[:, 1],
            "tau3p": rotated[:, 2],
            "plane": plane,
            "plane_tof": plane_tof,
            "normal_offset": (tof - plane_tof) / math.sqrt(3.0),
        }
    )


def project_to_plane(transformed: pd.DataFrame) -> pd.DataFrame:
    """Orthogonal projection onto the nearest plane (Fig. 5c): τ3' := T/√3, in-plane coordinates unchanged."""
    out = transformed.copy()
    out["tau3p"] = out["plane_tof"] / math.sqrt(3.0)
    out["normal_offset"] = 0.0
    return out
