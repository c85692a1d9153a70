"""One identity for α, and one form of the metric keys that carry it.

Two α are *the same* when their three-decimal labels are equal (:func:`alpha_label`, ``0.150``): that is
how α appears in file names, Snakemake wildcards, table selections and MLflow keys, so a value read back from
a Parquet table, a path or a config always selects the same rows.  Every comparison of α in the package goes
through :func:`same_alpha` or :func:`rows_at`; no module compares α with ``==``, ``np.isclose`` or a
tolerance of its own.

Metric keys (MLflow and the metrics JSON files) are built by :func:`metric_key` only:
``name`` or ``name/alpha_0.150`` or ``name/alpha_0.150/amorgs``: the α part is always ``alpha_`` + label.
"""

from __future__ import annotations

import math
from collections.abc import Iterable

import numpy as np
import pandas as pd


def alpha_label(alpha: float | str) -> str:
    """The stable string form of α in paths, wildcards and keys: three fixed decimals (``0.150``)."""
    return f"{float(alpha):.3f}"


def same_alpha(a: float | str, b: float | str) -> bool:
    """Whether ``a`` and ``b`` are the same α (equal labels)."""
    return alpha_label(a) == alpha_label(b)


def alpha_mask(values: Iterable[float] | pd.Series | np.ndarray, alpha: float | str) -> np.ndarray:
    """Boolean mask of the entries of ``values`` that are the same α as ``alpha``."""
    label = alpha_label(alpha)
    return np.array([alpha_label(v) == label for v in np.asarray(values, dtype=float)], dtype=bool)


def rows_at(df: pd.DataFrame, alpha: float | str, column: str = "alpha") -> pd.DataFrame:
    """The rows of ``df`` at ``alpha`` (by label), index kept."""
    return df[alpha_mask(df[column], alpha)]


def rows_at_any(df: pd.DataFrame, alphas: Iterable[float | str], column: str = "alpha") -> pd.DataFrame:
    """The rows of ``df`` at any of ``alphas`` (by label), index kept."""
    labels = {alpha_label(a) for a in alphas}
    return df[df[column].map(alpha_label).isin(labels)]


def cap_per_alpha(df: pd.DataFrame, max_rows: int | None, seed: int) -> pd.DataFrame:
    """At most ``max_rows`` rows of every α — a seeded sample where an α holds more, every row where it holds
    fewer (stratified by α: a crowded α does not crowd out the others); order kept, index reset.  ``None``
    returns ``df`` whole."""
    if max_rows is None:
        return df
    rng = np.random.default_rng([seed, 40])
    keep = np.zeros(len(df), dtype=bool)
    for rows in df.groupby(df["alpha"].map(alpha_label), sort=True).indices.values():
        keep[rows if len(rows) <= max_rows else rng.choice(rows, size=max_rows, replace=False)] = True
    return df.loc[keep].reset_index(drop=True)


def alpha_value(alpha: float | str) -> float:
    """The α that ``alpha`` is, as a number: the float of its label (``0.1500001`` → ``0.15``)."""
    return float(alpha_label(alpha))


def distinct_alphas(values: Iterable[float | str] | pd.Series | np.ndarray) -> list[float]:
    """The distinct α among ``values``, one per label, as :func:`alpha_value`, ascending."""
    return sorted({alpha_value(v) for v in np.asarray(values, dtype=float).ravel()})


def metric_key(name: str, alpha: float | str | None = None, *qualifiers: object) -> str:
    """The metric key ``name[/alpha_<label>][/<qualifier>…]`` (MLflow allows ``/``, not ``=``)."""
    parts = [name]
    if alpha is not None:
        parts.append(f"alpha_{alpha_label(alpha)}")
    parts += [str(q) for q in qualifiers]
    return "/".join(parts)


def check_alpha(alpha: float, alpha_range: tuple[float, float], problem: str) -> float:
    """Return ``alpha`` as float or raise a ``ValueError`` that names the field and the range."""
    lo, hi = alpha_range
    try:
        a = float(alpha)
    except (TypeError, ValueError):
        raise ValueError(f"{problem}: alpha must be a number, got {alpha!r}") from None
    if not math.isfinite(a) or a < lo - 1e-12 or a > hi + 1e-12:
        raise ValueError(f"{problem}: alpha={alpha!r} is outside its range [{lo}, {hi}]")
    return a
