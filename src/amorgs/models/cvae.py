"""Conditional variational autoencoders: Gaussian-mixture prior (AmorGS) and the vanilla baseline.

Source: Li et al., "Global Search of Optimal Spacecraft Trajectories using Amortization and Deep Generative
Models", Sec. IV.B–C (Eq. 34–37), Fig. 15a, Tables 3–5.

Data flow (``u`` is the data mapped to [0, 1] per column by the model's :class:`Normalizer`)::

    encoder   q_φ(z | x, α):  h = Encode([Embed_x(u), Embed_α(α)]),  μ = Encode_μ(h),  log σ² = Encode_Σ(h)
    prior     G_θ(z | α):     w = softmax(GMM_w(α)),  μ_k = GMM_μ(α),  log σ_k² = GMM_Σ(α)   (K components)
    decoder   p_ψ(x | z, α):  û = sigmoid(Decode_x([Embed_z(z), Embed_α(α)]))

Every hidden layer is Linear → BatchNorm1d → LeakyReLU; the output heads (μ, log σ², w, û) are plain Linear
followed by their own map (identity, softmax, sigmoid).  Batch statistics are used in training mode and the
running averages in eval mode, so :meth:`sample` switches the model to eval mode for its duration.

Units: :meth:`loss` takes data and :meth:`sample` returns samples in the *physical* units of the decision
vector; :meth:`encode`, :meth:`decode` work in normalised units ``u`` ∈ [0, 1]; ``z`` is dimensionless.
The normalizer's bounds are buffers, so one checkpoint (:func:`save` / :func:`load`) holds state dict,
config and normalizer together.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import NamedTuple

import numpy as np
import torch
from torch import Tensor, nn

CHECKPOINT_FORMAT = 1
_LOG_2PI = math.log(2.0 * math.pi)


# --------------------------------------------------------------------------------------------- configs
@dataclass(frozen=True, kw_only=True)
class VanillaCVAEConfig:
    """Layer widths of a CVAE with a standard-Gaussian prior (paper Table 5).

    Each tuple lists the widths *after* a layer's input; the input width follows from the other fields, so a
    config cannot be inconsistent.  :meth:`layer_table` gives the full lists in the paper's notation.
    ``kl_weight`` is η_L of Eq. 37; ``negative_slope`` that of the leaky ReLU.
    """

    x_dim: int
    latent_dim: int
    alpha_dim: int = 1
    embed_x: tuple[int, ...]
    embed_alpha: tuple[int, ...]
    encode: tuple[int, ...]
    encode_mu: tuple[int, ...]  # hidden widths; the head adds latent_dim
    encode_sigma: tuple[int, ...]  # hidden widths; the head adds latent_dim
    embed_z: tuple[int, ...]
    decode_x: tuple[int, ...]  # hidden widths; the head adds x_dim
    kl_weight: float = 1e-4
    negative_slope: float = 0.01

    def layer_table(self) -> dict[str, list[int]]:
        """Full layer-size lists (input first), named and laid out like the paper's tables."""
        return {
            "Embed_x": [self.x_dim, *self.embed_x],
            "Embed_alpha": [self.alpha_dim, *self.embed_alpha],
            "Encode": [self.embed_x[-1] + self.embed_alpha[-1], *self.encode],
            "Encode_mu": [self.encode[-1], *self.encode_mu, self.latent_dim],
            "Encode_Sigma": [self.encode[-1], *self.encode_sigma, self.latent_dim],
            "Embed_z": [self.latent_dim, *self.embed_z],
            "Decode_x": [self.embed_z[-1] + self.embed_alpha[-1], *self.decode_x, self.x_dim],
        }

    @classmethod
    def cr3bp_paper(cls) -> VanillaCVAEConfig:
        """Table 5: the whole 64-vector (τ_s, τ_i, τ_f, m_f, u_1 … u_20), 64-D latent."""
        return cls(
            x_dim=64,
            latent_dim=64,
            embed_x=(1024,) * 4,
            embed_alpha=(256,) * 4,
            encode=(512, 512, 512, 128),
            encode_mu=(128, 128),
            encode_sigma=(128, 128),
            embed_z=(1024,) * 4,
            decode_x=(512, 512, 512),
        )

    @classmethod
    def small(cls, x_dim: int, latent_dim: int) -> VanillaCVAEConfig:
        """Table 3's narrow encoder/decoder widths for any ``x_dim``/``latent_dim``: fast on a CPU."""
        return cls(
            x_dim=x_dim,
            latent_dim=latent_dim,
            embed_x=(32, 64, 64),
            embed_alpha=(32, 64, 64),
            encode=(64, 64),
            encode_mu=(32,),
            encode_sigma=(32,),
            embed_z=(32, 64, 64),
            decode_x=(64, 64),
        )


@dataclass(frozen=True, kw_only=True)
class CVAEConfig(VanillaCVAEConfig):
    """Layer widths of the CVAE with the conditional Gaussian-mixture prior (paper Tables 3–4).

    Adds ``n_components`` (K) and the hidden widths shared by the three prior MLPs GMM_w, GMM_μ, GMM_Σ,
    whose heads output K, K·latent_dim and K·latent_dim values.
    """

    n_components: int
    gmm_hidden: tuple[int, ...]

    def layer_table(self) -> dict[str, list[int]]:
        table = super().layer_table()
        k, d = self.n_components, self.latent_dim
        table["GMM_w"] = [self.alpha_dim, *self.gmm_hidden, k]
        table["GMM_mu"] = [self.alpha_dim, *self.gmm_hidden, k * d]
        table["GMM_Sigma"] = [self.alpha_dim, *self.gmm_hidden, k * d]
        return table

    @classmethod
    def dejong_paper(cls) -> CVAEConfig:
        """Table 3: x = (x1, x2), K = 2 components, 2-D latent."""
        return cls(
            x_dim=2,
            latent_dim=2,
            n_components=2,
            embed_x=(32, 64, 64),
            embed_alpha=(32, 64, 64),
            encode=(64, 64),
            encode_mu=(32,),
            encode_sigma=(32,),
            embed_z=(32, 64, 64),
            decode_x=(64, 64),
            gmm_hidden=(512, 512, 512),
        )

    @classmethod
    def cr3bp_paper(cls) -> CVAEConfig:
        """Table 4 (time & mass CVAE): x = (τ_s, τ_i, τ_f, m_f), K = 20 components, 4-D latent."""
        return cls(
            x_dim=4,
            latent_dim=4,
            n_components=20,
            embed_x=(1024,) * 4,
            embed_alpha=(256,) * 4,
            encode=(512, 512, 512, 128),
            encode_mu=(128, 128),
            encode_sigma=(128, 128),
            embed_z=(1024,) * 4,
            decode_x=(512, 512, 512),
            gmm_hidden=(512, 512, 512),
        )

    @classmethod
    def small(cls, x_dim: int, latent_dim: int, n_components: int) -> CVAEConfig:
        """Table 3's encoder/decoder widths with a (64, 64) prior instead of (512, 512, 512).

        The wide prior MLPs dominate the cost on a CPU (≈ 5× slower per step for De Jong); with this preset
        the De Jong CVAE trains to the paper's quality in ≈ 30 s on one CPU core.
        """
        return cls(
            x_dim=x_dim,
            latent_dim=latent_dim,
            n_components=n_components,
            embed_x=(32, 64, 64),
            embed_alpha=(32, 64, 64),
            encode=(64, 64),
            encode_mu=(32,),
            encode_sigma=(32,),
            embed_z=(32, 64, 64),
            decode_x=(64, 64),
            gmm_hidden=(64, 64),
        )


# ------------------------------------------------------------------------------------------ normalizer
class Normalizer(nn.Module):
    """Per-column affine map of the data to [0, 1]: ``u = (x − low) / (high − low)``.

    ``low``/``high`` are buffers (saved in the model's state dict).  A column with ``high == low`` is mapped
    with unit scale so that it round-trips exactly.
    """

    def __init__(self, low: Tensor | np.ndarray, high: Tensor | np.ndarray):
        super().__init__()
        low = torch.as_tensor(low, dtype=torch.float32).reshape(-1)
        high = torch.as_tensor(high, dtype=torch.float32).reshape(-1)
        if low.shape != high.shape or not bool(torch.all(high >= low)):
            raise ValueError("Normalizer: low and high must have equal shapes and high ≥ low")
        self.register_buffer("low", low)
        self.register_buffer("high", high)

    @classmethod
    def from_data(cls, x: Tensor | np.ndarray) -> Normalizer:
        """Column-wise min/max of training data ``x`` (n, d)."""
        x = torch.as_tensor(x, dtype=torch.float32)
        return cls(x.min(dim=0).values, x.max(dim=0).values)

    def _scale(self) -> Tensor:
        span = self.high - self.low
        return torch.where(span > 0, span, torch.ones_like(span))

    def transform(self, x: Tensor) -> Tensor:
        """Physical units → [0, 1]."""
        return (x - self.low) / self._scale()

    def inverse(self, u: Tensor) -> Tensor:
        """[0, 1] → physical units."""
        return self.low + u * self._scale()


# ------------------------------------------------------------------------------------------ networks
def mlp(sizes: list[int], negative_slope: float, head: bool) -> nn.Sequential:
    """Linear layers of widths ``sizes``; every hidden layer is Linear → BatchNorm1d → LeakyReLU.

    With ``head=True`` the last Linear is left bare (an output head); otherwise it too is a hidden layer.
    """
    layers: list[nn.Module] = []
    n = len(sizes) - 1
    for i in range(n):
        layers.append(nn.Linear(sizes[i], sizes[i + 1]))
        if not (head and i == n - 1):
            layers += [nn.BatchNorm1d(sizes[i + 1]), nn.LeakyReLU(negative_slope)]
    return nn.Sequential(*layers)


def gaussian_log_density(z: Tensor, mu: Tensor, logvar: Tensor) -> Tensor:
    """log N(z; μ, diag(exp logvar)) summed over the last axis."""
    return -0.5 * torch.sum(_LOG_2PI + logvar + (z - mu) ** 2 * torch.exp(-logvar), dim=-1)


class GMMPrior(NamedTuple):
    """Parameters of G_θ(z|α) for a batch: ``log_w`` (B, K), ``mu`` and ``logvar`` (B, K, latent)."""

    log_w: Tensor
    mu: Tensor
    logvar: Tensor

    @property
    def w(self) -> Tensor:
        return torch.exp(self.log_w)

    def log_prob(self, z: Tensor) -> Tensor:
        """log G_θ(z|α) for ``z`` (B, latent) by log-sum-exp over the components, shape (B,)."""
        comp = gaussian_log_density(z[:, None, :], self.mu, self.logvar)
        return torch.logsumexp(self.log_w + comp, dim=-1)


class _CVAE(nn.Module):
    """Encoder, decoder and sampling shared by both CVAEs; subclasses define the prior and the KL."""

    config: VanillaCVAEConfig

    def __init__(self, config: VanillaCVAEConfig, normalizer: Normalizer | None = None):
        super().__init__()
        c, t, s = config, config.layer_table(), config.negative_slope
        self.config = config
        self.normalizer = normalizer or Normalizer(torch.zeros(c.x_dim), torch.ones(c.x_dim))
        if self.normalizer.low.numel() != c.x_dim:
            raise ValueError(f"normalizer has {self.normalizer.low.numel()} columns, config x_dim={c.x_dim}")
        self.embed_x = mlp(t["Embed_x"], s, head=False)
        self.embed_alpha = mlp(t["Embed_alpha"], s, head=False)
        self.encoder = mlp(t["Encode"], s, head=False)
        self.encode_mu = mlp(t["Encode_mu"], s, head=True)
        self.encode_sigma = mlp(t["Encode_Sigma"], s, head=True)
        self.embed_z = mlp(t["Embed_z"], s, head=False)
        self.decode_x = mlp(t["Decode_x"], s, head=True)

    # -- the maths ---------------------------------------------------------------------------------
    def encode(self, u: Tensor, alpha: Tensor) -> tuple[Tensor, Tensor]:
        """q_φ(z|x,α): normalised data ``u`` (B, x_dim), ``alpha`` (B, alpha_dim) → (μ, log σ²), each (B, latent)."""
        h = self.encoder(torch.cat([self.embed_x(u), self.embed_alpha(alpha)], dim=-1))
        return self.encode_mu(h), self.encode_sigma(h)

    @staticmethod
    def reparameterize(mu: Tensor, logvar: Tensor) -> Tensor:
        """z = μ + σ ⊙ ξ_N with ξ_N ~ N(0, I) from the global torch RNG (training)."""
        return mu + torch.exp(0.5 * logvar) * torch.randn_like(mu)

    def decode(self, z: Tensor, alpha: Tensor) -> Tensor:
        """p_ψ(x|z,α): latent ``z`` (B, latent), ``alpha`` (B, alpha_dim) → normalised û ∈ (0, 1), (B, x_dim)."""
        h = torch.cat([self.embed_z(z), self.embed_alpha(alpha)], dim=-1)
        return torch.sigmoid(self.decode_x(h))

    def kl(self, z: Tensor, mu: Tensor, logvar: Tensor, alpha: Tensor) -> Tensor:
        """KL(q_φ(z|x,α) ‖ prior) per sample, shape (B,); ``z`` is the reparameterised sample."""
        raise NotImplementedError

    def loss(self, x: Tensor, alpha: Tensor) -> tuple[Tensor, dict[str, float]]:
        """Negative of Eq. 37 for a batch in physical units: MSE(û, u) + η_L · mean KL.

        The reconstruction is the mean squared error over batch and columns in normalised units (the Gaussian
        likelihood up to constants), from a single reparameterised sample.  Returns the scalar loss and its
        parts as floats (``loss``, ``recon``, ``kl``).
        """
        alpha = self._alpha_batch(alpha, x.shape[0], x.device)
        u = self.normalizer.transform(x)
        mu, logvar = self.encode(u, alpha)
        z = self.reparameterize(mu, logvar)
        recon = torch.mean((self.decode(z, alpha) - u) ** 2)
        kl = torch.mean(self.kl(z, mu, logvar, alpha))
        total = recon + self.config.kl_weight * kl
        return total, {"loss": float(total.detach()), "recon": float(recon.detach()), "kl": float(kl.detach())}

    # -- sampling ----------------------------------------------------------------------------------
    def sample_latent(self, alpha: Tensor, generator: torch.Generator | None) -> Tensor:
        """Draw one z per row of ``alpha`` (B, alpha_dim) from the prior; noise drawn on the CPU."""
        raise NotImplementedError

    @torch.no_grad()
    def sample(self, alpha: float | np.ndarray | Tensor, n: int, generator: torch.Generator | None = None) -> Tensor:
        """``n`` samples x ~ p(x|α) in physical units, shape (n, x_dim); no encoder involved.

        ``alpha`` is a scalar (alpha_dim = 1) or a vector of length alpha_dim, shared by all samples.  The
        model is in eval mode while sampling (BatchNorm running averages) and returns to its previous mode.
        Noise comes from ``generator`` (a CPU ``torch.Generator``), so a seeded generator gives identical
        samples on any device.
        """
        device = next(self.parameters()).device
        a = self._alpha_batch(alpha, int(n), device)
        was_training = self.training
        self.eval()
        try:
            z = self.sample_latent(a, generator).to(device)
            return self.normalizer.inverse(self.decode(z, a)).cpu()
        finally:
            self.train(was_training)

    def _alpha_batch(self, alpha: float | np.ndarray | Tensor, n: int, device: torch.device) -> Tensor:
        """``alpha`` as a (n, alpha_dim) float tensor: a scalar/vector is repeated, a (n, ·) batch kept."""
        a = torch.as_tensor(alpha, dtype=torch.float32, device=device)
        d = self.config.alpha_dim
        if a.ndim == 2 and a.shape == (n, d):
            return a
        if a.ndim == 1 and d == 1 and a.shape[0] == n:
            return a[:, None]
        if a.numel() == d:
            return a.reshape(1, d).expand(n, d)
        raise ValueError(f"alpha must be a scalar/vector of length {d} or a ({n}, {d}) batch, got {tuple(a.shape)}")


class GMMPriorCVAE(_CVAE):
    """CVAE with the conditional Gaussian-mixture prior G_θ(z|α) of Eq. 34 (the AmorGS generator).

    KL term: the paper picks one mixture component with a generalised-Bernoulli draw to get an analytic
    Gaussian–Gaussian KL.  That pick gives no gradient to the mixture weights, so we use the standard
    alternative instead: the single-sample Monte-Carlo estimate ``log q_φ(z|x,α) − log G_θ(z|α)`` at the
    reparameterised ``z`` (unbiased, log-sum-exp over the K components), which trains weights, means and
    variances jointly.  Sampling does use the generalised-Bernoulli pick: i ~ Cat(w(α)), z ~ N(μ_i, σ_i²).
    """

    config: CVAEConfig

    def __init__(self, config: CVAEConfig, normalizer: Normalizer | None = None):
        super().__init__(config, normalizer)
        t, s = config.layer_table(), config.negative_slope
        self.gmm_w = mlp(t["GMM_w"], s, head=True)
        self.gmm_mu = mlp(t["GMM_mu"], s, head=True)
        self.gmm_sigma = mlp(t["GMM_Sigma"], s, head=True)

    def prior(self, alpha: Tensor) -> GMMPrior:
        """G_θ(z|α) for ``alpha`` (B, alpha_dim): log-weights (softmax), means and log-variances."""
        k, d = self.config.n_components, self.config.latent_dim
        b = alpha.shape[0]
        return GMMPrior(
            log_w=torch.log_softmax(self.gmm_w(alpha), dim=-1),
            mu=self.gmm_mu(alpha).reshape(b, k, d),
            logvar=self.gmm_sigma(alpha).reshape(b, k, d),
        )

    def kl(self, z: Tensor, mu: Tensor, logvar: Tensor, alpha: Tensor) -> Tensor:
        """Single-sample estimate log q_φ(z|x,α) − log G_θ(z|α), shape (B,)."""
        return gaussian_log_density(z, mu, logvar) - self.prior(alpha).log_prob(z)

    def sample_latent(self, alpha: Tensor, generator: torch.Generator | None) -> Tensor:
        p = self.prior(alpha)
        idx = torch.multinomial(p.w.cpu(), 1, generator=generator)[:, 0]
        rows = torch.arange(alpha.shape[0])
        mu, logvar = p.mu.cpu()[rows, idx], p.logvar.cpu()[rows, idx]
        return mu + torch.exp(0.5 * logvar) * torch.randn(mu.shape, generator=generator)


class VanillaCVAE(_CVAE):
    """CVAE with a standard-Gaussian prior N(0, I) on z, independent of α (paper Table 5 baseline).

    α enters through the encoder and the decoder only; the KL term is the analytic Gaussian–N(0, I) one.
    """

    def prior(self, alpha: Tensor) -> tuple[Tensor, Tensor]:
        """N(0, I): means and log-variances (zeros), each (B, latent)."""
        zeros = torch.zeros(alpha.shape[0], self.config.latent_dim, device=alpha.device)
        return zeros, zeros.clone()

    def kl(self, z: Tensor, mu: Tensor, logvar: Tensor, alpha: Tensor) -> Tensor:
        """Analytic KL(N(μ, σ²) ‖ N(0, I)), shape (B,)."""
        return -0.5 * torch.sum(1.0 + logvar - mu**2 - torch.exp(logvar), dim=-1)

    def sample_latent(self, alpha: Tensor, generator: torch.Generator | None) -> Tensor:
        return torch.randn(alpha.shape[0], self.config.latent_dim, generator=generator)


# ------------------------------------------------------------------------------------------ checkpoints
_MODELS: dict[str, tuple[type[_CVAE], type[VanillaCVAEConfig]]] = {
    "GMMPriorCVAE": (GMMPriorCVAE, CVAEConfig),
    "VanillaCVAE": (VanillaCVAE, VanillaCVAEConfig),
}


def save(model: GMMPriorCVAE | VanillaCVAE, path: str | Path) -> None:
    """One checkpoint file: model class, config, state dict (normalizer bounds included)."""
    state = {k: v.detach().cpu() for k, v in model.state_dict().items()}
    torch.save(
        {
            "format": CHECKPOINT_FORMAT,
            "model": type(model).__name__,
            "config": asdict(model.config),
            "state_dict": state,
        },
        Path(path),
    )


def load(path: str | Path, models: dict[str, tuple[type[_CVAE], type[VanillaCVAEConfig]]] | None = None):
    """Rebuild a model written by :func:`save`, on the CPU and in eval mode.  ``models`` maps the class names
    a checkpoint may hold to (class, config class); default: the two paper CVAEs."""
    models = _MODELS if models is None else models
    ckpt = torch.load(Path(path), map_location="cpu", weights_only=True)
    if ckpt.get("format") != CHECKPOINT_FORMAT:
        raise ValueError(f"{path}: not an amorgs CVAE checkpoint (format {ckpt.get('format')!r})")
    if ckpt.get("model") not in models:
        raise ValueError(f"{path}: holds a {ckpt.get('model')!r}, expected one of {sorted(models)}")
    cls, cfg_cls = models[ckpt["model"]]
    cfg = cfg_cls(**{k: tuple(v) if isinstance(v, list) else v for k, v in ckpt["config"].items()})
    model = cls(cfg)
    model.load_state_dict(ckpt["state_dict"])
    return model.eval()


def _load_as(path: str | Path, cls: type[_CVAE]) -> _CVAE:
    model = load(path)
    if not isinstance(model, cls):
        raise ValueError(f"{path}: expected a {cls.__name__}, got {type(model).__name__}")
    return model


def load_gmm_prior_cvae(path: str | Path) -> GMMPriorCVAE:
    """A checkpoint of :func:`save` that must hold a :class:`GMMPriorCVAE`; ``ValueError`` naming the file."""
    return _load_as(path, GMMPriorCVAE)


def load_vanilla_cvae(path: str | Path) -> VanillaCVAE:
    """A checkpoint of :func:`save` that must hold a :class:`VanillaCVAE`; ``ValueError`` naming the file."""
    return _load_as(path, VanillaCVAE)


def torch_generator(rng: np.random.Generator) -> torch.Generator:
    """A CPU torch generator seeded by one draw from ``rng`` (so a seeded ``rng`` fixes the CVAE noise)."""
    return torch.Generator().manual_seed(int(rng.integers(0, 2**63 - 1)))
