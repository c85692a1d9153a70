"""A generic, deterministic mini-batch training loop (Adam) for any model with a ``loss`` method.

The model is an ``nn.Module`` whose ``loss(x, cond) -> (scalar Tensor, dict[str, float])`` takes a batch of
data ``x`` (B, …) and its conditioning ``cond`` (B, …) — for the CVAEs the decision vector and α, for a
sequence model the sequence and its conditioning.  The loop knows nothing else about the model, and
nothing about experiment tracking: a caller logs through the ``on_epoch`` callback.

Progress: every ``progress_every`` epochs (by default about twenty times per run, always the first and the
last epoch) one line ``epoch 40/500  loss … | 0.05 s/epoch, 23 s left`` goes to standard output, flushed, so
a job's log shows how far training is while it runs.

Early stopping (issue 40): with ``validation_fraction`` > 0 a seeded share of the rows is held out and the
model's loss on it (no gradient, its noise drawn from a fixed seed, so the number moves only with the weights)
is reported as ``val_loss`` after every epoch; with ``patience`` > 0 training stops once ``val_loss`` has not
improved on its best by more than ``min_delta`` (relative) for ``patience`` epochs, and the weights of the best
epoch are restored.

Determinism: ``torch.manual_seed(seed)`` seeds the noise drawn inside ``loss`` (e.g. re-parameterisation),
and a separate seeded ``torch.Generator`` drives the shuffling.  Seed the model's initial weights yourself
(``torch.manual_seed`` before constructing it).  On one device and thread count, a rerun is bit-identical.
"""

from __future__ import annotations

import math
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import torch
from torch import Tensor, nn


@dataclass(frozen=True)
class TrainConfig:
    """Adam on mini-batches: ``epochs`` passes over the data, learning rate ``lr``, shuffling ``seed``.

    ``device`` None means CUDA when available, else CPU.  A trailing batch of one row is skipped (batch norm
    needs two), so every row is still visited in almost every epoch because the order is reshuffled.
    ``progress_every``: print a progress line every that many epochs (and at the first and last); ``None``
    picks ``ceil(epochs / 20)``, ``0`` prints nothing.  ``validation_fraction``, ``patience``, ``min_delta``:
    early stopping (module docstring; ``epochs`` is then the most that run).
    """

    epochs: int = 100
    batch_size: int = 256
    lr: float = 1e-3
    seed: int = 0
    device: str | None = None
    progress_every: int | None = None
    validation_fraction: float = 0.0
    patience: int = 0
    min_delta: float = 1e-3

    def progress_interval(self) -> int:
        """Epochs between two progress lines (0: none)."""
        if self.progress_every is None:
            return max(1, math.ceil(self.epochs / 20))
        return max(0, self.progress_every)

    def resolved_device(self) -> torch.device:
        if self.device is not None:
            return torch.device(self.device)
        return torch.device("cuda" if torch.cuda.is_available() else "cpu")


def train(
    model: nn.Module,
    x: np.ndarray | Tensor,
    cond: np.ndarray | Tensor,
    cfg: TrainConfig,
    on_epoch: Callable[[int, dict[str, float]], None] | None = None,
) -> dict[str, list[float]]:
    """Train ``model`` in place on ``x`` (n, …) with conditioning ``cond`` (n, …); return the history.

    The history maps every metric the model's ``loss`` reports (batch-size-weighted epoch means) plus
    ``epoch`` (1-based), ``epoch_s`` (wall seconds) and, with a validation share, ``val_loss`` to one list
    entry per epoch that ran (fewer than ``cfg.epochs`` when early stopping ended it; then the weights are those
    of ``best_epoch``, also in the history as a one-entry list).  ``on_epoch(epoch, metrics)`` is called after
    every epoch with the same numbers.  The model is left on the training device in train mode.
    """
    if cfg.epochs < 1 or cfg.batch_size < 2 or not cfg.lr > 0:
        raise ValueError(f"TrainConfig needs epochs ≥ 1, batch_size ≥ 2, lr > 0; got {cfg}")
    if not 0 <= cfg.validation_fraction < 1 or cfg.patience < 0 or (cfg.patience and not cfg.validation_fraction):
        raise ValueError(f"TrainConfig needs 0 ≤ validation_fraction < 1, patience ≥ 0, and a validation share "
                         f"for patience; got {cfg}")
    device = cfg.resolved_device()
    x = torch.as_tensor(x, dtype=torch.float32).to(device)
    cond = torch.as_tensor(cond, dtype=torch.float32).to(device)
    if cond.ndim == 1:
        cond = cond[:, None]
    n = x.shape[0]
    if cond.shape[0] != n or n < 2:
        raise ValueError(f"x has {n} rows and cond {cond.shape[0]}; need equal counts ≥ 2")
    x_val = cond_val = None
    if cfg.validation_fraction:
        n_val = int(round(cfg.validation_fraction * n))
        if not 2 <= n_val <= n - 2:
            raise ValueError(f"validation_fraction {cfg.validation_fraction} of {n} rows leaves no 2-row split")
        split = torch.randperm(n, generator=torch.Generator().manual_seed(cfg.seed + 1)).to(device)
        held, kept = split[:n_val], split[n_val:]
        x_val, cond_val, x, cond = x[held], cond[held], x[kept], cond[kept]
        n = x.shape[0]

    torch.manual_seed(cfg.seed)
    shuffle = torch.Generator().manual_seed(cfg.seed)
    model.to(device).train()
    opt = torch.optim.Adam(model.parameters(), lr=cfg.lr)
    history: dict[str, list[float]] = {}
    every = cfg.progress_interval()
    started = time.perf_counter()
    best, best_epoch, best_state = math.inf, 0, None
    for epoch in range(1, cfg.epochs + 1):
        t0 = time.perf_counter()
        order = torch.randperm(n, generator=shuffle).to(device)
        sums: dict[str, float] = {}
        seen = 0
        for start in range(0, n, cfg.batch_size):
            idx = order[start : start + cfg.batch_size]
            if idx.numel() < 2:
                continue
            loss, parts = model.loss(x[idx], cond[idx])
            opt.zero_grad(set_to_none=True)
            loss.backward()
            opt.step()
            b = idx.numel()
            seen += b
            for k, v in parts.items():
                sums[k] = sums.get(k, 0.0) + v * b
        metrics = {k: v / seen for k, v in sums.items()}
        if x_val is not None:
            metrics["val_loss"] = _validation_loss(model, x_val, cond_val, cfg)
        metrics["epoch_s"] = time.perf_counter() - t0
        for k, v in {"epoch": float(epoch), **metrics}.items():
            history.setdefault(k, []).append(v)
        if on_epoch is not None:
            on_epoch(epoch, metrics)
        stop = False
        if cfg.patience:
            if metrics["val_loss"] < best - cfg.min_delta * abs(best) or best_state is None:
                best, best_epoch = metrics["val_loss"], epoch
                best_state = {k: v.detach().clone() for k, v in model.state_dict().items()}
            stop = epoch - best_epoch >= cfg.patience
        if every and (epoch == 1 or epoch % every == 0 or epoch == cfg.epochs or stop):
            _print_progress(epoch, cfg.epochs, metrics, time.perf_counter() - started)
        if stop:
            print(f"early stop after epoch {epoch}: val_loss has not improved for {cfg.patience} epochs; "
                  f"weights of epoch {best_epoch} (val_loss {best:.5g}) restored", file=sys.stdout, flush=True)
            break
    if best_state is not None:
        model.load_state_dict(best_state)
        history["best_epoch"] = [float(best_epoch)]
    return history


def _validation_loss(model: nn.Module, x: Tensor, cond: Tensor, cfg: TrainConfig) -> float:
    """The model's loss on the held-out rows, batch-size-weighted, with no gradient and its noise drawn from a
    fixed seed (the training stream untouched); batch norm and dropout in eval mode."""
    model.eval()
    total, seen = 0.0, 0
    with torch.no_grad(), torch.random.fork_rng(devices=[] if x.device.type == "cpu" else [x.device]):
        torch.manual_seed(cfg.seed + 2)
        for start in range(0, x.shape[0], cfg.batch_size):
            xb, cb = x[start : start + cfg.batch_size], cond[start : start + cfg.batch_size]
            if xb.shape[0] < 2:
                continue
            loss, _ = model.loss(xb, cb)
            total += float(loss) * xb.shape[0]
            seen += xb.shape[0]
    model.train()
    return total / seen


def _print_progress(epoch: int, epochs: int, metrics: dict[str, float], elapsed: float) -> None:
    """One progress line on standard output, flushed at once (jobs write it to their log)."""
    losses = "  ".join(f"{k} {v:.5g}" for k, v in metrics.items() if k != "epoch_s")
    per_epoch = elapsed / epoch
    print(
        f"epoch {epoch}/{epochs}  {losses} | {per_epoch:.3g} s/epoch, {per_epoch * (epochs - epoch):.0f} s left",
        file=sys.stdout,
        flush=True,
    )
