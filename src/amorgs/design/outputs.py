"""The files of ``amorgs design``: the chosen solutions as tables, dense trajectories (CSV and CCSDS OEM in an
Earth-centred inertial frame), a 3-D plot, a JSON summary and a README, all under one output folder
(:func:`write_outputs`); and the check that the folder can take them, made before the first solve
(:func:`check_output_dir`).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from amorgs.alphas import alpha_label
from amorgs.design.search import PROBLEM, DesignResult
from amorgs.errors import InputError


def check_output_dir(output_dir: str | Path, library_dir: str | Path | None = None) -> None:
    """:class:`InputError` naming the folder if the design's files could not be written there (a file in the
    way, no write permission, a read-only file system) or it lies inside the solution library ``library_dir``
    (every later run would refuse the library's unlisted files) — checked before the first solve, writing nothing
    that stays: a folder that exists must take a file; else its nearest existing parent must."""
    import tempfile

    out = Path(output_dir)
    if library_dir is not None and out.resolve().is_relative_to(Path(library_dir).resolve()):
        raise InputError(f"--output {output_dir}: inside the solution library {library_dir} (its files are only "
                         "what `amorgs library-export` adds); choose another folder")
    for path in (out, out / "trajectories"):
        if path.exists() and not path.is_dir():
            raise InputError(f"{path}: not a folder (--output {output_dir})")
    existing = out
    while not existing.exists() and existing != existing.parent:
        existing = existing.parent
    if not existing.is_dir():
        raise InputError(f"{out}: cannot be created, {existing} is not a folder (--output {output_dir})")
    try:
        with tempfile.TemporaryFile(dir=existing):
            pass
    except OSError as exc:
        raise InputError(f"{out}: output folder not writable ({existing}: {exc.strerror or exc})") from None



def default_output_dir(alpha: float) -> Path:
    """``results/design/alpha=<label>/``."""
    return Path("results/design") / f"alpha={alpha_label(alpha)}"


def write_outputs(result: DesignResult, output_dir: str | Path) -> dict[str, list[Path]]:
    """Write the design of ``result`` under ``output_dir`` and return the paths by kind::

        solutions.parquet, solutions.csv     the chosen solutions (solution-table columns + rank), best m_f first
        all_solves.parquet                   every solve of the search (+ high_quality, selected)
        summary.json                         request, counts, timings, sampler provenance, frames and epoch
        trajectories.png                     3-D plot, rotating and Earth-centred inertial frames
        trajectories/rank-KK.csv             dense state and control history (trajectory_export.dense_history)
        trajectories/rank-KK.oem             CCSDS OEM (KVN), Earth-centred inertial EMI_CR3BP, TDB
        best_known.csv                       where the best-known record holds the best known m_f at α
        trajectories/best-known.{csv,oem}    (``result.best_known``): that trajectory (stored layout at α, its
                                             provenance), whether or not the search found it
        README.txt                           what the files hold, the frames and the epoch

    Earlier ``trajectories/rank-*.{csv,oem}`` in the folder are removed first (they belong to an earlier call).
    """
    import matplotlib

    matplotlib.use("Agg")
    from matplotlib import pyplot as plt

    from amorgs import trajectory_export as te
    from amorgs.data.io import atomic_path, write_json, write_parquet
    from amorgs.problems import get_problem
    from amorgs.problems.cr3bp import frames

    out = Path(output_dir)
    traj_dir = out / "trajectories"
    traj_dir.mkdir(parents=True, exist_ok=True)
    for old in [*traj_dir.glob("rank-*.csv"), *traj_dir.glob("rank-*.oem"), *traj_dir.glob("best-known.*"),
                *out.glob("best_known.csv")]:
        old.unlink()
    problem = get_problem(PROBLEM)
    req = result.request
    label = alpha_label(req.alpha)
    paths: dict[str, list[Path]] = {"tables": [], "trajectories": [], "figures": [], "reports": []}

    selected = result.selected
    write_parquet(selected, out / "solutions.parquet")
    with atomic_path(out / "solutions.csv") as tmp:
        selected.to_csv(tmp, index=False)
    paths["tables"] += [out / "solutions.parquet", out / "solutions.csv"]
    if len(result.solves):
        write_parquet(result.solves, out / "all_solves.parquet")
        paths["tables"].append(out / "all_solves.parquet")

    histories, labels = [], []

    def trajectory(x: np.ndarray, stem: str, object_name: str, object_id: str, caption: str) -> None:
        """``trajectories/<stem>.{csv,oem}`` of the stored vector ``x`` at α, and its curve and label in the plot."""
        history = te.dense_history(x, req.alpha, problem.initial_state, problem.terminal_state)
        csv = traj_dir / f"{stem}.csv"
        with atomic_path(csv) as tmp:
            history.to_csv(tmp, index=False)
        oem = te.write_oem(history, traj_dir / f"{stem}.oem", object_name=object_name, object_id=object_id)
        paths["trajectories"] += [csv, oem]
        histories.append(history)
        labels.append(f"{caption} m_f={x[3]:.1f} kg TOF={x[0] + x[1] + x[2]:.1f} TU")

    for _, row in selected.iterrows():
        rank = int(row["rank"])
        trajectory(row[list(problem.variable_names)].to_numpy(dtype=float), f"rank-{rank:02d}",
                   f"AMORGS ALPHA={label} RANK={rank:02d}", f"amorgs-{label}-seed{req.seed}-start{int(row['start'])}",
                   f"#{rank}")

    known = result.best_known
    if known is not None:  # the record's trajectory at α: what "below the best known" measures against
        import pandas as pd

        x = np.asarray(known["x"], float)
        source = known["source"]
        row = {"alpha": req.alpha, "m_f": float(x[3]), "verify_defect": float(known["verify_defect"]),
               "source_kind": source.get("kind", ""), "from_alpha": float(source.get("from_alpha", req.alpha)),
               "where": source.get("where", ""), "commit": source.get("commit", ""),
               **dict(zip(problem.variable_names, x))}
        with atomic_path(out / "best_known.csv") as tmp:
            pd.DataFrame([row]).to_csv(tmp, index=False)
        paths["tables"].append(out / "best_known.csv")
        trajectory(x, "best-known", f"AMORGS ALPHA={label} BEST KNOWN", f"amorgs-{label}-best-known",
                   "best known (record)")

    fig = te.plot_trajectories(histories, req.alpha, labels)
    with atomic_path(out / "trajectories.png") as tmp:
        fig.savefig(tmp, format="png", dpi=150, bbox_inches="tight")
    plt.close(fig)
    paths["figures"].append(out / "trajectories.png")

    summary = {
        **result.summary(),
        "frames": {
            "rotating": "barycentric rotating (synodic) frame of the CR3BP, Earth at (-mu, 0, 0), Moon at (1-mu, 0, 0)",
            "inertial": frames.INERTIAL_FRAME_DESCRIPTION,
            "inertial_name": frames.INERTIAL_FRAME_NAME,
            "epoch": f"{frames.EPOCH_ISO} {frames.EPOCH_SCALE.upper()} = departure (t = 0)",
            "units": {"DU_km": frames.DU_KM, "VU_km_s": frames.VU_KM_S, "TU_s": frames.TU_S},
        },
        "solutions": [
            {"rank": int(r["rank"]), "start": int(r["start"]), "m_f_kg": float(r["m_f"]),
             "tof_tu": float(r["tau_s"] + r["tau_i"] + r["tau_f"]), "iterations": int(r["iterations"]),
             "verify_defect": float(r["verify_defect"])}
            for _, r in selected.iterrows()
        ],
        "best_known_trajectory": None if known is None else {
            "m_f_kg": float(known["m_f_kg"]), "verify_defect": float(known["verify_defect"]),
            "source": known["source"], "files": ["best_known.csv", "trajectories/best-known.csv",
                                                 "trajectories/best-known.oem"]},
    }
    write_json(summary, out / "summary.json")
    with atomic_path(out / "README.txt") as tmp:
        tmp.write_text(_readme(result, summary))
    paths["reports"] += [out / "summary.json", out / "README.txt"]
    return paths


def _best_known_lines(result: DesignResult) -> str:
    """The README's lines on the best known m_f at α and, where the best-known record holds it, its files."""
    known, source = result.info.get("best_known_m_f_kg"), result.info.get("best_known_source", "none")
    if known is None:
        return ""
    text = f"\n\nBest known m_f at this alpha: {known:.3f} kg ({source}); below_best_known_kg in solutions.csv is " \
           "each solution's distance from it."
    if result.best_known is not None:
        s = result.best_known["source"]
        text += f"""
best_known.csv             that trajectory (decision vector at this alpha, from_alpha, where, commit): the record's
                           entry, found at alpha = {float(s.get('from_alpha', result.request.alpha)):g} N in {s.get('where') or 'an unnamed run'}
                           ({s.get('kind', '')}; a lifted one flies unchanged here, throttles rescaled by
                           alpha_s / alpha), independently re-verified at this alpha.
trajectories/best-known.csv, .oem   its dense history and OEM, as for rank-KK."""
    return text


def _readme(result: DesignResult, summary: dict) -> str:
    from amorgs import trajectory_export as te
    from amorgs.problems.cr3bp import frames

    req = result.request
    return f"""amorgs design: alpha = {req.alpha:g} N (maximum thrust), {len(result.selected)} of {req.n} solutions wanted
Each is converged (IPOPT + independent DOP853 re-propagation of the match point <= 1e-5 in DU, VU, t),
has final fuel m_f >= {req.beta_kg:g} kg, and is more than eta = {req.eta:g} from every other under the
time metric of paper Eq. 12 (Euclidean on tau_s/40, tau_i/15, tau_f/15). Search: sampler {req.sampler},
seed {req.seed}, {result.starts} starts in {result.rounds} rounds, stop: {result.stop_reason}.

solutions.parquet / .csv   the chosen solutions, best m_f first: decision vector (tau_s, tau_i, tau_f in TU,
                           m_f in kg, theta_k, phi_k in rad, rho_k in [0, 1]), guess_*, solver status, defects
all_solves.parquet         every solve of the search
trajectories/rank-KK.csv   dense history of solution KK: {', '.join(['t_tu', 't_s', 'epoch_tdb', 'arc', 'segment'])},
                           rotating barycentric {', '.join(te.ROT_ND)} (DU, VU) and {', '.join(te.ROT_KM)},
                           Earth-centred inertial {', '.join(te.EMI_KM)}, fuel_kg, mass_kg (wet), throttle,
                           thrust_n, thrust direction ux_rot..uz_rot (rotating axes), ux_emi..uz_emi (inertial axes).
                           Arc boundaries appear twice (end of one arc, start of the next).
trajectories/rank-KK.oem   CCSDS OEM 2.0 (KVN): inertial position and velocity, km and km/s.
trajectories.png           3-D plot in both frames.{_best_known_lines(result)}

Frames and time
  rotating:  {summary['frames']['rotating']}; DU = {frames.DU_KM} km, VU = {frames.VU_KM_S:.9f} km/s,
             TU = {frames.TU_S:.6f} s.
  inertial ({frames.INERTIAL_FRAME_NAME}): {frames.INERTIAL_FRAME_DESCRIPTION}
  epoch:     t = 0 (departure from the end of the GTO spiral) is {frames.EPOCH_ISO} {frames.EPOCH_SCALE.upper()};
             a sample at t TU is at epoch + t * TU seconds. The CR3BP is time-invariant: the epoch is nominal.
  The transfer ends on the stable manifold of the L1 halo orbit (spec section 4); the coast along the manifold
  to the halo is not part of these files.
"""


