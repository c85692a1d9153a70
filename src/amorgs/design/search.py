"""The search of ``amorgs design``: warm starts at one α solved in rounds until N good, η-diverse solutions.

:func:`design` draws warm starts from a sampler (default ``auto``: the arm the committed frontier measured best
at the requested α's distance from the library's α, :func:`resolve_sampler` — reuse of the nearest library α's
high-quality solutions unless a learned arm beat it significantly there), solves
them with the workflow's solver and options (``problems.cr3bp.solver`` of the config) through the multistart
pool, in **rounds** of ``round_size`` starts, until ``n`` solutions are

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

Start-up (:func:`prepare`): every option and the presence of every input are checked first; then the solver
workers start (:class:`~amorgs.solvers.multistart.WorkerPool`: spawn, imports, the compiled NLP loaded from
the cache) while the library is read and the sampler built, and the same workers serve every round.  The
model-free samplers import no torch.  Nothing of this changes a guess or a solve.
"""

from __future__ import annotations

import math
import resource
import time
from collections.abc import Callable
from contextlib import ExitStack
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import pandas as pd

from amorgs.ablation.arms import REUSE_ARM
from amorgs.alphas import alpha_label
from amorgs.analysis.structure_params import ETA
from amorgs.config import ConfigError
from amorgs.errors import InputError
from amorgs.problems.cr3bp import BETA_KG
from amorgs.solvers.basin_hopping import HopSettings
from amorgs.solvers.options import IpoptOptions

if TYPE_CHECKING:
    from amorgs.solvers.multistart import WorkerPool

PROBLEM = "cr3bp"
#: The hop defaults of ``--strategy mbh``.
HOPS = HopSettings()
#: Defaults of ``amorgs design`` (see :class:`DesignRequest`).
#: ``--sampler auto``: the arm the frontier recommends (:func:`resolve_sampler`).
AUTO_SAMPLER = "auto"
DEFAULT_SAMPLER = AUTO_SAMPLER
#: The committed frontier tables (``amorgs frontier``) that ``auto`` follows: the frontier of the five arms
#: (issue 21) and the transfer selector's folds (issue 38).
DEFAULT_FRONTIERS = ("reference/frontier/frontier.csv", "reference/selector-frontier/frontier.csv")
#: ``--strategy auto``: basin hopping where the committed global-search study shows it faster to the funnel bottom
#: (:func:`resolve_strategy`); the studies it reads (``amorgs global-search --dest``: events.parquet, study.json,
#: best_known.csv) and the target it judges by, within this many kg of the best known m_f.
AUTO_STRATEGY = "auto"
STRATEGIES = (AUTO_STRATEGY, "multistart", "mbh")
DEFAULT_GLOBAL_SEARCH = "reference/global-search"
STRATEGY_DELTA_KG = 2.0
DEFAULT_LIBRARY_DIR = "data/library"
DEFAULT_MODELS_DIR = "data/models/cr3bp"
DEFAULT_CONFIG = "config/default.yaml"
#: Cached high-quality library tables kept (:func:`library_high_quality`, ≈ 10 MB each).
HQ_CACHE_ENTRIES = 4


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
    strategy: ``multistart`` (every start from the sampler) or ``mbh`` (monotonic basin hopping: each of the
    ``round_size`` slots of a round is a chain that hops from its best solution and restarts from the sampler
    after ``patience`` hops that do not improve it; :mod:`amorgs.solvers.basin_hopping`) — which spends the whole
    budget (``max_starts``, ``max_cpu_s``) looking for the best, then returns the n best η-diverse.   hop, hop_scale,
    hop_shape, patience, hop_variables: the hops of ``mbh`` (distribution, step per unit draw as a fraction of the
    box width, Pareto tail, misses before a restart, the names of the variables a hop moves — empty: all).
    """

    alpha: float
    n: int
    sampler: str = DEFAULT_SAMPLER
    beta_kg: float = BETA_KG
    eta: float = ETA
    seed: int = 0
    workers: int = 2
    round_size: int = 16
    max_starts: int = 400
    max_cpu_s: float = 3600.0
    library_dir: str = DEFAULT_LIBRARY_DIR
    models_dir: str = DEFAULT_MODELS_DIR
    config: str = DEFAULT_CONFIG
    frontier: tuple[str, ...] | str = DEFAULT_FRONTIERS  # one table or several, read together
    strategy: str = "multistart"
    hop: str = HOPS.distribution
    hop_scale: float = HOPS.scale
    hop_shape: float = HOPS.shape
    patience: int = HOPS.patience
    hop_variables: tuple[str, ...] = HOPS.variables

    def hops(self):
        """The :class:`~amorgs.solvers.basin_hopping.HopSettings` of ``mbh``."""
        from amorgs.solvers.basin_hopping import HopSettings

        return HopSettings(distribution=self.hop, scale=self.hop_scale, shape=self.hop_shape, patience=self.patience,
                           variables=tuple(self.hop_variables))

    def check(self) -> None:
        """One :class:`ConfigError` naming the option for every out-of-range value (β against the problem's
        bound on m_f: :func:`check_beta`, once the problem is loaded)."""
        from amorgs.ablation.arms import SAMPLER_NAMES
        from amorgs.problems import get_family

        lo, hi = get_family(PROBLEM).alpha_range
        if not (isinstance(self.alpha, (int, float)) and math.isfinite(self.alpha) and lo <= self.alpha <= hi):
            raise ConfigError(f"--alpha {self.alpha}: the maximum thrust α must lie in [{lo}, {hi}] N")
        if self.n < 1:
            raise ConfigError(f"-n {self.n}: ask for at least 1 solution")
        if self.sampler != AUTO_SAMPLER and self.sampler not in SAMPLER_NAMES:
            raise ConfigError(f"--sampler {self.sampler!r}: choose {AUTO_SAMPLER} or one of {', '.join(SAMPLER_NAMES)}")
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
        if self.strategy not in STRATEGIES:
            raise ConfigError(f"--strategy {self.strategy!r}: choose {', '.join(STRATEGIES)}")
        try:
            hops = self.hops()
        except ValueError as exc:
            raise ConfigError(f"--hop/--hop-scale/--hop-shape/--patience/--hop-variables: {exc}") from None
        if hops.variables:
            from amorgs.problems.cr3bp.transcription import variable_names

            try:
                hops.movable(variable_names())
            except ValueError as exc:
                raise ConfigError(f"--hop-variables: {exc}") from None


@dataclass
class DesignResult:
    """Outcome of :func:`design`.

    ``selected``: the chosen solutions (≤ n rows, solution-table columns + ``rank``, best m_f first);
    ``solves``: every solve (solution-table columns, ``shard`` = round index, ``high_quality`` and
    ``selected`` flags); ``found``: size of the η-diverse high-quality set; ``stop_reason``: ``found``,
    ``max_starts`` or ``max_cpu_s``; ``cpu_s``: CPU seconds of this process and its solver workers;
    ``solver_cpu_s``: the IPOPT CPU seconds summed over solves; ``wall_s``: wall seconds; ``info``: the
    sampler's provenance (nearest training α, seed rows) and the solver options; ``best_known``: the best-known
    record's entry at α (``m_f_kg``, ``x`` in the stored layout, ``verify_defect``, ``source``) where the record
    holds the best known m_f at α — a trajectory the search may not have found — else ``None``.
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
    best_known: dict | None = None

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


def best_known(library_dir: str | Path, alpha: float, solves: pd.DataFrame,
               record_path: str | Path | None = None) -> tuple[dict, dict | None]:
    """The best verified m_f known at ``alpha`` (kg) and where it is held: the best-known record
    (:mod:`amorgs.data.best_known`, ``data/best_known/cr3bp.json`` unless ``record_path``; its entry at ``alpha``
    or one lifted there), the library's per-α best (its manifest, where ``alpha`` is a library α) or this search's
    converged solves, whichever is highest (the record on a tie).  Returns ``({"best_known_m_f_kg",
    "best_known_source"}, entry)``: ``entry`` is the record's entry at ``alpha`` (its trajectory ``x`` in the
    stored layout, ``source`` provenance) where the record holds the best known, else ``None``."""
    from amorgs.data import best_known as bk
    from amorgs.data.library import read_manifest

    manifest = read_manifest(library_dir, PROBLEM) or {}
    library = [-float(e["best_objective"]) for e in manifest.get("per_alpha", [])
               if alpha_label(e["alpha"]) == alpha_label(alpha) and e.get("best_objective") is not None]
    conv = solves[solves["converged"].astype(bool)] if len(solves) else solves
    try:
        entry = bk.best_entry_lifted(bk.read_record(record_path or bk.DEFAULT_PATH), alpha)
    except InputError:  # a damaged record must not lose a finished search: the library and the search still count
        entry = None
    candidates = {"best-known record": float(entry["m_f_kg"]) if entry else math.nan,
                  "library": library[0] if library else math.nan,
                  "this search": float(conv["m_f"].max()) if len(conv) else math.nan}
    known = {k: v for k, v in candidates.items() if math.isfinite(v)}
    if not known:
        return {"best_known_m_f_kg": None, "best_known_source": "none"}, None
    source = max(known, key=known.get)
    return ({"best_known_m_f_kg": known[source], "best_known_source": source},
            entry if source == "best-known record" else None)


def _cpu_seconds() -> float:
    """CPU seconds of this process plus its terminated (reaped) children — the solver workers once closed."""
    children = resource.getrusage(resource.RUSAGE_CHILDREN)
    return time.process_time() + children.ru_utime + children.ru_stime


def _library_not_found(library_dir: str | Path) -> InputError:
    from amorgs.data.library import MANIFEST

    return InputError(f"{Path(library_dir) / PROBLEM / MANIFEST}: solution library not found (--library-dir {library_dir})")


def library_high_quality(library_dir: str | Path, train_alphas, min_final_mass_kg: float,
                         cache: bool = True) -> pd.DataFrame:
    """The library's high-quality rows (converged, m_f ≥ β) at the training α; :class:`InputError` naming the
    manifest if the library is missing or holds none, or the file if one differs from the manifest or is not
    listed in it (:func:`~amorgs.data.library.verify_library`, always run first).

    ``cache``: the table is kept under the compile cache (:func:`~amorgs.solvers.codegen.cache_dir`) by
    :func:`hq_cache_key` and read from there next time (≈ 0.1 s instead of ≈ 3–5 s for 242 files): the key
    holds the manifest, which names every file's SHA-256, so a verified library with the same manifest is the
    same table.  The newest :data:`HQ_CACHE_ENTRIES` entries are kept; an unreadable or unwritable cache is
    ignored.
    """
    from amorgs.data.io import atomic_path
    from amorgs.problems.cr3bp import Cr3bpFilter
    from amorgs.data.library import MANIFEST, read_library, verify_library
    from amorgs.solvers.codegen import cache_dir

    manifest = Path(library_dir) / PROBLEM / MANIFEST
    if verify_library(library_dir, PROBLEM) is None:
        raise _library_not_found(library_dir)
    cached = cache_dir() / f"design-library-hq-{hq_cache_key(manifest, train_alphas, min_final_mass_kg)}.parquet"
    if cache and cached.is_file():
        try:
            return pd.read_parquet(cached)
        except Exception:  # noqa: BLE001 — a damaged cache entry: read the library again, below
            pass
    frames = [read_library(library_dir, PROBLEM, alpha_label(a)) for a in train_alphas]
    frames = [f for f in frames if len(f)]
    if not frames:
        raise InputError(f"{manifest}: the library holds no solutions at the training α {list(train_alphas)}")
    hq = Cr3bpFilter(min_final_mass_kg=min_final_mass_kg).select(pd.concat(frames, ignore_index=True))
    if not len(hq):
        raise InputError(f"{manifest}: no library solution at the training α has m_f ≥ {min_final_mass_kg} kg")
    if cache:
        try:
            with atomic_path(cached) as tmp:
                hq.to_parquet(tmp)
            entries = sorted(cached.parent.glob("design-library-hq-*.parquet"), key=lambda p: p.stat().st_mtime)
            for old in entries[:-HQ_CACHE_ENTRIES]:  # earlier libraries, betas, code: the newest few stay
                old.unlink(missing_ok=True)
        except OSError:
            pass
    return hq


def hq_cache_key(manifest: Path, train_alphas, min_final_mass_kg: float) -> str:
    """Key of a cached :func:`library_high_quality` table: SHA-256 (16 hex digits) of the manifest's bytes, the
    training α labels, β (kg) and the code that reads and filters the library (this module and
    :mod:`amorgs.data.library`, :mod:`~amorgs.data.tables` and the quality filter's :mod:`amorgs.problems.base`,
    :mod:`amorgs.problems.cr3bp`)."""
    import hashlib
    import json

    from amorgs.data import library, tables
    from amorgs.problems import base, cr3bp

    digest = hashlib.sha256(manifest.read_bytes())
    digest.update(json.dumps({"train": sorted(alpha_label(a) for a in train_alphas),
                              "beta_kg": float(min_final_mass_kg)}).encode())
    for module in (library, tables, base, cr3bp):
        digest.update(Path(module.__file__).read_bytes())
    digest.update(Path(__file__).read_bytes())
    return digest.hexdigest()[:16]


def resolve_sampler(request: DesignRequest, cfg) -> tuple[DesignRequest, str]:
    """``request`` with ``--sampler auto`` replaced by the arm the committed frontier tables
    (``request.frontier``, read together) recommend at ``request.alpha`` —
    :func:`~amorgs.ablation.frontier.choose_sampler` with the config's training α (the library α the samplers
    draw from) and the arms whose checkpoints (and, for a transfer arm, selector) ``request.models_dir`` holds —
    and one line saying which and why, naming the evidence; any other sampler is kept.  A default table that is
    missing is skipped (none at all: reuse); a ``--frontier`` file named but missing is refused
    (``InputError``).  With several tables each row's run is prefixed by its table's folder, so the reason names
    where a measurement lies."""
    from dataclasses import replace

    if request.sampler != AUTO_SAMPLER:
        return request, f"sampler {request.sampler} (--sampler)"
    from amorgs.ablation.arms import ARMS
    from amorgs.ablation.frontier import choose_sampler
    from amorgs.models.names import CHECKPOINTS
    from amorgs.models.selector import SELECTOR_FILE

    named = (request.frontier,) if isinstance(request.frontier, str) else tuple(request.frontier)
    defaults = {Path(p) for p in DEFAULT_FRONTIERS}
    for name in named:
        if not Path(name).is_file() and Path(name) not in defaults:
            raise InputError(f"--frontier {name}: no such file (a frontier table of `amorgs frontier`)")
    paths = [Path(p) for p in named if Path(p).is_file()]
    if not paths:
        return (replace(request, sampler=REUSE_ARM),
                f"sampler {REUSE_ARM} (--sampler auto): no frontier table at {', '.join(named)}, reuse by default")
    models = Path(request.models_dir)
    available = tuple(a.name for a in ARMS if all((models / CHECKPOINTS[m]).is_file() for m in a.models)
                      and (not a.transfer or (models / SELECTOR_FILE).is_file()))
    tables = []
    for path in paths:
        try:
            table = pd.read_csv(path)
            if len(paths) > 1:
                table["run"] = path.parent.name + "/" + table["run"].astype(str)
        except (KeyError, ValueError, OSError, pd.errors.ParserError) as exc:
            raise InputError(f"{path}: not a frontier table of `amorgs frontier` ({exc})") from None
        tables.append(table)
    try:
        choice = choose_sampler(pd.concat(tables, ignore_index=True), request.alpha,
                                cfg.problems.cr3bp.alphas.train_values(), available=available)
    except (KeyError, ValueError) as exc:
        raise InputError(f"{', '.join(map(str, paths))}: not a frontier table of `amorgs frontier` ({exc})") from None
    return replace(request, sampler=choice.sampler), f"sampler {choice.sampler} (--sampler auto): {choice.reason}"


def resolve_strategy(request: DesignRequest, studies: str | Path = DEFAULT_GLOBAL_SEARCH,
                     record: str | Path = "data/best_known/cr3bp.json") -> tuple[DesignRequest, str]:
    """``request`` with ``--strategy auto`` replaced by what the committed global-search study nearest in α says
    (``studies``/alpha=*/: events.parquet, study.json, best_known.csv), and one line saying which and why: ``mbh``
    if monotonic basin hopping from the request's sampler (its resolved arm, or ``uniform`` where the study has
    no cell of it) reached within :data:`STRATEGY_DELTA_KG` of the best known m_f (the study's, or the best-known
    ``record``'s at its α where that is higher: :func:`amorgs.data.best_known.lift`) in significantly fewer IPOPT
    iterations than multi-start from the same sampler (ERT ratio's bootstrap 95 % interval below 1, the study's
    own budget, seed and target; or MBH got there and multi-start never did), ``multistart`` otherwise or without
    a study.  Any other strategy is kept."""
    from dataclasses import replace

    if request.strategy != AUTO_STRATEGY:
        return request, f"strategy {request.strategy} (--strategy)"
    from amorgs.ablation.global_search import ert_ratios, hit_iterations
    from amorgs.data.io import read_json

    found = [d for d in sorted(Path(studies).glob("alpha=*"))
             if all((d / n).is_file() for n in ("events.parquet", "study.json", "best_known.csv"))]
    if not found:
        return (replace(request, strategy="multistart"),
                f"strategy multistart (--strategy auto): no global-search study under {studies}, multi-start by default")
    settings = {d: read_json(d / "study.json") for d in found}
    where = min(found, key=lambda d: (abs(settings[d]["alpha"] - request.alpha), str(d)))
    study = settings[where]
    events = pd.read_parquet(where / "events.parquet")
    sampler = request.sampler if request.sampler in set(events["sampler"]) else "uniform"
    cells = set(zip(events["strategy"], events["sampler"]))
    head = f"at α = {study['alpha']:g} ({where})"
    if not {("multistart", sampler), ("mbh", sampler)} <= cells:
        return (replace(request, strategy="multistart"),
                f"strategy multistart (--strategy auto): {head} holds no multistart and mbh cells of {sampler}")
    from amorgs.data import best_known as bk

    best = -float(pd.read_csv(where / "best_known.csv")["m_f"].iloc[0])
    known = -bk.best_m_f_lifted(bk.read_record(record), study["alpha"])
    if known < best:  # NaN (no entry) compares False
        best = known
    # multi-start ÷ MBH, so that a multi-start that never got there (∞) still answers: MBH is significantly faster
    # when this ratio's interval lies above 1; it is reported the other way round (MBH ÷ multi-start, the
    # percentile interval's ends inverted, 1/∞ = 0)
    ratios = ert_ratios(events[events["sampler"] == sampler], best, deltas=(STRATEGY_DELTA_KG,),
                        baseline=("mbh", sampler), seed=study["seed"], budget=study["budget"])
    row = ratios[ratios["strategy"] == "multistart"].iloc[0]
    counts = {strategy: int(np.isfinite(hit_iterations(cell, best + STRATEGY_DELTA_KG, study["budget"])).sum())
              for strategy, cell in events[events["sampler"] == sampler].groupby("strategy")}
    searches = f"{study['searches']} searches of {study['budget']} IPOPT iterations each"
    if not counts["mbh"]:
        evidence = (f"{head}, MBH × {sampler} never came within {STRATEGY_DELTA_KG:g} kg of the best known m_f "
                    f"({searches}; multi-start from it in {counts['multistart']})")
        faster = False
    elif not counts["multistart"]:
        evidence = (f"{head}, MBH × {sampler} came within {STRATEGY_DELTA_KG:g} kg of the best known m_f in "
                    f"{counts['mbh']} of {searches}, multi-start from the same sampler in none")
        faster = True
    else:
        inverse = [0.0 if v == math.inf else math.inf if v == 0 else 1 / v
                   for v in (row["ratio"], row["ratio_hi"], row["ratio_lo"])]
        evidence = (f"{head}, MBH × {sampler} reached within {STRATEGY_DELTA_KG:g} kg of the best known m_f in "
                    f"{inverse[0]:.2f}× multi-start's iterations (95 % {inverse[1]:.2f}–{inverse[2]:.2f}, {searches}; "
                    f"{counts['mbh']} against {counts['multistart']} searches got there)")
        faster = bool(row["ratio_lo"] > 1)
    if faster:
        return replace(request, strategy="mbh"), f"strategy mbh (--strategy auto): {evidence}"
    return (replace(request, strategy="multistart"),
            f"strategy multistart (--strategy auto): {evidence} — not significantly faster (MBH does find more "
            "near-best alternatives: --strategy mbh)")


def check_inputs_present(request: DesignRequest) -> None:
    """:class:`InputError` naming the file if an input of the requested sampler is missing: a checkpoint it
    loads, or the library's manifest (a library with files but no manifest is named as such).  Only presence
    (cheap, before any worker starts); :func:`make_sampler` verifies the contents."""
    from amorgs.ablation.arms import get_arm
    from amorgs.data.library import MANIFEST, verify_library
    from amorgs.models.names import CHECKPOINTS

    arm = get_arm(request.sampler)
    for model in arm.models:
        path = Path(request.models_dir) / CHECKPOINTS[model]
        if not path.is_file():
            raise InputError(f"{path}: model checkpoint not found (--models-dir {request.models_dir}; "
                             f"sampler {request.sampler} needs {', '.join(arm.models)})")
    if arm.transfer:
        from amorgs.models.selector import SELECTOR_FILE

        path = Path(request.models_dir) / SELECTOR_FILE
        if not path.is_file():
            raise InputError(f"{path}: transfer selector not found (--models-dir {request.models_dir}; sampler "
                             f"{request.sampler} needs a run's selector, e.g. --models-dir results/cr3bp/models)")
    if arm.high_quality and not (Path(request.library_dir) / PROBLEM / MANIFEST).is_file():
        verify_library(request.library_dir, PROBLEM)  # files without a manifest: named
        raise _library_not_found(request.library_dir)


def make_sampler(request: DesignRequest, cfg, problem):
    """The requested sampler and a provenance dict; missing inputs raise :class:`InputError` naming the file."""
    from amorgs.ablation.arms import build_sampler, get_arm
    from amorgs.models.baselines import nearest_training_alpha
    from amorgs.models.names import CHECKPOINTS

    check_inputs_present(request)
    arm = get_arm(request.sampler)
    section = cfg.problems.cr3bp
    train = tuple(section.alphas.train_values())
    info: dict = {"sampler": request.sampler}
    from amorgs.models.selector import SELECTOR_FILE

    # the selector lies beside the checkpoints; both are checked against a shipped folder's manifest
    needed = tuple(CHECKPOINTS[m] for m in arm.models) + ((SELECTOR_FILE,) if arm.transfer else ())
    models_dir = Path(request.models_dir) if needed else None
    if needed:
        from amorgs.models.shipped import verify_models

        shipped = verify_models(models_dir, needed)
        if shipped is not None:
            # a selector-only arm is judged by the selector's own record (it is trained on its own run's library)
            record = shipped if arm.models else shipped.get("selector", shipped)
            info["models_git_commit"] = record["git_commit"]
            note = stale_models_note(record, request.library_dir, models_dir)
            if note:
                info["models_note"] = note
    hq = None
    if arm.high_quality:
        hq = library_high_quality(request.library_dir, train, section.filter.min_final_mass_kg)
        info["library_seed_rows"] = int(len(hq))
    try:
        sampler = build_sampler(request.sampler, problem, models_dir=models_dir, high_quality=hq, train_alphas=train,
                                perturbation_scale=cfg.ablation.perturbation_scale,
                                gmm_components=cfg.ablation.gmm_components,
                                selection_oversample=cfg.ablation.selection_oversample)
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


def stale_models_note(shipped: dict, library_dir: str | Path, models_dir: Path) -> str:
    """A line when the shipped models (their provenance: ``library_rows``, ``library_manifest_sha256``) were
    trained on another library than ``library_dir`` holds today; empty when it is the same one."""
    from amorgs.data.library import MANIFEST, read_manifest, sha256_file

    manifest = Path(library_dir) / PROBLEM / MANIFEST
    held = read_manifest(library_dir, PROBLEM) if manifest.is_file() else None
    if held is None or shipped.get("library_manifest_sha256") in (None, sha256_file(manifest)):
        return ""
    return (f"the models in {models_dir} were trained on an older library ({shipped.get('library_rows')} solves) "
            f"than {library_dir} holds today ({held['totals']['rows']} solves): retrain them on it "
            "(the workflow's train_cr3bp, then amorgs models-export) to learn from every solution")


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


def pool_size(request: DesignRequest) -> int:
    """Solver processes of a search: ``workers``, but never more than the starts of one round."""
    return max(1, min(request.workers, request.round_size, request.max_starts))


@dataclass
class Prepared:
    """Everything :func:`design` needs before the first solve: the config, the solver options, the problem, the
    sampler with its provenance (``info``) and the solver workers, already starting (``pool``, or None: the
    search starts them).  A context manager: leaving it (or :meth:`close`) ends the workers."""

    cfg: object
    solver_options: IpoptOptions
    problem: object
    sampler: object
    info: dict
    pool: WorkerPool | None = None

    def close(self) -> None:
        if self.pool is not None:
            self.pool.close()

    def __enter__(self) -> Prepared:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def prepare(request: DesignRequest, start_workers: bool = True) -> Prepared:
    """Check the request and load its inputs (config, library or models); bad options raise
    :class:`ConfigError`, missing or unreadable files :class:`InputError` — before any solve.

    ``start_workers``: once every option is checked and every input found, start the solver workers, which
    build their solvers while the library is read and the sampler built (they end if a later step fails)."""
    from amorgs.config import load_config
    from amorgs.problems import get_problem
    from amorgs.solvers.multistart import WorkerPool

    request.check()
    if not Path(request.config).is_file():
        raise InputError(f"{request.config}: config file not found (--config)")
    cfg = load_config(request.config)
    request, choice = resolve_sampler(request, cfg)
    request, strategy_choice = resolve_strategy(request)
    problem = get_problem(PROBLEM)
    check_beta(request.beta_kg, problem)
    check_inputs_present(request)
    solver_options = cfg.problems.cr3bp.solver
    pool = WorkerPool(problem, pool_size(request), solver_options, alpha=request.alpha) if start_workers else None
    try:
        sampler, info = make_sampler(request, cfg, problem)
    except BaseException:
        if pool is not None:
            pool.close()
        raise
    info["solver_options"] = solver_options.to_dict()
    info["sampler_choice"] = choice
    info["strategy"], info["strategy_choice"] = request.strategy, strategy_choice
    return Prepared(cfg, solver_options, problem, sampler, info, pool)


def design(request: DesignRequest, progress: Callable[[dict], None] | None = None,
           prepared: Prepared | None = None, started: Callable[[], None] | None = None) -> DesignResult:
    """Run the search (module docstring); ``progress`` is called after every round with the running counts
    (``found``, ``n``, ``starts``, ``max_starts``, ``cpu_s``, ``max_cpu_s``, ``wall_s``, ``round``), ``started``
    once, as soon as the first guess is with a solver worker.  ``prepared``: the result of :func:`prepare` for
    this request (made here if not given); its workers serve every round and end with the search."""
    from amorgs.data.tables import validate_solutions
    from amorgs.problems.cr3bp import Cr3bpFilter
    from amorgs.solvers.multistart import WorkerPool, records_table

    wall0, cpu0 = time.perf_counter(), _cpu_seconds()
    tables: list[pd.DataFrame] = []
    solves = pd.DataFrame()
    found, starts, rounds, selected = 0, 0, 0, pd.DataFrame()
    stop_reason = ""
    with ExitStack() as stack:
        if prepared is None:
            prepared = stack.enter_context(prepare(request))
        stack.callback(prepared.close)
        solver_options, problem, sampler = prepared.solver_options, prepared.problem, prepared.sampler
        pool = prepared.pool or stack.enter_context(WorkerPool(problem, pool_size(request), solver_options,
                                                               alpha=request.alpha))
        info = dict(prepared.info)
        if request.sampler == AUTO_SAMPLER or request.strategy == AUTO_STRATEGY:  # the result names what ran
            from dataclasses import replace

            request = replace(request, sampler=info["sampler"], strategy=info["strategy"])
        rng = np.random.default_rng(request.seed)
        chains = None
        if request.strategy == "mbh":
            from amorgs.solvers.basin_hopping import Chains

            chains = Chains(request.round_size, request.hops(), problem.variable_names)

        def cpu_s() -> float:  # this process, the workers that ended, and the live ones so far
            return _cpu_seconds() - cpu0 + pool.cpu_seconds()

        while True:
            if found >= request.n and chains is None:  # mbh searches its whole budget for the funnel bottom
                stop_reason = "found"
            elif starts >= request.max_starts:
                stop_reason = "max_starts"
            elif rounds and cpu_s() >= request.max_cpu_s:  # checked between rounds: the first always runs
                stop_reason = "max_cpu_s"
            if stop_reason:
                break
            size = min(request.round_size, request.max_starts - starts)
            if chains is None:
                guesses, kinds = sampler.sample(request.alpha, size, rng), ["start"] * size
            else:
                guesses, kinds = chains.propose(lambda m: sampler.sample(request.alpha, m, rng), problem.lower,
                                                problem.upper, rng, size)
            records, run_info = pool.solve(request.alpha, guesses, progress=False, started=started)
            started = None
            if chains is not None:
                chains.update(records, kinds)
            table = records_table(PROBLEM, request.alpha, request.seed, guesses, records, problem.variable_names,
                                  run_info["options_hash"])
            table["start"] += starts
            table.insert(int(table.columns.get_loc("seed")) + 1, "shard", rounds)
            table.insert(int(table.columns.get_loc("shard")) + 1, "kind", kinds)
            tables.append(table)
            starts += size
            rounds += 1
            solves = pd.concat(tables, ignore_index=True)
            hq = Cr3bpFilter(min_final_mass_kg=request.beta_kg).select(solves)
            found, selected = select_diverse(hq, request.eta, request.n)
            if progress is not None:
                progress({"round": rounds, "found": found, "n": request.n, "starts": starts,
                          "max_starts": request.max_starts, "cpu_s": cpu_s(),
                          "max_cpu_s": request.max_cpu_s, "wall_s": time.perf_counter() - wall0})

    if len(solves):
        validate_solutions(solves, problem.variable_names, where="design solves")
        keep = solves["converged"].astype(bool) & (solves["m_f"] >= request.beta_kg)
        solves["high_quality"] = keep.to_numpy()
        solves["selected"] = solves["start"].isin(selected["start"]) if len(selected) else False
    known, record_entry = best_known(request.library_dir, request.alpha, solves)
    info.update(known)
    if len(selected):  # how far each chosen trajectory is from the best known at this α (kg, ≥ 0)
        selected = selected.assign(below_best_known_kg=info["best_known_m_f_kg"] - selected["m_f"])
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
        best_known=record_entry,
    )

