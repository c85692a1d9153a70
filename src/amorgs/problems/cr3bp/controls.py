"""Conversions between the stored control triples (θ, φ, ρ) and Cartesian throttle vectors u = ρ û.

Stored layout (see :mod:`amorgs.problems.cr3bp.transcription`): columns 4 … 4+3N of the decision vector
hold (θ_k, φ_k, ρ_k) per segment; û = (cos φ cos θ, cos φ sin θ, sin φ) in the rotating frame.
"""

from __future__ import annotations

import math

import numpy as np


def thrust_vectors(theta: np.ndarray, phi: np.ndarray, rho: np.ndarray) -> np.ndarray:
    """u = ρ (cos φ cos θ, cos φ sin θ, sin φ), stacked on a new last axis of length 3."""
    return np.stack([rho * np.cos(phi) * np.cos(theta), rho * np.cos(phi) * np.sin(theta), rho * np.sin(phi)], axis=-1)


def cartesian_controls(x: np.ndarray, n_segments: int = 20) -> np.ndarray:
    """Stored vectors (n, 4 + 3N) → Cartesian controls (n, N, 3)."""
    u = np.asarray(x, float)[:, 4 : 4 + 3 * n_segments].reshape(-1, n_segments, 3)
    return thrust_vectors(u[..., 0], u[..., 1], u[..., 2])


def spherical_controls(u: np.ndarray) -> np.ndarray:
    """Cartesian controls (n, N, 3) → stored (θ, φ, ρ) triples flattened to (n, 3N); θ ∈ [0, 2π), ρ ≤ 1."""
    u = np.asarray(u, float)
    rho = np.linalg.norm(u, axis=-1)
    theta = np.mod(np.arctan2(u[..., 1], u[..., 0]), 2 * math.pi)
    phi = np.arcsin(np.clip(u[..., 2] / np.where(rho > 0, rho, 1.0), -1.0, 1.0))
    return np.stack([theta, phi, np.minimum(rho, 1.0)], axis=-1).reshape(len(u), -1)


def rescale_throttle(x: np.ndarray, alpha_from: float, alpha_to: float) -> np.ndarray | None:
    """The stored vector ``x`` (layout above) of a solution at maximum thrust ``alpha_from`` (N), re-expressed at
    ``alpha_to`` (N) as the *same* trajectory: the thrust is T = α ρ and the mass flow −T ρ / c depend on α only
    through α ρ, so ρ' = ρ α_from / α_to flies it unchanged — times, directions and m_f are kept.  ``None`` where
    some ρ' would exceed 1 (the trajectory needs more thrust than ``alpha_to`` allows).  Hence the best final mass
    at α is non-decreasing in α."""
    y = np.array(x, float)
    rho = y[6::3] * (alpha_from / alpha_to)
    if rho.max(initial=0.0) > 1.0:
        return None
    y[6::3] = rho
    return y
