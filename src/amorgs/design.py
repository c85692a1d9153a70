"""Trajectory design on demand: N good, verified, η-diverse CR3BP transfers at one α (issue 12).

:func:`design` is the search behind ``amorgs design``.  It draws warm starts from a sampler (default
``nearest_alpha``: the high-quality *library* solutions of the nearest training α, reused unchanged — the
arm that measured best in the ablation), solves them with the workflow's solver and options
(``problems.cr3bp.solver`` of the config) through the multistart pool, in **rounds** of ``round_size``
starts, until ``n`` solutions are

- *high quality*: converged — the solver succeeded **and** the independent DOP853 re-propagation closes the
  match point to ``verify_tol`` (spec §6) — and m_f ≥ β (kg);
- *η-diverse* (paper Eq. 12): pairwise farther than η apart under the surrogate metric of
  :mod:`amorgs.analysis.diversity` (default features ``"times"``: Euclidean on (τ_s/40, τ_i/15, τ_f/15),
  dimensionless; η = 0.02 ≈ 0.8 TU of τ_s or 0.3 TU of τ_i, τ_f),

or a budget runs out (``max_starts`` solves, or ``max_cpu_s`` CPU seconds of this process and its solver
workers, checked between rounds).  Determinism: the guesses come from ``numpy.random.default_rng(seed)``,
one ``sampler.sample`` call per round, and every solve is deterministic (iteration cap first), so a seed
gives the same table for any number of workers — unless the CPU budget (timing-dependent) ends the search
at a different round.

The chosen solutions: the η-diverse subset of every high-quality solution found (minimum-degree greedy,
ties to higher m_f), the ``n`` with the highest m_f, ranked by m_f.
"""

from __future__ import annotations

import math
import resource
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from amorgs.ablation.arms import REUSE_ARM
from amorgs.alphas import alpha_label
from amorgs.config import ConfigError
from amorgs.errors import InputError
from amorgs.solvers.options import IpoptOptions

PROBLEM = "cr3bp"
#: Defaults of ``amorgs design`` (see :class:`DesignRequest`).
DEFAULT_SAMPLER = REUSE_ARM  # library solutions of the nearest training α
DEFAULT_LIBRARY_DIR = "data/library"
DEFAULT_MODELS_DIR = "data/models/cr3bp"
DEFAULT_CONFIG = "config/default.yaml"


@dataclass(frozen=True)
class DesignRequest:
    """What to search for and with which budget.

    alpha: maximum thrust α in N, in [0.1, 1.0].      n: solutions wanted (≥ 1).
    sampler: a registered sampler name (``amorgs.ablation.arms.SAMPLER_NAMES``).
    beta_kg: β, the minimum final fuel mass m_f in kg.   eta: η of Eq. 12 (dimensionless, see module doc).
    seed: seed of the guesses.   workers: solver processes.   round_size: starts per round.
    max_starts: at most this many solves.   max_cpu_s: stop starting rounds after this many CPU seconds.
    library_dir: the solution library (seeds of the library-based samplers; training α only, β-filtered
    with the config's filter β).   models_dir: checkpoints of the learned samplers.
    config: the config file giving the solver options, the training α, the filter β and the sampler options.
    """

    alpha: float
    n: int
    sampler: str = DEFAULT_SAMPLER
    beta_kg: float = 415.0
    eta: float = 0.02
    seed: int = 0
    workers: int = 2
    round_size: int = 16
    max_starts: int = 400
    max_cpu_s: float = 3600.0
    library_dir: str = DEFAULT_LIBRARY_DIR
    models_dir: str = DEFAULT_MODELS_DIR
    config: str = DEFAULT_CONFIG

    def check(self) -> None:
        """One :class:`ConfigError` naming the option for every out-of-range value (β against the problem's
        bound on m_f: :func:`check_beta`, once the problem is loaded)."""
        from amorgs.ablation.arms import SAMPLER_NAMES
        from amorgs.problems import ALPHA_RANGES

        lo, hi = ALPHA_RANGES[PROBLEM]
        if not (isinstance(self.alpha, (int, float)) and math.isfinite(self.alpha) and lo <= self.alpha <= hi):
            raise ConfigError(f"--alpha {self.alpha}: the maximum thrust α must lie in [{lo}, {hi}] N")
        if self.n < 1:
            raise ConfigError(f"-n {self.n}: ask for at least 1 solution")
        if self.sampler not in SAMPLER_NAMES:
            raise ConfigError(f"--sampler {self.sampler!r}: choose one of {', '.join(SAMPLER_NAMES)}")
        if not (math.isfinite(self.beta_kg) and self.beta_kg >= 0):
            raise ConfigError(f"--beta {self.beta_kg}: β must be a final mass ≥ 0 kg")
        if self.seed < 0:
            raise ConfigError(f"--seed {self.seed}: the seed must be ≥ 0")
        if not (math.isfinite(self.eta) and self.eta > 0):
            raise ConfigError(f"--eta {self.eta}: η must be > 0")
        if self.workers < 1:
            raise ConfigError(f"--workers {self.workers}: at least 1 solver process")
        if self.round_size < 1:
            raise ConfigError(f"--round-size {self.round_size}: at least 1 start per round")
        if self.max_starts < 1:
            raise ConfigError(f"--max-starts {self.max_starts}: the budget must allow at least 1 start")
        if not (self.max_cpu_s > 0 and not math.isnan(self.max_cpu_s)):
            raise ConfigError(f"--max-cpu-s {self.max_cpu_s}: the CPU budget must be > 0 seconds")


@dataclass
class DesignResult:
    """Outcome of :func:`design`.

    ``selected``: the chosen solutions (≤ n rows, solution-table columns + ``rank``, best m_f first);
    ``solves``: every solve (solution-table columns, ``shard`` = round index, ``high_quality`` and
    ``selected`` flags); ``found``: size of the η-diverse high-quality set; ``stop_reason``: ``found``,
    ``max_starts`` or ``max_cpu_s``; ``cpu_s``: CPU seconds of this process and its solver workers;
    ``solver_cpu_s``: the IPOPT CPU seconds summed over solves; ``wall_s``: wall seconds; ``info``: the
    sampler's provenance (nearest training α, seed rows) and the solver options.
    """

    request: DesignRequest
    selected: pd.DataFrame
    solves: pd.DataFrame
    found: int
    starts: int
    rounds: int
    stop_reason: str
    cpu_s: float
    solver_cpu_s: float
    wall_s: float
    info: dict = field(default_factory=dict)

    def summary(self) -> dict:
        """Flat JSON-able summary (request, counts, timings, provenance)."""
        conv = self.solves["converged"].astype(bool) if len(self.solves) else pd.Series(dtype=bool)
        return {
            "request": asdict(self.request),
            "alpha_label": alpha_label(self.request.alpha),
            "found": self.found,
            "returned": int(len(self.selected)),
            "starts": self.starts,
            "rounds": self.rounds,
            "converged": int(conv.sum()),
            "high_quality": int(self.solves["high_quality"].sum()) if len(self.solves) else 0,
            "stop_reason": self.stop_reason,
            "cpu_s": self.cpu_s,
            "solver_cpu_s": self.solver_cpu_s,
            "wall_s": self.wall_s,
            "m_f_best_kg": float(self.selected["m_f"].max()) if len(self.selected) else None,
            **self.info,
        }


def _cpu_seconds() -> float:
    """CPU seconds of this process plus its terminated (reaped) children — the solver workers."""
    children = resource.getrusage(resource.RUSAGE_CHILDREN)
    return time.process_time() + children.ru_utime + children.ru_stime


def library_high_quality(library_dir: str | Path, train_alphas, min_final_mass_kg: float) -> pd.DataFrame:
    """The library's high-quality rows (converged, m_f ≥ β) at the training α; :class:`InputError` naming the
    manifest if the library is missing or holds none, or the file if one differs from the manifest or is not
    listed in it (:func:`~amorgs.data.library.verify_library`)."""
    from amorgs.data.filter import high_quality
    from amorgs.data.library import MANIFEST, read_library, verify_library

    manifest = Path(library_dir) / PROBLEM / MANIFEST
    if verify_library(library_dir, PROBLEM) is None:
        raise InputError(f"{manifest}: solution library not found (--library-dir {library_dir})")
    frames = [read_library(library_dir, PROBLEM, alpha_label(a)) for a in train_alphas]
    frames = [f for f in frames if len(f)]
    if not frames:
        raise InputError(f"{manifest}: the library holds no solutions at the training α {list(train_alphas)}")
    hq = high_quality(pd.concat(frames, ignore_index=True), min_final_mass_kg=min_final_mass_kg)
    if not len(hq):
        raise InputError(f"{manifest}: no library solution at the training α has m_f ≥ {min_final_mass_kg} kg")
    return hq


def make_sampler(request: DesignRequest, cfg, problem):
    """The requested sampler and a provenance dict; missing inputs raise :class:`InputError` naming the file."""
    from amorgs.ablation.arms import build_sampler, get_arm
    from amorgs.models.samplers import CHECKPOINTS, nearest_training_alpha

    arm = get_arm(request.sampler)
    section = cfg.problems.cr3bp
    train = tuple(section.alphas.train_values())
    info: dict = {"sampler": request.sampler}
    models_dir = None
    if arm.models:
        models_dir = Path(request.models_dir)
        for model in arm.models:
            path = models_dir / CHECKPOINTS[model]
            if not path.is_file():
                raise InputError(f"{path}: model checkpoint not found (--models-dir {request.models_dir}; "
                                 f"sampler {request.sampler} needs {', '.join(arm.models)})")
        from amorgs.models.shipped import verify_models

        shipped = verify_models(models_dir, tuple(CHECKPOINTS[m] for m in arm.models))
        if shipped is not None:
            info["models_git_commit"] = shipped["git_commit"]
    hq = None
    if arm.high_quality:
        hq = library_high_quality(request.library_dir, train, section.filter.min_final_mass_kg)
        info["library_seed_rows"] = int(len(hq))
    try:
        sampler = build_sampler(request.sampler, problem, models_dir=models_dir, high_quality=hq, train_alphas=train,
                                perturbation_scale=cfg.ablation.perturbation_scale,
                                gmm_components=cfg.ablation.gmm_components)
    except (OSError, RuntimeError) as exc:  # unreadable checkpoint
        raise InputError(f"{models_dir}: cannot load the models of sampler {request.sampler}: {exc}") from None
    by_alpha = getattr(sampler, "by_alpha", None)
    if by_alpha is not None:
        try:
            nearest = nearest_training_alpha(by_alpha, request.alpha)
        except ValueError as exc:
            raise InputError(f"{Path(request.library_dir) / PROBLEM}: {exc}") from None
        info["nearest_training_alpha"] = float(nearest)
        info["nearest_alpha_seed_rows"] = int(len(by_alpha[nearest]))
    return sampler, info


def select_diverse(hq: pd.DataFrame, eta: float, n: int) -> tuple[int, pd.DataFrame]:
    """(size of the η-diverse subset of ``hq``, its ``n`` best rows by m_f with a 1-based ``rank``)."""
    from amorgs.analysis.diversity import DiversityParams, diversity_features, greedy_diverse_subset

    if not len(hq):
        return 0, hq.assign(rank=pd.Series(dtype=int))
    params = DiversityParams(eta=eta)
    idx = greedy_diverse_subset(diversity_features(hq, params), params.eta, hq["m_f"].to_numpy(float))
    chosen = hq.iloc[idx].sort_values(["m_f", "start"], ascending=[False, True], kind="stable").head(n)
    return int(idx.size), chosen.reset_index(drop=True).assign(rank=np.arange(1, len(chosen) + 1))


def check_beta(beta_kg: float, problem) -> None:
    """:class:`ConfigError` if no solution of ``problem`` can reach m_f ≥ β: β above the upper bound of m_f
    (all the fuel left, 451.9 kg), which would spend the whole budget on solves that can never count."""
    bound = float(problem.upper[list(problem.variable_names).index("m_f")])
    if beta_kg > bound:
        raise ConfigError(f"--beta {beta_kg:g}: above the largest final mass a transfer can keep, m_f ≤ "
                          f"{bound:.1f} kg (no fuel spent); no solution could count")


def check_output_dir(output_dir: str | Path) -> None:
    """:class:`InputError` naming the folder if the design's files could not be written there (a file in the
    way, no write permission, a read-only file system) — checked before the first solve, writing nothing
    that stays: a folder that exists must take a file; else its nearest existing parent must."""
    import tempfile

    out = Path(output_dir)
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


@dataclass
class Prepared:
    """Everything :func:`design` needs before the first solve: the config, the solver options, the problem and
    the sampler with its provenance (``info``)."""

    cfg: object
    solver_options: IpoptOptions
    problem: object
    sampler: object
    info: dict


def prepare(request: DesignRequest) -> Prepared:
    """Check the request and load its inputs (config, library or models); bad options raise
    :class:`ConfigError`, missing or unreadable files :class:`InputError` — before any solve."""
    from amorgs.config import load_config
    from amorgs.problems import get_problem

    request.check()
    if not Path(request.config).is_file():
        raise InputError(f"{request.config}: config file not found (--config)")
    cfg = load_config(request.config)
    problem = get_problem(PROBLEM)
    check_beta(request.beta_kg, problem)
    sampler, info = make_sampler(request, cfg, problem)
    solver_options = cfg.problems.cr3bp.solver
    info["solver_options"] = solver_options.to_dict()
    return Prepared(cfg, solver_options, problem, sampler, info)


def design(request: DesignRequest, progress: Callable[[dict], None] | None = None,
           prepared: Prepared | None = None) -> DesignResult:
    """Run the search (module docstring); ``progress`` is called after every round with the running counts
    (``found``, ``n``, ``starts``, ``max_starts``, ``cpu_s``, ``max_cpu_s``, ``wall_s``, ``round``).
    ``prepared``: the result of :func:`prepare` for this request (made here if not given)."""
    from amorgs.data.filter import high_quality
    from amorgs.data.tables import validate_solutions
    from amorgs.solvers.multistart import records_table, solve_guesses

    wall0, cpu0 = time.perf_counter(), _cpu_seconds()
    prepared = prepared or prepare(request)
    solver_options, problem, sampler = prepared.solver_options, prepared.problem, prepared.sampler
    info = dict(prepared.info)
    rng = np.random.default_rng(request.seed)

    tables: list[pd.DataFrame] = []
    solves = pd.DataFrame()
    found, starts, rounds, selected = 0, 0, 0, pd.DataFrame()
    stop_reason = ""
    while True:
        cpu = _cpu_seconds() - cpu0
        if found >= request.n:
            stop_reason = "found"
        elif starts >= request.max_starts:
            stop_reason = "max_starts"
        elif cpu >= request.max_cpu_s:
            stop_reason = "max_cpu_s"
        if stop_reason:
            break
        size = min(request.round_size, request.max_starts - starts)
        guesses = sampler.sample(request.alpha, size, rng)
        records, run_info = solve_guesses(problem, request.alpha, guesses, request.workers, solver_options,
                                          progress=False)
        table = records_table(PROBLEM, request.alpha, request.seed, guesses, records, problem.variable_names,
                              run_info["options_hash"])
        table["start"] += starts
        table.insert(int(table.columns.get_loc("seed")) + 1, "shard", rounds)
        tables.append(table)
        starts += size
        rounds += 1
        solves = pd.concat(tables, ignore_index=True)
        hq = high_quality(solves, min_final_mass_kg=request.beta_kg)
        found, selected = select_diverse(hq, request.eta, request.n)
        if progress is not None:
            progress({"round": rounds, "found": found, "n": request.n, "starts": starts,
                      "max_starts": request.max_starts, "cpu_s": _cpu_seconds() - cpu0,
                      "max_cpu_s": request.max_cpu_s, "wall_s": time.perf_counter() - wall0})

    if len(solves):
        validate_solutions(solves, problem.variable_names, where="design solves")
        keep = solves["converged"].astype(bool) & (solves["m_f"] >= request.beta_kg)
        solves["high_quality"] = keep.to_numpy()
        solves["selected"] = solves["start"].isin(selected["start"]) if len(selected) else False
    return DesignResult(
        request=request,
        selected=selected,
        solves=solves,
        found=found,
        starts=starts,
        rounds=rounds,
        stop_reason=stop_reason,
        cpu_s=_cpu_seconds() - cpu0,
        solver_cpu_s=float(solves["cpu_s"].sum()) if len(solves) else 0.0,
        wall_s=time.perf_counter() - wall0,
        info=info,
    )


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
    for old in [*traj_dir.glob("rank-*.csv"), *traj_dir.glob("rank-*.oem")]:
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
    for _, row in selected.iterrows():
        rank = int(row["rank"])
        x = row[list(problem.variable_names)].to_numpy(dtype=float)
        history = te.dense_history(x, req.alpha, problem.initial_state, problem.terminal_state)
        csv = traj_dir / f"rank-{rank:02d}.csv"
        with atomic_path(csv) as tmp:
            history.to_csv(tmp, index=False)
        oem = te.write_oem(history, traj_dir / f"rank-{rank:02d}.oem",
                           object_name=f"AMORGS ALPHA={label} RANK={rank:02d}",
                           object_id=f"amorgs-{label}-seed{req.seed}-start{int(row['start'])}")
        paths["trajectories"] += [csv, oem]
        histories.append(history)
        labels.append(f"#{rank} m_f={row['m_f']:.1f} kg TOF={row['tau_s'] + row['tau_i'] + row['tau_f']:.1f} TU")

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
    }
    write_json(summary, out / "summary.json")
    with atomic_path(out / "README.txt") as tmp:
        tmp.write_text(_readme(result, summary))
    paths["reports"] += [out / "summary.json", out / "README.txt"]
    return paths


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
trajectories.png           3-D plot in both frames.

Frames and time
  rotating:  {summary['frames']['rotating']}; DU = {frames.DU_KM} km, VU = {frames.VU_KM_S:.9f} km/s,
             TU = {frames.TU_S:.6f} s.
  inertial ({frames.INERTIAL_FRAME_NAME}): {frames.INERTIAL_FRAME_DESCRIPTION}
  epoch:     t = 0 (departure from the end of the GTO spiral) is {frames.EPOCH_ISO} {frames.EPOCH_SCALE.upper()};
             a sample at t TU is at epoch + t * TU seconds. The CR3BP is time-invariant: the epoch is nominal.
  The transfer ends on the stable manifold of the L1 halo orbit (spec section 4); the coast along the manifold
  to the halo is not part of these files.
"""


# ------------------------------------------------------------------------------- the command behind the CLI

#: The MLflow store of ``amorgs design`` calls: its own SQLite database beside the workflow's, so that a design
#: never touches a running workflow's invocation (``results/mlflow/invocation.json``).
DESIGN_STORE_DIR = Path("results/mlflow")  # the workflow's store: `amorgs ui` shows designs beside workflow runs
DESIGN_EXPERIMENT = "amorgs-design"


class ProgressLine:
    """Progress on stderr after every round: tqdm if it is installed, else one updating line (a new line per
    round when stderr is not a terminal)."""

    def __init__(self, request: DesignRequest, stream=None):
        import importlib.util
        import sys

        self.stream = stream or sys.stderr
        self.request = request
        self._bar = None
        if importlib.util.find_spec("tqdm") is not None:
            from tqdm import tqdm

            self._bar = tqdm(total=request.n, desc=f"design α={alpha_label(request.alpha)}", unit="sol",
                             file=self.stream)
        self._tty = hasattr(self.stream, "isatty") and self.stream.isatty()

    def __call__(self, state: dict) -> None:
        text = (f"starts {state['starts']}/{state['max_starts']} | CPU {state['cpu_s']:.0f}/{state['max_cpu_s']:.0f} s"
                f" | wall {state['wall_s']:.0f} s | round {state['round']}")
        if self._bar is not None:
            self._bar.n = min(state["found"], state["n"])
            self._bar.set_postfix_str(text)
            return
        n, found = state["n"], min(state["found"], state["n"])
        width = 20
        filled = int(round(width * found / n))
        line = f"design α={alpha_label(self.request.alpha)} [{'#' * filled}{'.' * (width - filled)}] {found}/{n} | {text}"
        self.stream.write(("\r" + line) if self._tty else line + "\n")
        self.stream.flush()

    def close(self) -> None:
        if self._bar is not None:
            self._bar.close()
        elif self._tty:
            self.stream.write("\n")
            self.stream.flush()


def run_design(request: DesignRequest, output_dir: str | Path | None = None, track: bool = True,
               store_dir: str | Path = DESIGN_STORE_DIR, progress: bool = True) -> tuple[DesignResult, dict]:
    """``amorgs design``: check every option (the output folder included) and prepare — every user error
    before the first solve —, search, write the outputs, mirror it to MLflow.

    MLflow (unless ``track`` is false or the config's ``mlflow.enabled`` is false): one run per call
    (:func:`amorgs.tracking.standalone_run`) in experiment :data:`DESIGN_EXPERIMENT` of the store
    ``store_dir``, holding the request as parameters, the metrics (per round and final: found, starts, CPU s,
    wall s …) and the artifacts (tables, plot, summary, trajectory CSV and OEM files); it ends FINISHED,
    KILLED (Ctrl-C) or FAILED.  Returns the result and the written paths by kind.
    """
    from contextlib import nullcontext

    request.check()
    out = Path(output_dir) if output_dir is not None else default_output_dir(request.alpha)
    check_output_dir(out)
    prepared = prepare(request)
    params = {**asdict(request), "output": str(out), **{k: v for k, v in prepared.info.items()}}
    track = track and bool(prepared.cfg.mlflow.enabled)
    from amorgs import tracking

    bar = ProgressLine(request) if progress else None
    if track:
        context = tracking.standalone_run(f"design alpha={alpha_label(request.alpha)}", DESIGN_EXPERIMENT,
                                          store_dir=store_dir, uri=prepared.cfg.mlflow.tracking_uri,
                                          tags={"rule": "design", "wildcard.alpha": alpha_label(request.alpha)})
    else:
        context = nullcontext(tracking.JobRun(Path(store_dir)))
    try:
        with context as run:
            run.log_params(params)

            def on_round(state: dict) -> None:
                run.log_metrics({k: state[k] for k in ("found", "starts", "cpu_s", "wall_s")}, step=state["round"])
                if bar is not None:
                    bar(state)

            result = design(request, on_round, prepared)
            if bar is not None:
                bar.close()
                bar = None
            paths = write_outputs(result, out)
            summary = result.summary()
            run.log_metrics({k: float(v) for k, v in summary.items()
                             if isinstance(v, (int, float)) and not isinstance(v, bool) and k != "request"
                             and math.isfinite(float(v))})
            run.log_metrics({"complete": float(result.found >= request.n)})
            for kind, files in paths.items():
                for path in files:
                    run.log_artifact(path, kind)
    finally:
        if bar is not None:
            bar.close()
    return result, paths
