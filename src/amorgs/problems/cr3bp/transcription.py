"""Forward–backward shooting transcription of the low-thrust transfer in CasADi (spec §5, paper Eq. 28–31).

Stored decision vector (64 entries for N = 20), in this order and these units::

    x = (τ_s, τ_i, τ_f, m_f, θ_1, φ_1, ρ_1, …, θ_N, φ_N, ρ_N)
        τ_* in TU, m_f in kg of fuel at the terminal state, θ ∈ [0, 2π], φ ∈ [−π/2, π/2], ρ ∈ [0, 1]

Forward arc: from ξ₀ coast τ_i, then thrust segments 1 … N/2 (each τ_s/N).  Backward arc: from
(ξ_f, m_f) coast τ_f backward, then segments N … N/2+1 backward.  The 7 match-point defects (position DU,
velocity VU, fuel tonnes) are the equality constraints; the objective is −m_f.

Internally the NLP variable ``w`` is this vector with m_f in tonnes (every state is O(1)), azimuths
unbounded (wrapped to [0, 2π) on the way out) — or, with ``controls = 'cartesian'``, with each (θ_k, φ_k, ρ_k)
replaced by (v_x, v_y, v_z, ρ)_k, a direction v ∈ [−1, 1]³ with ‖v‖² ≤ 1 (one inequality per segment after the
match defects) and the throttle ρ: thrust ρ·v, fuel flow ρ, so ‖v‖ = 1 wherever ρ > 0 at a fuel optimum
(84 core entries for N = 20). With ``multiple_shooting`` the core is followed by the 7-states at the
start of every sub-arc ("piece") after the first on each side, so that each piece is integrated
independently: the constraint Jacobian and the Lagrangian Hessian become block-sparse and an exact Hessian
is cheap.  Every piece is integrated with a fixed number of 8th-order Runge–Kutta steps (the DOP853
tableau), time-scaled so that the step length follows the piece length: thrust segments take
``steps_per_segment`` steps each.  Only position and velocity are integrated: the fuel flow is constant over a
piece, so the fuel mass is linear in time and exact (what RK8 on the 7-state gives).  The step and its Jacobian
are C code that CasADi calls (:mod:`~amorgs.problems.cr3bp.rk8_kernel`: the constraint Jacobian in about half
the time of CasADi's own reverse sweeps).  The two coasts start
from fixed states (ξ₀, and ξ_f with a mass that a coast does not change), so each is a function of one scalar
(τ_i, τ_f ∈ [0, 15] TU): with ``coast = 'interpolant'`` they are read off a cubic B-spline of the ballistic
flow sampled once every ``coast_grid_step`` TU (:func:`ballistic_flow`: the thrust segments' own RK8 kernel at
fixed steps of at most :data:`FLOW_MAX_STEP_TU`, so the spline's bits depend on no BLAS and no libm but ``sqrt``)
— one piece each, no integration at all per evaluation;
with ``coast = 'rk8'`` they are cut into ``coast_pieces`` pieces of
``steps_per_coast / coast_pieces`` RK8 steps.  Those choices are
:class:`~amorgs.solvers.options.TranscriptionOptions` (part of the solver's options, since they change the
solve but not the stored vector).
"""

from __future__ import annotations

import math

import casadi as ca
import numpy as np

from amorgs.problems.cr3bp import constants as K
from amorgs.problems.cr3bp import rk8_kernel
from amorgs.problems.cr3bp.controls import thrust_vectors
from amorgs.solvers.options import TranscriptionOptions

N_SEGMENTS = 20
CORE_SIZE = 4 + 3 * N_SEGMENTS
#: Upper bound of the thrust-arc duration τ_s (TU, spec §5).
TAU_S_MAX = 40.0
#: Upper bound of the coast durations τ_i and τ_f (TU, spec §5); the coast interpolants span [0, TAU_COAST_MAX].
TAU_COAST_MAX = 15.0
#: Longest RK8 step of the coasts' reference flow (TU): at 0.001 TU the flow agrees with half the step to
#: ≈ 1e-12 over the 15 TU (roundoff), where scipy's DOP853 at rtol 1e-13 was 2e-11 off.
FLOW_MAX_STEP_TU = 0.001


def variable_names(n_segments: int = N_SEGMENTS) -> tuple[str, ...]:
    """Names of the stored decision variables: tau_s, tau_i, tau_f, m_f, theta_01, phi_01, rho_01, …"""
    names = ["tau_s", "tau_i", "tau_f", "m_f"]
    for k in range(1, n_segments + 1):
        names += [f"theta_{k:02d}", f"phi_{k:02d}", f"rho_{k:02d}"]
    return tuple(names)


def _piece(step: ca.Function, n_steps: int, name: str) -> ca.Function:
    """Integrate n fixed steps over a duration dt (negative = backward): (s6, m, u4, p, dt) → s6.

    ``u4`` = (ρ·û, ρ), ``p`` = (a_max, ṁ_max); the fuel mass at the start of step j is m − ṁ_max·ρ·j·h
    (h = dt/n), exact (:mod:`~amorgs.problems.cr3bp.rk8_kernel`); the piece's final mass is :func:`_mass_after`.
    """
    s = ca.MX.sym("s", 6)
    m = ca.MX.sym("m")
    u = ca.MX.sym("u", 4)
    p = ca.MX.sym("p", 2)
    dt = ca.MX.sym("dt")
    h = dt / n_steps
    mdot = p[1] * u[3]
    masses = m - mdot * h * ca.DM(np.arange(n_steps)).T
    acc = step.mapaccum(n_steps)
    row = lambda v: ca.repmat(v, 1, n_steps)  # noqa: E731
    traj = acc(s, masses, row(u[:3]), row(p[0]), row(mdot), row(h))
    return ca.Function(name, [s, m, u, p, dt], [traj[:, -1]])


def _mass_after(m, u, p, dt):
    """Fuel mass (tonnes) after a piece of signed duration ``dt`` at throttle u[3]: m − ṁ_max·ρ·dt."""
    return m - p[1] * u[3] * dt


def ballistic_flow(state6, direction: int, duration: float, step: float) -> tuple[np.ndarray, np.ndarray]:
    """The ballistic flow of one fixed 6-state sampled on a uniform grid of coast durations.

    Returns ``grid`` (TU, shape (n,), 0 … ``duration`` in steps of at most ``step``) and ``states`` (6, n): the
    state (DU, VU) after coasting ``grid[k]`` TU forward (``direction`` = +1) or backward (−1) in time from
    ``state6``.  Integrated with the thrust segments' RK8 step (:mod:`~amorgs.problems.cr3bp.rk8_kernel`, zero
    thrust) at a fixed step ``grid[1] / k`` ≤ :data:`FLOW_MAX_STEP_TU`: C compiled with ``-ffp-contract=off``,
    only IEEE arithmetic and ``sqrt``, so the spline — constants of the NLP — has the same bits on every x86-64
    CPU and under every BLAS build (scipy's DOP853, used before, reads numpy's BLAS, whose kernels differ between
    CPUs; docs/reproducibility.md).
    """
    if direction not in (1, -1):
        raise ValueError(f"direction must be +1 or -1, got {direction!r}")
    n = int(np.ceil(duration / step - 1e-9)) + 1
    grid = np.linspace(0.0, duration, n)
    sub = math.ceil(duration / (n - 1) / FLOW_MAX_STEP_TU - 1e-9)
    total = (n - 1) * sub
    zero, one = ca.DM.zeros(1, total), ca.DM.ones(1, total)
    start = np.asarray(state6, float)[:6]
    # Zero thrust: the mass (1 t) is unused, the accelerations vanish and every step is ballistic.
    traj = rk8_kernel.rk8_step().mapaccum(total)(ca.DM(start), one, ca.DM.zeros(3, total), zero, zero,
                                                 one * (direction * duration / total))
    states = np.empty((6, n))
    states[:, 0] = start
    states[:, 1:] = np.asarray(traj)[:, sub - 1 :: sub]
    return grid, states


def _coast_interpolant(state6, direction: int, step: float, name: str) -> ca.Function:
    """Ballistic coast from a fixed state as a function of its duration: (s6, m, u4, p, dt) → s6.

    The position and velocity come from a cubic B-spline of the flow of ``state6[:6]`` (sampled every
    ``step`` TU over [0, TAU_COAST_MAX]); ``dt`` is the signed duration (``direction`` · τ).  ``s6`` must be the
    fixed start state the flow was sampled from (``m``, ``u4`` and ``p`` are unused: a coast burns no fuel).
    """
    grid, states = ballistic_flow(state6, direction, TAU_COAST_MAX, step)
    flow = ca.interpolant(f"{name}_flow", "bspline", [grid], states.ravel(order="F"))
    s = ca.MX.sym("s", 6)
    m = ca.MX.sym("m")
    u = ca.MX.sym("u", 4)
    p = ca.MX.sym("p", 2)
    dt = ca.MX.sym("dt")
    return ca.Function(name, [s, m, u, p, dt], [flow(direction * dt)])


def thrust_parameters(alpha: float | ca.MX) -> list:
    """(a_max, ṁ_max) for the internal units: α N → t·DU/TU² and t/TU."""
    return [alpha * K.thrust_nd(1.0) / 1000.0, alpha * K.mass_flow_kg_per_tu(1.0) / 1000.0]


class ForwardBackwardTranscription:
    """Builds the NLP ``min f(w; α) s.t. g(w; α) = 0, lbw ≤ w ≤ ubw`` and maps w ↔ the stored 64-vector.

    ``initial_state`` is ξ₀ (x, y, z, vx, vy, vz, fuel kg); ``terminal_state`` is ξ_f (6 entries).
    """

    def __init__(self, initial_state, terminal_state, options: TranscriptionOptions):
        self.options = options
        if self.options.step_scaling_alpha > 0 or self.options.controls_switch_alpha > 0:
            raise ValueError("resolve the α-dependent step count and controls first: "
                             "TranscriptionOptions.for_alpha(alpha)")
        opt = self.options
        self.n = N_SEGMENTS
        self.xi0 = np.asarray(initial_state, float).copy()
        self.xi0[6] /= 1000.0
        self.xif = np.asarray(terminal_state, float)[:6].copy()
        self.m0_kg = float(np.asarray(initial_state, float)[6])
        self.m0_t = float(self.xi0[6])
        step = rk8_kernel.rk8_step()
        self.c_sources = (rk8_kernel.source_path(),)
        if opt.coast == "interpolant":
            self.coast_pieces = {"coast_f": _coast_interpolant(self.xi0, 1, opt.coast_grid_step, "coast_f"),
                                 "coast_b": _coast_interpolant(self.xif, -1, opt.coast_grid_step, "coast_b")}
            self.kc = 1
        else:
            piece = _piece(step, opt.steps_per_coast // opt.coast_pieces, "coast_piece")
            self.coast_pieces = {"coast_f": piece, "coast_b": piece}
            self.kc = opt.coast_pieces
        self.thrust_piece = _piece(step, opt.steps_per_segment, "thrust_piece")
        half = self.n // 2
        # Pieces per chain: kc coast pieces then N/2 thrust segments.
        self.pieces_per_chain = self.kc + half
        self.n_nodes = 2 * (self.pieces_per_chain - 1) if opt.multiple_shooting else 0
        self.cartesian = opt.controls == "cartesian"
        self.core_size = 4 + (4 if self.cartesian else 3) * self.n
        self.n_w = self.core_size + 7 * self.n_nodes
        self._build()

    # -- layout ---------------------------------------------------------------------------------------
    def _controls(self, core):
        """u4 = (ρ·û, ρ) for each segment (time order) from the internal core variables."""
        if self.cartesian:
            return [ca.vertcat(core[7 + 4 * k] * core[4 + 4 * k: 7 + 4 * k], core[7 + 4 * k]) for k in range(self.n)]
        return self._stored_controls(core)

    def _stored_controls(self, core):
        """u4 = (ρ·û, ρ) for each segment (time order) from the stored layout's (θ, φ, ρ)."""
        us = []
        for k in range(self.n):
            th, ph, rho = core[4 + 3 * k], core[5 + 3 * k], core[6 + 3 * k]
            us.append(ca.vertcat(rho * ca.cos(ph) * ca.cos(th), rho * ca.cos(ph) * ca.sin(th), rho * ca.sin(ph), rho))
        return us

    def _chain_specs(self, core, us):
        """(kind, u4, dt) of every piece, forward chain then backward chain."""
        tau_s, tau_i, tau_f = core[0], core[1], core[2]
        zero = ca.MX.zeros(4)
        half = self.n // 2
        fwd = [("coast_f", zero, tau_i / self.kc)] * self.kc
        fwd += [("thrust", us[k], tau_s / self.n) for k in range(half)]
        bwd = [("coast_b", zero, -tau_f / self.kc)] * self.kc
        bwd += [("thrust", us[k], -tau_s / self.n) for k in range(self.n - 1, half - 1, -1)]
        return fwd, bwd

    def _apply(self, kind, state, u, p, dt):
        """One piece: the state (s6, fuel mass) at its start → at its end (a coast burns no fuel)."""
        s6, m = state
        if kind == "thrust":
            return self.thrust_piece(s6, m, u, p, dt), _mass_after(m, u, p, dt)
        return self.coast_pieces[kind](s6, m, u, p, dt), m

    @staticmethod
    def _difference(a, b):
        """a − b of two (s6, fuel mass) states, as the 7-vector of defects (DU, VU, tonnes)."""
        return ca.vertcat(a[0] - b[0], a[1] - b[1])

    def _build(self) -> None:
        w = ca.MX.sym("w", self.n_w)
        alpha = ca.MX.sym("alpha")
        p = ca.vertcat(*thrust_parameters(alpha))
        core = w[:self.core_size]
        us = self._controls(core)
        fwd, bwd = self._chain_specs(core, us)
        start_f = (ca.DM(self.xi0[:6]), ca.DM(self.xi0[6]))
        start_b = (ca.DM(self.xif), core[3])
        g = []
        if self.options.multiple_shooting:
            nodes = ca.reshape(w[self.core_size:], 7, self.n_nodes)
            m = self.pieces_per_chain - 1
            ends = []
            for chain, start, node_cols in ((fwd, start_f, range(0, m)), (bwd, start_b, range(m, 2 * m))):
                starts = [start] + [(nodes[:6, j], nodes[6, j]) for j in node_cols]
                chain_ends = [self._apply(kind, s, u, p, dt) for (kind, u, dt), s in zip(chain, starts)]
                g += [self._difference(e, s) for e, s in zip(chain_ends[:-1], starts[1:])]
                ends.append(chain_ends[-1])
            end_f, end_b = ends
        else:
            end_f, end_b = start_f, start_b
            for kind, u, dt in fwd:
                end_f = self._apply(kind, end_f, u, p, dt)
            for kind, u, dt in bwd:
                end_b = self._apply(kind, end_b, u, p, dt)
        g.append(self._difference(end_b, end_f))
        self.n_eq = 7 * len(g)
        if self.cartesian:  # ‖v_k‖² ≤ 1
            g += [ca.sumsqr(core[4 + 4 * k: 7 + 4 * k]) - 1 for k in range(self.n)]
        self.nlp = {"x": w, "p": alpha, "f": -core[3], "g": ca.vertcat(*g)}
        self.n_g = self.n_eq + (self.n if self.cartesian else 0)
        # Node initialisation: the single-shooting states at every piece start, as one Function.
        x64 = ca.MX.sym("x", CORE_SIZE)
        us64 = self._stored_controls(x64)
        fwd64, bwd64 = self._chain_specs(x64, us64)
        node_states = []
        match64 = []
        for chain, start in ((fwd64, start_f), (bwd64, (ca.DM(self.xif), x64[3]))):
            s = start
            for i, (kind, u, dt) in enumerate(chain):
                s = self._apply(kind, s, u, p, dt)
                if i < len(chain) - 1:
                    node_states.append(ca.vertcat(*s))
            match64.append(s)
        self.node_init = ca.Function(
            "node_init", [x64, alpha], [ca.horzcat(*node_states) if node_states else ca.DM.zeros(7, 0)]
        )
        self.match_defect_fn = ca.Function("match_defect", [x64, alpha], [self._difference(match64[1], match64[0])])

    # -- bounds and conversions -----------------------------------------------------------------------
    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Box bounds on w: spec §5 on the core (azimuths free; a Cartesian direction v in [−1, 1]³), node
        masses in [0, m₀], others free."""
        lo = np.full(self.n_w, -np.inf)
        hi = np.full(self.n_w, np.inf)
        lo[:4] = [0.0, 0.0, 0.0, 0.0]
        hi[:4] = [TAU_S_MAX, TAU_COAST_MAX, TAU_COAST_MAX, self.m0_t]
        for k in range(self.n):
            if self.cartesian:
                lo[4 + 4 * k: 7 + 4 * k], hi[4 + 4 * k: 7 + 4 * k] = -1.0, 1.0  # v
                lo[7 + 4 * k], hi[7 + 4 * k] = 0.0, 1.0
            else:
                lo[5 + 3 * k], hi[5 + 3 * k] = -math.pi / 2, math.pi / 2
                lo[6 + 3 * k], hi[6 + 3 * k] = 0.0, 1.0
        if self.n_nodes:
            mass = self.core_size + 6 + 7 * np.arange(self.n_nodes)
            lo[mass], hi[mass] = 0.0, self.m0_t
        return lo, hi

    def to_internal(self, x: np.ndarray, alpha: float) -> np.ndarray:
        """Stored 64-vector (m_f in kg) → w, with node states from single-shooting propagation."""
        core = np.asarray(x, float).copy()
        core[3] /= 1000.0
        internal = self._cartesian_core(core) if self.cartesian else core
        if not self.n_nodes:
            return internal
        nodes = np.asarray(self.node_init(core, alpha)).reshape(-1, order="F")
        return np.concatenate([internal, nodes])

    def constraint_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Bounds on g: the defects are equalities (0), the Cartesian ‖v‖² − 1 ≤ 0."""
        lo, hi = np.zeros(self.n_g), np.zeros(self.n_g)
        lo[self.n_eq:] = -np.inf
        return lo, hi

    def _cartesian_core(self, core: np.ndarray) -> np.ndarray:
        """Stored-layout core (m_f in tonnes) → the Cartesian internal core (v = û, ρ)."""
        th, ph, rho = core[4::3], core[5::3], core[6::3]
        u = np.column_stack([thrust_vectors(th, ph, 1.0), rho])
        return np.concatenate([core[:4], u.ravel()])

    @staticmethod
    def _spherical_core(w_core: np.ndarray) -> np.ndarray:
        """Cartesian internal core → stored layout: θ, φ of v (0 where v = 0) and the throttle ρ·‖v‖, so that
        the stored thrust ρ_stored·û is the solved ρ·v exactly (the fuel flow differs by ρ·(1 − ‖v‖), which is
        zero at a fuel optimum).  Unlike :func:`~amorgs.problems.cr3bp.controls.spherical_controls` (angles of
        the thrust vector, 0 where it vanishes) the angles are v's even where ρ = 0, so a warm start from the
        stored vector gets the solver's direction back."""
        u = w_core[4:].reshape(-1, 4)
        th = np.arctan2(u[:, 1], u[:, 0])
        ph = np.arctan2(u[:, 2], np.hypot(u[:, 0], u[:, 1]))
        rho = u[:, 3] * np.minimum(np.linalg.norm(u[:, :3], axis=1), 1.0)
        return np.concatenate([w_core[:4], np.stack([th, ph, rho], axis=1).ravel()])

    def to_stored(self, w: np.ndarray) -> np.ndarray:
        """w → stored 64-vector: m_f in kg, θ wrapped to [0, 2π), τ_s/τ_i/τ_f, m_f, φ and ρ clipped to their bounds.

        Cartesian controls are stored as θ, φ of v and the throttle ρ·min(‖v‖, 1) (:meth:`_spherical_core`).
        IPOPT may return values a few 1e-9 outside the box (its bound relaxation); clipping keeps every
        stored solution a valid warm start for ``check_guess``.
        """
        x = np.asarray(w, float)[:self.core_size].copy()
        if self.cartesian:
            x = self._spherical_core(x)
        x[:3] = np.clip(x[:3], 0.0, [TAU_S_MAX, TAU_COAST_MAX, TAU_COAST_MAX])
        x[3] = min(max(x[3] * 1000.0, 0.0), self.m0_kg)
        x[4::3] = np.mod(x[4::3], 2 * math.pi)
        x[5::3] = np.clip(x[5::3], -math.pi / 2, math.pi / 2)
        x[6::3] = np.clip(x[6::3], 0.0, 1.0)
        return x

    def match_defect(self, x: np.ndarray, alpha: float) -> np.ndarray:
        """Single-shooting match-point defect of a stored vector with this transcription's integrator."""
        core = np.asarray(x, float).copy()
        core[3] /= 1000.0
        return np.asarray(self.match_defect_fn(core, alpha)).ravel()
