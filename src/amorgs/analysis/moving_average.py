"""Moving averages of the final mass over the time of flight (paper Sec. III.B.4, Figs. 7–8).

For a window width w (TU) the average at a time of flight t is the mean final mass m_f (kg) of every solution
with |TOF − t| ≤ w/2 (a centred box window over the *data*, not over a fixed number of neighbours, so the
curve has the same meaning where solutions are dense and where they are sparse).  It is evaluated at the
sorted TOFs of the data themselves, where it is never empty.
"""

from __future__ import annotations

import numpy as np
import pandas as pd


def moving_average(tof: np.ndarray, m_f: np.ndarray, window: float) -> pd.DataFrame:
    """Centred box moving average of ``m_f`` (kg) over ``tof`` (TU) with width ``window`` (TU).

    Returns columns ``tof`` (ascending, TU), ``m_f_ma`` (kg) and ``count`` (solutions inside the window);
    rows with a non-finite TOF or m_f are dropped first.
    """
    if not window > 0:
        raise ValueError(f"moving-average window must be > 0 TU, got {window}")
    tof = np.asarray(tof, float)
    m_f = np.asarray(m_f, float)
    ok = np.isfinite(tof) & np.isfinite(m_f)
    order = np.argsort(tof[ok], kind="stable")
    t, m = tof[ok][order], m_f[ok][order]
    lo = np.searchsorted(t, t - window / 2, side="left")
    hi = np.searchsorted(t, t + window / 2, side="right")
    csum = np.r_[0.0, np.cumsum(m)]
    count = hi - lo
    return pd.DataFrame({"tof": t, "m_f_ma": (csum[hi] - csum[lo]) / count, "count": count})


def moving_averages(tof: np.ndarray, m_f: np.ndarray, windows: tuple[float, ...]) -> pd.DataFrame:
    """:func:`moving_average` for each window, stacked long with a ``window`` column (TU)."""
    frames = [moving_average(tof, m_f, w).assign(window=float(w)) for w in windows]
    if not frames:
        return pd.DataFrame(columns=["tof", "m_f_ma", "count", "window"])
    return pd.concat(frames, ignore_index=True)
