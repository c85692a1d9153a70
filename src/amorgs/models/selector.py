"""The transfer selector (issue 38 §2): which known solutions will transfer to a new α, and at what cost.

Reuse solves the high-quality solutions of the nearest training α at the new α, in random order; its failed
starts (mostly 1000-iteration stops) cost 6–57 % of its iterations on the frontier, and they are predictable
from what is known before solving (the retrieved solution's time of flight above all).  The selector learns that
from the transfer data (:mod:`amorgs.steps.transfer`: solutions of one training α solved at another):

* :func:`transfer_features` — what is known of a candidate before solving it: the source and target α (N),
  their gap (absolute, relative, signed, log ratio), the source solution's times τ_s, τ_i, τ_f and total time of
  flight (TU), its final fuel m_f (kg), and its throttle profile (mean ρ, fractions of full and zero thrust);
* :class:`TransferSelector` — two gradient-boosted tree ensembles (scikit-learn's
  ``HistGradientBoostingClassifier`` / ``…Regressor``: tabular data of a few thousand rows, thresholds on time
  of flight and gap that trees find without feature scaling, deterministic with a seed, seconds to train on a
  CPU): P(high quality) — converged with m_f ≥ β — and the expected IPOPT iterations (fitted on log(1 + k));
  the score of a candidate is its predicted iterations per high-quality solution, E[k] / P(hq);
* :class:`SelectorSampler` (arm ``selector``) — candidates are the high-quality solutions of *all* training α,
  not only the nearest; they are solved in order of score, without replacement, skipping a candidate whose
  times lie within η (Eq. 12's distance on (τ_s/40, τ_i/15, τ_f/15)) of one already chosen — a proxy of its
  landing basin, so that a designer gets different trajectories — until the distinct ones are used up, then
  the skipped ones in score order;
* :class:`SampledSelectorSampler` (arm ``selector_sampled``, issue 41) — the same candidates in a random order
  that favours the same ones (Plackett–Luce with weights 1 / score, drawn with the caller's ``rng``): a global
  search needs independent searches, and the ``selector`` arm's single ranking makes every search the same;
* :class:`SelectedProposalSampler` (arm ``amorgs_selected``, issue 38 §3) — selection on top of generation:
  ``oversample`` × n proposals of a generator (AmorGS) at the target α, the n that the same selector ranks best
  (the same :func:`selection_order`) solved.  A proposal is a guess made *for* the target α, so it is scored as a
  warm start from the target α itself (gap 0); the transfer data hold only pairs of distinct α, so the trees
  answer for gap 0 as for their smallest gap — what they rank on is the proposal's own times, fuel and throttle.

The decision-vector layout is the CR3BP's (``tau_s, tau_i, tau_f, m_f, theta_01, phi_01, rho_01, …``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from amorgs.analysis.structure_params import ETA, DiversityParams
from amorgs.problems.cr3bp import BETA_KG

#: The selector's file in a models directory (the train_selector step writes it there).
SELECTOR_FILE = "selector.joblib"
#: Names of the columns of :func:`transfer_features`, in order.
FEATURES = ("alpha_to", "alpha_from", "gap", "gap_relative", "gap_signed", "log_ratio", "tau_s", "tau_i", "tau_f",
            "tof", "m_f", "rho_mean", "rho_full", "rho_zero")
#: Scales of the times in Eq. 12's distance (TU): the upper bounds of τ_s, τ_i, τ_f.
TIME_SCALES = np.asarray(DiversityParams().time_scale, float)


def transfer_features(x: np.ndarray, alpha_from, alpha_to: float, names) -> np.ndarray:
    """The features (:data:`FEATURES`) of candidate solutions ``x`` (n, 3N+4; columns ``names``) of training α
    ``alpha_from`` (a number or one per row) as warm starts at ``alpha_to``; shape (n, len(FEATURES))."""
    x = np.atleast_2d(np.asarray(x, float))
    col = {name: i for i, name in enumerate(names)}
    rho = x[:, [i for name, i in col.items() if name.startswith("rho_")]]
    a_from = np.broadcast_to(np.asarray(alpha_from, float), (len(x),))
    a_to = np.full(len(x), float(alpha_to))
    tau = x[:, [col["tau_s"], col["tau_i"], col["tau_f"]]]
    return np.column_stack([
        a_to, a_from, np.abs(a_to - a_from), np.abs(a_to - a_from) / a_to, (a_to - a_from) / a_to,
        np.log(a_to / a_from), tau, tau.sum(axis=1), x[:, col["m_f"]], rho.mean(axis=1),
        (rho >= 0.99).mean(axis=1), (rho <= 0.01).mean(axis=1),
    ])


def transfer_labels(table: pd.DataFrame, beta_kg: float) -> tuple[np.ndarray, np.ndarray]:
    """(high quality — converged with m_f ≥ β —, IPOPT iterations) of every row of a transfer table."""
    hq = (table["converged"].astype(bool) & (table["m_f"] >= beta_kg)).to_numpy()
    return hq, table["iterations"].to_numpy(dtype=float)


def training_set(table: pd.DataFrame, names) -> np.ndarray:
    """The features of every row of a transfer table (its guesses are the source solutions), in row order."""
    out = np.empty((len(table), len(FEATURES)))
    x = table[[f"guess_{n}" for n in names]].to_numpy(dtype=float)
    source = table["source_alpha"].to_numpy(dtype=float)
    for alpha, idx in table.groupby("alpha").indices.items():
        out[idx] = transfer_features(x[idx], source[idx], float(alpha), names)
    return out


@dataclass
class TransferSelector:
    """P(high quality) and E[iterations] of a warm start from a known solution (module docstring).

    ``beta_kg``: the β it was trained for (kg).  ``seed``: of both ensembles.  With a single class in the training
    labels, the classifier is replaced by that class's frequency (a constant)."""

    beta_kg: float = BETA_KG
    seed: int = 0
    max_iter: int = 200
    classifier: object | None = field(default=None, repr=False)
    regressor: object | None = field(default=None, repr=False)
    constant_p: float | None = None
    rows: int = 0

    def fit(self, table: pd.DataFrame, names) -> TransferSelector:
        """Fit on a transfer table (rows of :mod:`amorgs.steps.transfer`); returns itself."""
        from sklearn.ensemble import HistGradientBoostingClassifier, HistGradientBoostingRegressor

        if not len(table):
            raise ValueError("the transfer table is empty: nothing to learn a selector from")
        order = table.sort_values(["alpha", "source_alpha", "seed", "start"], kind="stable")
        # rows sorted by their key: the fit does not depend on the order the shards were read in
        x, (hq, iterations) = training_set(order, names), transfer_labels(order, self.beta_kg)
        self.rows = len(order)
        if hq.all() or not hq.any():
            self.constant_p, self.classifier = float(hq.mean()), None
        else:
            self.constant_p = None
            self.classifier = HistGradientBoostingClassifier(max_iter=self.max_iter, random_state=self.seed).fit(x, hq)
        self.regressor = HistGradientBoostingRegressor(max_iter=self.max_iter, random_state=self.seed).fit(
            x, np.log1p(iterations))
        return self

    def predict(self, features: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(P(high quality), E[iterations]) of each row of ``features``."""
        if self.regressor is None:
            raise ValueError("the selector is not fitted")
        p = (np.full(len(features), self.constant_p) if self.classifier is None
             else self.classifier.predict_proba(features)[:, list(self.classifier.classes_).index(True)])
        return p, np.expm1(self.regressor.predict(features))

    def score(self, features: np.ndarray, floor: float = 1e-3) -> np.ndarray:
        """Predicted iterations per high-quality solution, E[k] / max(P(hq), ``floor``): lower is better."""
        p, k = self.predict(features)
        return k / np.maximum(p, floor)

    def save(self, path: str | Path) -> None:
        """Write the fitted selector (joblib; atomic)."""
        import joblib

        from amorgs.data.io import atomic_path

        with atomic_path(Path(path)) as tmp:
            joblib.dump(self, tmp)

    @staticmethod
    def load(path: str | Path) -> TransferSelector:
        """A selector written by :meth:`save` (``ValueError`` if the file holds something else)."""
        import joblib

        obj = joblib.load(path)
        if not isinstance(obj, TransferSelector):
            raise ValueError(f"{path}: not a transfer selector")
        return obj


def selection_order(scores: np.ndarray, times: np.ndarray, eta: float) -> np.ndarray:
    """Indices of candidates in the order the selector solves them: ascending score, a candidate whose scaled
    times ``times / TIME_SCALES`` lie within ``eta`` of one already chosen deferred, and the deferred ones last
    (in score order)."""
    order = np.argsort(scores, kind="stable")
    scaled = np.asarray(times, float) / TIME_SCALES
    chosen: list[int] = []
    deferred: list[int] = []
    for i in order:
        if chosen and np.min(np.linalg.norm(scaled[chosen] - scaled[i], axis=1)) <= eta:
            deferred.append(int(i))
        else:
            chosen.append(int(i))
    return np.array(chosen + deferred, dtype=int)


class SelectorSampler:
    """Arm ``selector``: the high-quality solutions of every training α, in the order :class:`TransferSelector`
    ranks them at the target α (:func:`selection_order`); draws beyond the candidates repeat the order.  ``rng``
    is not used: the order is the selector's (the cells of every model seed are slices of it, like reuse's)."""

    name = "selector"

    def __init__(self, problem, high_quality: pd.DataFrame, train_alphas, selector: TransferSelector,
                 eta: float = ETA):
        from amorgs.models.baselines import training_rows

        self.problem = problem
        self.by_alpha = training_rows(high_quality, train_alphas, problem.variable_names)
        self.selector, self.eta = selector, float(eta)
        self._candidates: dict[float, tuple[np.ndarray, np.ndarray, np.ndarray]] = {}
        self._ranked: dict[float, tuple[np.ndarray, np.ndarray]] = {}

    @classmethod
    def build(cls, problem, inputs) -> SelectorSampler:
        return cls(problem, inputs.high_quality, inputs.train_alphas, inputs.models["selector"])

    def candidates(self, alpha: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(candidates (m, 3N+4), their scores at ``alpha``, their times (m, 3) in TU), in the training table's
        order; computed once per α."""
        key = float(alpha)
        if key not in self._candidates:
            names = self.problem.variable_names
            x = np.vstack(list(self.by_alpha.values()))
            source = np.concatenate([np.full(len(v), a) for a, v in self.by_alpha.items()])
            scores = self.selector.score(transfer_features(x, source, key, names))
            times = x[:, [list(names).index(n) for n in ("tau_s", "tau_i", "tau_f")]]
            self._candidates[key] = (x, scores, times)
        return self._candidates[key]

    def ranked(self, alpha: float) -> tuple[np.ndarray, np.ndarray]:
        """(candidates in selection order (m, 3N+4), their scores) at ``alpha``; computed once per α."""
        key = float(alpha)
        if key not in self._ranked:
            x, scores, times = self.candidates(key)
            order = selection_order(scores, times, self.eta)
            self._ranked[key] = (x[order], scores[order])
        return self._ranked[key]

    def sample(self, alpha: float, n: int, rng: np.random.Generator) -> np.ndarray:
        rows, _ = self.ranked(alpha)
        return _repeated(rows, n, self.problem)


class SampledSelectorSampler(SelectorSampler):
    """Arm ``selector_sampled``: the ``selector`` arm's candidates in a random order drawn with ``rng`` — a
    Plackett–Luce order with weights 1 / score (a candidate's predicted high-quality solutions per IPOPT
    iteration), drawn by the Gumbel-top-k trick (Kool, van Hoof & Welling 2019: sort log w + Gumbel noise) —
    then :func:`selection_order`'s η-deferral.  The ``selector`` arm's order is one deterministic ranking, so
    every search of a global search (and every model seed's cell) starts from the same candidates; here each
    call of :meth:`sample` is its own order, which still puts cheap, likely transfers first on average (the
    first candidate is candidate i with probability w_i / Σ w).  Draws beyond the candidates repeat that call's
    order.  Scores below one iteration count as one."""

    name = "selector_sampled"

    def sample(self, alpha: float, n: int, rng: np.random.Generator) -> np.ndarray:
        x, scores, times = self.candidates(alpha)
        keys = np.log(np.maximum(scores, 1.0)) - rng.gumbel(size=len(scores))  # ascending: −(log w + G)
        return _repeated(x[selection_order(keys, times, self.eta)], n, self.problem)


def _repeated(rows: np.ndarray, n: int, problem) -> np.ndarray:
    """The first ``n`` of ``rows`` repeated as often as needed, made valid for ``problem``."""
    from amorgs.models.baselines import make_valid

    repeats = math.ceil(n / len(rows)) if len(rows) else 0
    return make_valid(np.tile(rows, (max(repeats, 1), 1))[:n], problem)


class SelectedProposalSampler:
    """Selection on top of generation (module docstring): ``oversample`` × n proposals of ``generator`` drawn
    with ``rng``, scored by ``selector`` at gap 0, the first n of :func:`selection_order` returned in that order
    (the solver takes them best first).  Not pooled: each cell draws its own proposals."""

    def __init__(self, problem, generator, selector: TransferSelector, oversample: int = 5, eta: float = ETA,
                 name: str = "amorgs_selected"):
        if oversample < 1:
            raise ValueError(f"oversample must be ≥ 1, got {oversample}")
        self.problem, self.generator, self.selector = problem, generator, selector
        self.oversample, self.eta, self.name = int(oversample), float(eta), name

    @classmethod
    def build_amorgs(cls, problem, inputs) -> SelectedProposalSampler:
        """Arm ``amorgs_selected``: AmorGS's proposals (CVAE time & mass, LSTM controls), ranked."""
        from amorgs.models.samplers import AmorGSSampler

        return cls(problem, AmorGSSampler.build(problem, inputs), inputs.models["selector"],
                   inputs.selection_oversample, name="amorgs_selected")

    def ranked(self, alpha: float, n: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
        """(all ``oversample`` × n proposals in selection order, their scores)."""
        names = self.problem.variable_names
        proposals = self.generator.sample(alpha, self.oversample * n, rng)
        scores = self.selector.score(transfer_features(proposals, float(alpha), float(alpha), names))
        times = proposals[:, [list(names).index(v) for v in ("tau_s", "tau_i", "tau_f")]]
        order = selection_order(scores, times, self.eta)
        return proposals[order], scores[order]

    def sample(self, alpha: float, n: int, rng: np.random.Generator) -> np.ndarray:
        if n <= 0:
            return np.empty((0, len(self.problem.variable_names)))
        return self.ranked(alpha, n, rng)[0][:n]
