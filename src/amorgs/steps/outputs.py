"""Writing a step's outputs: figures as PNG (atomic, logged to MLflow), metrics MLflow can hold."""

from __future__ import annotations

import math
import os
from collections.abc import Mapping

from amorgs.data.io import atomic_path


def finite_metrics(metrics: Mapping) -> dict[str, float]:
    """The numeric, finite entries of a flat metrics mapping (what MLflow can hold)."""
    return {k: float(v) for k, v in metrics.items()
            if isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(float(v))}


def write_png(fig, path: str, run) -> None:
    """Save ``fig`` as PNG atomically, close it and log it as an artifact of ``run`` under ``figures/``."""
    from matplotlib import pyplot as plt

    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", dpi=150, bbox_inches="tight")
    plt.close(fig)
    run.log_artifact(path, "figures")


def by_name(paths: list[str] | str, names, suffix: str, what: str) -> dict[str, str]:
    """The declared outputs ``paths`` keyed by file name without ``suffix``; they must be exactly ``names``
    (what a step computed), else a ``ValueError`` naming both."""
    paths = [paths] if isinstance(paths, str) else list(paths)
    out = {os.path.basename(p).removesuffix(suffix): p for p in paths}
    if sorted(names) != sorted(out):
        raise ValueError(f"{what} {sorted(names)} differ from the declared outputs {sorted(out)}")
    return out


def write_figures(figures: Mapping, paths: list[str] | str, run) -> None:
    """Save each figure of ``figures`` (name → Figure) to the declared output ``<name>.png``."""
    paths = by_name(paths, figures, ".png", "figures")
    for name, fig in figures.items():
        write_png(fig, paths[name], run)


def use_agg() -> None:
    """Select matplotlib's non-interactive backend (jobs have no display)."""
    import matplotlib

    matplotlib.use("Agg")
