"""The reuse-conditioned CVAE (issue 21 §3): a learned sampler built to beat reuse of known solutions.

Reuse (:class:`~amorgs.models.baselines.NearestAlphaSampler`) starts the solver from the high-quality
solutions of the nearest training α, unchanged.  This model keeps that retrieval and learns what to do with
what it retrieved: given a retrieved solution ``v_s`` of a training α ``a_s`` and the target α ``a_t``, it
samples a target solution ``v_t ~ p(v_t | v_s, a_s, a_t)`` — a *correction* when the neighbour's basin
continues to ``a_t``, a jump to another basin when the data say that neighbours like ``v_s`` sit next to a
different population at ``a_t``.

Layout: every vector is the vanilla CVAE's (:func:`~amorgs.models.baselines.vanilla_vectors`: τ_s, τ_i, τ_f
in TU, m_f in kg, then the Cartesian throttle vectors u_1 … u_20, dimensionless), 64 long.

Training pairs (:func:`matched_pairs`), from the high-quality rows at the training α only: for every ordered
pair of distinct training α (a_s, a_t) whose relative gap |a_t − a_s| / a_t is at most ``max_relative_gap``,
each solution at a_t is paired with its nearest solution at a_s, and each solution at a_s with its nearest at
a_t (Euclidean distance after dividing each column by its range over the training rows, ``source_scale``).
Both directions, so every retrieved row a sampler may draw and every target solution appear; and every row
with itself (no gap, no correction: the anchor that makes small gaps small corrections).  At most
``max_pairs`` pairs, a seeded subsample.

The model (:class:`ReuseCVAE`) is a :class:`~amorgs.models.cvae.VanillaCVAE` (standard-Gaussian prior) whose
data are the corrections ``Δ = v_t − v_s`` (its normalizer maps Δ to [0, 1] per column) and whose
conditioning, 66 wide, is ``(v_s / source_scale, a_s, a_t − a_s)``; ``source_scale`` is a buffer, saved with the
checkpoint.  Sampling: ``v = v_s + Δ`` with Δ drawn from the prior and decoded (:meth:`ReuseCVAE.propose`).

The sampler (:class:`ReuseCVAESampler`, arm ``reuse_cvae``) draws its retrieved rows exactly as reuse draws
its starts (the nearest training α's pool, without replacement until it is exhausted), then one torch seed
from ``rng`` for the CVAE noise.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pandas as pd
import torch
from torch import Tensor

from amorgs.models.baselines import NearestAlphaSampler, make_valid, stored_from_vanilla, vanilla_vectors
from amorgs.models.cvae import Normalizer, VanillaCVAE, VanillaCVAEConfig, torch_generator
from amorgs.models.names import CR3BP_PRESETS
from amorgs.problems import Problem
from amorgs.problems.cr3bp.transcription import N_SEGMENTS, variable_names

#: Width of a vector in the vanilla layout (τ_s, τ_i, τ_f, m_f, u_1 … u_20).
DIM = 4 + 3 * N_SEGMENTS
#: Conditioning width: the scaled retrieved vector, its α and the gap to the target α.
COND_DIM = DIM + 2
#: Latent size of the correction (small: the correction of one retrieved solution has few modes).
LATENT_DIM = 16
#: KL weight η_L of the correction CVAE (larger than the paper CVAEs' 1e-4: samples come from the prior).
KL_WEIGHT = 1e-3
#: Pairs (a_s, a_t) used for training: |a_t − a_s| / a_t at most this (the frontier's gaps reach 0.67).
MAX_RELATIVE_GAP = 1.0
#: At most this many training pairs (a seeded subsample beyond).
MAX_PAIRS = 20_000


def reuse_cvae_config(preset: str) -> VanillaCVAEConfig:
    """Layer widths: the vanilla CVAE's ``small`` or Table 5 (``paper``) widths, 66-wide conditioning,
    :data:`LATENT_DIM`-D latent, KL weight :data:`KL_WEIGHT`."""
    if preset not in CR3BP_PRESETS:
        raise ValueError(f"unknown model preset {preset!r}; choose one of {CR3BP_PRESETS}")
    base = (VanillaCVAEConfig.cr3bp_paper() if preset == "paper"
            else VanillaCVAEConfig.small(x_dim=DIM, latent_dim=LATENT_DIM))
    return replace(base, x_dim=DIM, latent_dim=LATENT_DIM, alpha_dim=COND_DIM, kl_weight=KL_WEIGHT)


def column_scale(v: np.ndarray) -> np.ndarray:
    """Each column's range over ``v`` (n, 64), floored at 1e-6: the unit of the matching distance."""
    v = np.asarray(v, dtype=np.float64)
    return np.maximum(v.max(axis=0) - v.min(axis=0), 1e-6)


def matched_pairs(
    by_alpha: dict[float, np.ndarray],
    scale: np.ndarray,
    rng: np.random.Generator,
    max_relative_gap: float = MAX_RELATIVE_GAP,
    max_pairs: int = MAX_PAIRS,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Training pairs from ``by_alpha`` (training α → vectors (m, 64) in the vanilla layout): arrays
    ``(v_s, a_s, v_t, a_t)`` of the retrieved vectors, their α, the target vectors and theirs (module
    docstring), plus every row paired with itself (a_s = a_t, Δ = 0: the correction vanishes with the gap).
    ``ValueError`` when no two training α are within ``max_relative_gap``."""
    from scipy.spatial import cKDTree

    alphas = sorted(by_alpha)
    trees = {a: cKDTree(by_alpha[a] / scale) for a in alphas}
    parts = []
    for a_s in alphas:
        for a_t in alphas:
            if abs(a_t - a_s) / a_t > max_relative_gap:
                continue
            src, tgt = by_alpha[a_s], by_alpha[a_t]
            if a_s == a_t:  # the anchor: no gap, no correction
                parts.append((src, np.full(len(src), a_s), src, np.full(len(src), a_t)))
                continue
            nearest_src = trees[a_s].query(tgt / scale)[1]  # each target → its nearest retrieved row
            nearest_tgt = trees[a_t].query(src / scale)[1]  # each retrieved row → its nearest target
            v_s = np.concatenate([src[nearest_src], src])
            v_t = np.concatenate([tgt, tgt[nearest_tgt]])
            parts.append((v_s, np.full(len(v_s), a_s), v_t, np.full(len(v_t), a_t)))
    if len(parts) == len(alphas):
        raise ValueError(f"no two training α {alphas} within a relative gap of {max_relative_gap}: "
                         "the reuse-conditioned CVAE needs at least one pair")
    v_s, a_s, v_t, a_t = (np.concatenate(p) for p in zip(*parts))
    if len(v_s) > max_pairs:
        keep = np.sort(rng.choice(len(v_s), size=max_pairs, replace=False))
        v_s, a_s, v_t, a_t = v_s[keep], a_s[keep], v_t[keep], a_t[keep]
    return v_s, a_s, v_t, a_t


class ReuseCVAE(VanillaCVAE):
    """p(v_t | v_s, a_s, a_t) as a vanilla CVAE of the correction Δ = v_t − v_s (module docstring).

    ``source_scale`` (64 values, the column ranges of the training vectors) divides the retrieved vector in
    the conditioning; it is a buffer, so :func:`amorgs.models.cvae.save` / ``load`` keep it.
    """

    def __init__(self, config: VanillaCVAEConfig, normalizer: Normalizer | None = None,
                 source_scale: np.ndarray | Tensor | None = None):
        super().__init__(config, normalizer)
        scale = torch.ones(config.x_dim) if source_scale is None else torch.as_tensor(source_scale, dtype=torch.float32)
        self.register_buffer("source_scale", scale.clone())

    def condition(self, v_s: np.ndarray, a_s: np.ndarray | float, a_t: np.ndarray | float) -> Tensor:
        """The conditioning rows (n, 66): ``v_s / source_scale``, ``a_s``, ``a_t − a_s`` (α scalars broadcast)."""
        v = torch.as_tensor(np.asarray(v_s, dtype=np.float64), dtype=torch.float32) / self.source_scale.cpu()
        n = v.shape[0]
        a = [torch.as_tensor(np.broadcast_to(np.asarray(x, dtype=np.float64), (n,)).copy(), dtype=torch.float32)
             for x in (a_s, a_t)]
        return torch.cat([v, a[0][:, None], (a[1] - a[0])[:, None]], dim=1)

    @torch.no_grad()
    def propose(self, v_s: np.ndarray, a_s: float, a_t: float, generator: torch.Generator | None = None) -> np.ndarray:
        """One sample v_t = v_s + Δ per retrieved row of ``v_s`` (n, 64), Δ ~ p(Δ | v_s, a_s, a_t); float64."""
        v_s = np.asarray(v_s, dtype=np.float64)
        delta = self.sample(self.condition(v_s, a_s, a_t), len(v_s), generator=generator)
        return v_s + delta.numpy().astype(np.float64)


def train_reuse_cvae(hq: pd.DataFrame, preset: str, train_cfg, on_epoch=None) -> ReuseCVAE:
    """The reuse-conditioned CVAE on the high-quality rows ``hq`` (columns ``alpha`` and the stored vector;
    training α only); pairs drawn with ``train_cfg.seed``; returned on the CPU, eval mode.  ``on_epoch``
    receives ``loss``, ``recon``, ``kl`` and ``epoch_s`` after every epoch."""
    from amorgs.models.training import train

    v = vanilla_vectors(hq[list(variable_names(N_SEGMENTS))].to_numpy(dtype=np.float64))
    alpha = hq["alpha"].to_numpy(dtype=np.float64)
    by_alpha = {float(a): v[alpha == a] for a in np.unique(alpha)}
    scale = column_scale(v)
    v_s, a_s, v_t, a_t = matched_pairs(by_alpha, scale, np.random.default_rng(train_cfg.seed))
    torch.manual_seed(train_cfg.seed)
    model = ReuseCVAE(reuse_cvae_config(preset), Normalizer.from_data(v_t - v_s), scale)
    train(model, v_t - v_s, model.condition(v_s, a_s, a_t), train_cfg, on_epoch)
    return model.cpu().eval()


class ReuseCVAESampler(NearestAlphaSampler):
    """Reuse's draw of retrieved rows (the nearest training α a_s), each replaced by one sample of the
    reuse-conditioned CVAE at the target α; mapped back to the stored layout and made valid."""

    name = "reuse_cvae"

    def __init__(self, problem: Problem, high_quality: pd.DataFrame, train_alphas, model: ReuseCVAE):
        super().__init__(problem, high_quality, train_alphas)
        self.model = model

    @classmethod
    def build(cls, problem: Problem, inputs) -> ReuseCVAESampler:
        return cls(problem, inputs.high_quality, inputs.train_alphas, inputs.models["reuse_cvae"])

    def sample(self, alpha: float, n: int, rng: np.random.Generator) -> np.ndarray:
        a_s = self.pool(alpha)[0]
        v_s = vanilla_vectors(self._draw(alpha, n, rng))
        v = self.model.propose(v_s, a_s, float(alpha), generator=torch_generator(rng))
        return make_valid(stored_from_vanilla(v), self.problem)


def load(path) -> ReuseCVAE:
    """A checkpoint written by :func:`amorgs.models.cvae.save` that must hold a :class:`ReuseCVAE`."""
    from amorgs.models import cvae

    model = cvae.load(path, {"ReuseCVAE": (ReuseCVAE, VanillaCVAEConfig)})
    if not isinstance(model, ReuseCVAE):
        raise ValueError(f"{path}: expected a ReuseCVAE, got {type(model).__name__}")
    return model
