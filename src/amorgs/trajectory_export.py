"""Export designed CR3BP trajectories: dense state and control histories (CSV), CCSDS OEM files, a 3-D plot.

Per trajectory (one stored 64-vector at one α), :func:`dense_history` re-propagates the solution with
:func:`amorgs.problems.cr3bp.propagation.propagate` (scipy DOP853, rtol 1e-10, arc by arc: the initial coast,
the 20 thrust segments, the final coast), samples every arc at least every :data:`MAX_STEP_TU` (≈ 2.1 h) and
at every integrator step, and tabulates, per sample:

===================================  ==========================================================================
column                               meaning
===================================  ==========================================================================
``t_tu``, ``t_s``, ``epoch_tdb``     time after departure (TU, s) and the epoch (ISO, TDB; frames.EPOCH_ISO + t)
``arc``, ``segment``                 ``coast_initial``, ``thrust_01`` … ``thrust_20``, ``coast_final``; 0 or k
``x_du`` … ``vz_vu``                 rotating frame, barycentric, nondimensional (DU, VU)
``x_rot_km`` … ``vz_rot_km_s``       the same in km, km/s
``x_emi_km`` … ``vz_emi_km_s``       Earth-centred inertial frame (frames.INERTIAL_FRAME_NAME), km, km/s
``fuel_kg``, ``mass_kg``             fuel mass and wet mass (dry 300 kg + fuel)
``throttle``, ``thrust_n``           ρ ∈ [0, 1] and the thrust ρ α in N (0 on the coasts)
``ux_rot`` … ``uz_rot``              thrust unit vector û in rotating axes (NaN on the coasts)
``ux_emi`` … ``uz_emi``              the same direction in inertial axes
===================================  ==========================================================================

Arc boundaries appear twice (end of one arc, start of the next, each with its own control); at the match
point the two samples differ by the re-propagated match defect (≤ 1e-5 DU ≈ 3.8 km for a verified solution).
The OEM (:func:`write_oem`, KVN, CCSDS 502.0-B-3 version 2.0, written with the ``oem`` package) holds the
inertial position and velocity (km, km/s) at every distinct epoch — the first sample of each duplicated
epoch — with ``CENTER_NAME = EARTH``, ``REF_FRAME = EMI_CR3BP`` (not a SANA-registered frame: see
:mod:`amorgs.problems.cr3bp.frames`), ``TIME_SYSTEM = TDB`` and ``REF_FRAME_EPOCH`` = the epoch, ``INTERPOLATION = LAGRANGE`` of degree 5 (measured: ≲ 0.01 km between
samples, ≈ 0.1 km where an interpolation window spans a thrust switch or the match point).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pandas as pd

from amorgs.problems.cr3bp import constants as K
from amorgs.problems.cr3bp import frames

ROT_ND = ["x_du", "y_du", "z_du", "vx_vu", "vy_vu", "vz_vu"]
ROT_KM = ["x_rot_km", "y_rot_km", "z_rot_km", "vx_rot_km_s", "vy_rot_km_s", "vz_rot_km_s"]
EMI_KM = ["x_emi_km", "y_emi_km", "z_emi_km", "vx_emi_km_s", "vy_emi_km_s", "vz_emi_km_s"]
OEM_VERSION = "2.0"
ORIGINATOR = "AMORGS"


#: Largest time step of the exported histories, TU (≈ 2.1 h); steps are shorter where the adaptive DOP853
#: integrator takes shorter steps (close Earth passes).
MAX_STEP_TU = 0.02
PROPAGATE_TOL = 1e-10  # rtol = atol of :func:`amorgs.problems.cr3bp.propagation.propagate`'s dense arcs


def _label_samples(t: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Segment index (1…N thrust, 0 coast) of every sample of a propagated history: the control on the interval
    to the sample's right, except for the first of two samples with the same time (the end of an arc), whose
    control is on the interval to its left."""
    n_seg = (len(x) - 4) // 3
    tau_s, tau_i = float(x[0]), float(x[1])
    right = np.r_[t[1:], t[-1]]
    left = np.r_[t[0], t[:-1]]
    t_mid = np.where(right > t, 0.5 * (t + right), 0.5 * (left + t))
    dt = tau_s / n_seg
    if tau_s <= 0:
        return np.zeros(t.shape, int)
    k = np.floor((t_mid - tau_i) / dt).astype(int) + 1
    inside = (t_mid >= tau_i) & (t_mid < tau_i + tau_s)
    return np.where(inside, np.clip(k, 1, n_seg), 0)


def _arcs(t: np.ndarray, seg: np.ndarray, x: np.ndarray) -> list[tuple[int, int, int, bool]]:
    """(first row, last row + 1, segment, backward) of each arc of a propagated history; ``backward``: the arc
    was integrated backward in time from its last sample (the backward half of the transcription)."""
    n_seg = (len(x) - 4) // 3
    match_time = float(x[1] + x[0] / 2)
    bounds = [0, *(np.flatnonzero((seg[1:] != seg[:-1]) | ((t[1:] == t[:-1]) & (seg[1:] == seg[:-1]))) + 1), len(t)]
    out = []
    for a, b in zip(bounds[:-1], bounds[1:]):
        k = int(seg[a])
        backward = k > n_seg // 2 or (k == 0 and t[a] >= match_time)
        out.append((a, b, k, backward))
    return out


def dense_history(x: np.ndarray, alpha: float, initial_state, terminal_state,
                  max_step_tu: float = MAX_STEP_TU) -> pd.DataFrame:
    """Dense state and control history of one stored solution (module docstring); rows in time order.

    The samples of :func:`~amorgs.problems.cr3bp.propagation.propagate` (40 per arc) are kept exactly; each arc
    is re-integrated from the state propagate started it from (the forward half from its first sample, the
    backward half backward from its last), with propagate's integrator and tolerances, and sampled also at
    every integrator step and at least every ``max_step_tu``.
    """
    from scipy.integrate import solve_ivp

    from amorgs.problems.cr3bp.dynamics import constant_thrust_rhs
    from amorgs.problems.cr3bp.propagation import propagate

    x = np.asarray(x, float)
    n_seg = (len(x) - 4) // 3
    controls = x[4:].reshape(n_seg, 3)
    t_nd = K.thrust_nd(alpha)
    mdot_per_thrust = K.mass_flow_kg_per_tu(alpha) / t_nd
    traj = propagate(x, alpha, initial_state, terminal_state)
    t_nodes, s_nodes = traj.t, traj.states.T
    seg_nodes = _label_samples(t_nodes, x)

    ts, ss, segs = [], [], []
    for a, b, k, backward in _arcs(t_nodes, seg_nodes, x):
        t0, t1 = float(t_nodes[a]), float(t_nodes[b - 1])
        duration = t1 - t0
        if duration <= 0:
            ts.append(t_nodes[a:a + 1]); ss.append(s_nodes[a:a + 1]); segs.append(seg_nodes[a:a + 1])
            continue
        if k > 0:
            th, ph, rho = controls[k - 1]
            thrust = t_nd * rho * np.array([np.cos(ph) * np.cos(th), np.cos(ph) * np.sin(th), np.sin(ph)])
        else:
            thrust = np.zeros(3)
        start = s_nodes[b - 1] if backward else s_nodes[a]
        span = (0.0, -duration) if backward else (0.0, duration)
        sol = solve_ivp(constant_thrust_rhs(thrust, mdot_per_thrust), span, start, method="DOP853",
                        rtol=PROPAGATE_TOL, atol=PROPAGATE_TOL, dense_output=True)
        if not sol.success:
            raise FloatingPointError(sol.message)
        steps = (t1 + sol.t) if backward else (t0 + sol.t)
        uniform = np.linspace(t0, t1, int(np.ceil(duration / max_step_tu)) + 1)
        nodes = t_nodes[a:b]
        extra = np.concatenate([steps, uniform])
        pos = np.clip(np.searchsorted(nodes, extra), 1, nodes.size - 1)
        gap = np.minimum(np.abs(extra - nodes[pos - 1]), np.abs(extra - nodes[pos]))
        extra = extra[(gap > 1e-9) & (extra > t0) & (extra < t1)]  # never a near-copy of a node
        grid = np.unique(np.concatenate([nodes, extra]))
        states = sol.sol((grid - t1) if backward else (grid - t0)).T
        # keep propagate's own samples exactly
        at_node = np.searchsorted(grid, t_nodes[a:b])
        states[at_node] = s_nodes[a:b]
        ts.append(grid); ss.append(states); segs.append(np.full(grid.size, k))
    t, states, seg = np.concatenate(ts), np.vstack(ss), np.concatenate(segs)
    # propagate's two halves meet at the match point with times equal only to ~1e-14 TU: make t non-decreasing
    t = np.maximum.accumulate(t)
    return _tabulate(t, states, seg, x, alpha)


def _tabulate(t: np.ndarray, states: np.ndarray, seg: np.ndarray, x: np.ndarray, alpha: float) -> pd.DataFrame:
    n_seg = (len(x) - 4) // 3
    tau_s, tau_i = float(x[0]), float(x[1])
    controls = x[4:].reshape(n_seg, 3)
    pick = np.maximum(seg, 1) - 1
    theta = np.where(seg > 0, controls[pick, 0], np.nan)
    phi = np.where(seg > 0, controls[pick, 1], np.nan)
    rho = np.where(seg > 0, controls[pick, 2], 0.0)
    u_rot = np.stack([np.cos(phi) * np.cos(theta), np.cos(phi) * np.sin(theta), np.sin(phi)], -1)
    coast = np.where(t <= tau_i + tau_s / 2, "coast_initial", "coast_final")
    arc = np.where(seg > 0, np.char.add("thrust_", np.char.zfill(seg.astype(str), 2)), coast)
    emi = frames.rotating_to_inertial(t, states[:, :6])
    epochs = frames.epochs(t)
    epochs.precision = 6
    out = {
        "t_tu": t,
        "t_s": frames.seconds_after_epoch(t),
        "epoch_tdb": epochs.isot,
        "arc": arc,
        "segment": seg,
        **{c: states[:, i] for i, c in enumerate(ROT_ND)},
        **{c: v for c, v in zip(ROT_KM, frames.to_km(states[:, :6]).T)},
        **{c: v for c, v in zip(EMI_KM, frames.to_km(emi).T)},
        "fuel_kg": states[:, 6],
        "mass_kg": K.DRY_MASS_KG + states[:, 6],
        "throttle": rho,
        "thrust_n": rho * alpha,
        **{c: u_rot[:, i] for i, c in enumerate(("ux_rot", "uy_rot", "uz_rot"))},
        **{c: v for c, v in zip(("ux_emi", "uy_emi", "uz_emi"), frames.rotate_direction(t, u_rot).T)},
    }
    return pd.DataFrame(out)


def distinct_epochs(history: pd.DataFrame) -> pd.DataFrame:
    """The first sample of every distinct epoch (to the microsecond of the OEM format), in time order."""
    micro = np.round(history["t_s"].to_numpy() * 1e6).astype(np.int64)
    keep = np.r_[True, micro[1:] > micro[:-1]]
    return history.loc[keep].reset_index(drop=True)


def write_oem(history: pd.DataFrame, path: str | Path, object_name: str, object_id: str) -> Path:
    """Write the inertial (EMI_CR3BP, km, km/s) ephemeris of one history as a KVN CCSDS OEM (v2.0)."""
    from astropy.time import Time
    from oem import OrbitEphemerisMessage
    from oem.components import EphemerisSegment, HeaderSection, MetaDataSection

    from amorgs.data.io import atomic_path

    h = distinct_epochs(history)
    times = frames.epochs(h["t_tu"].to_numpy())
    times.precision = 6
    header = HeaderSection({
        "CCSDS_OEM_VERS": OEM_VERSION,
        "CREATION_DATE": Time.now().utc.isot,
        "ORIGINATOR": ORIGINATOR,
    })
    metadata = MetaDataSection({
        "OBJECT_NAME": object_name,
        "OBJECT_ID": object_id,
        "CENTER_NAME": "EARTH",
        "REF_FRAME": frames.INERTIAL_FRAME_NAME,
        "REF_FRAME_EPOCH": f"{frames.EPOCH_ISO}.000000",
        "TIME_SYSTEM": frames.EPOCH_SCALE.upper(),
        "START_TIME": times[0].isot,
        "STOP_TIME": times[-1].isot,
        "INTERPOLATION": "LAGRANGE",
        "INTERPOLATION_DEGREE": "5",
    }, version=OEM_VERSION)
    columns = [h[c].to_numpy(dtype=float) for c in EMI_KM]
    segment = EphemerisSegment(metadata, (list(times), *columns), version=OEM_VERSION)
    message = OrbitEphemerisMessage(header, [segment])
    path = Path(path)
    with atomic_path(path) as tmp:
        message.save_as(tmp, file_format="kvn")
    return path


def plot_trajectories(histories: Sequence[pd.DataFrame], alpha: float, labels: Sequence[str] | None = None):
    """3-D plot of the trajectories: rotating frame (barycentric, 10³ km) and Earth-centred inertial frame."""
    from matplotlib import pyplot as plt
    from matplotlib.ticker import MaxNLocator

    fig = plt.figure(figsize=(13, 7))
    axes = [fig.add_subplot(1, 2, i + 1, projection="3d") for i in range(2)]
    cmap = plt.get_cmap("viridis")
    labels = list(labels) if labels is not None else [f"#{i + 1}" for i in range(len(histories))]
    for i, (h, lab) in enumerate(zip(histories, labels)):
        colour = cmap(i / max(len(histories) - 1, 1))
        for ax, cols in ((axes[0], ROT_KM), (axes[1], EMI_KM)):
            ax.plot(*(h[c].to_numpy() / 1e3 for c in cols[:3]), lw=0.8, color=colour, label=lab)
            ax.scatter(*(h[c].to_numpy()[-1:] / 1e3 for c in cols[:3]), s=6, color=colour)
    du = K.DU_KM / 1e3
    axes[0].scatter([-K.MU * du], [0], [0], color="tab:blue", s=40, label="Earth")
    axes[0].scatter([(1 - K.MU) * du], [0], [0], color="0.5", s=15, label="Moon")
    if histories:
        tof = max(float(h["t_tu"].iloc[-1]) for h in histories)
        th = np.linspace(0, tof, 400)
        axes[1].plot(du * np.cos(th), du * np.sin(th), 0 * th, color="0.5", lw=0.6, ls="--", label="Moon")
    axes[1].scatter([0], [0], [0], color="tab:blue", s=40, label="Earth")
    axes[0].set_title(f"rotating frame (barycentric), α = {alpha:g} N")
    axes[1].set_title(f"Earth-centred inertial ({frames.INERTIAL_FRAME_NAME}), t0 = {frames.EPOCH_ISO} TDB")
    for ax in axes:
        lims = np.array([ax.get_xlim3d(), ax.get_ylim3d(), ax.get_zlim3d()])
        ax.set_box_aspect(np.maximum(lims[:, 1] - lims[:, 0], 1e-9))  # equal scale on the three axes
        ax.zaxis.set_major_locator(MaxNLocator(3))
        ax.set_xlabel("x [10³ km]")
        ax.set_ylabel("y [10³ km]")
        ax.set_zlabel("z [10³ km]")
    handles, names = axes[0].get_legend_handles_labels()
    fig.legend(handles, names, fontsize=7, loc="lower center", ncol=4, frameon=False)
    fig.subplots_adjust(left=0.02, right=0.95, top=0.93, bottom=0.03 + 0.022 * ((len(names) + 3) // 4), wspace=0.1)
    return fig
