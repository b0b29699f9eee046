"""Optimal control beside the paper's method: the best human-like motion and the physical bound.

Direct transcription solved by IPOPT (CasADi, exact Hessians on SX graphs):

* **Trajectory family.** Every free joint is a C² piecewise cubic: constant jerk on each of N
  intervals (a triple integrator). Its states q, q̇, q̈ at the nodes are the unknowns; the exact
  integration of constant jerk links consecutive nodes. So the trajectory is known *between*
  the nodes too, and any grid samples it exactly (:meth:`PiecewiseCubic.sample`). Within each
  segment of the motion the intervals are equal except the first and last, each cut into
  halving pieces (graded ends, :data:`END_GRADING`), or of the relative lengths
  ``interval_weights`` (NLP parameters: an adaptive mesh reuses the solver of its counts).
* **Boundary conditions** are the quintic's: rest to rest, q̇ = q̈ = 0 at both ends.
* **Limits between nodes, exactly.** On an interval, q is a cubic and q̇ a quadratic; a
  polynomial lies inside the hull of its Bernstein coefficients, which are linear in the node
  states (q̇: q̇_k, q̇_k + q̈_k h/2, q̇_k+1; q: q_k, q_k + q̇_k h/3, q_k+1 − q̇_k+1 h/3, q_k+1).
  Bounding those bounds position and velocity, and no joint reversal, everywhere. Torques are
  bounded at the nodes and at every interval's midpoint (the quadrature points); the result is
  re-checked with Pinocchio on the fine report grid.
* **Dynamics** are exact symbolic inverse dynamics of the robot (:mod:`app.planning.symbolic`).
* **Objectives**, integrated by Simpson's rule on each interval (node, midpoint, node), every
  metric of :mod:`app.planning.energy` exactly: ``tau_sq`` directly; ``abs_work`` and
  ``pos_work`` with slacks s ≥ ±τq̇ (s ≥ 0); ``peak_power`` and ``peak_torque`` in epigraph form
  (z ≥ Σ|τq̇|, z ≥ |τ_j|/τ_max,j at every point); ``electrical_energy`` with P_bus = p⁺ − p⁻,
  p± ≥ 0 and cost ∫ (p⁺ − η p⁻) dt, which equals ∫ max(P_bus, 0) − η max(−P_bus, 0) dt at the
  optimum because η < 1 makes any overlap of p⁺ and p⁻ cost more (friction by the smooth Coulomb
  law of the energy module, copper losses R i², regeneration η); and ``torque_change``
  ∫ Σ τ̇² dt (the minimum-torque-change model) with τ̇ the exact chain-rule derivative.
* **Human-likeness** (``human_constraint``): ``"peak"`` splits the motion where the elbow passes
  the template's angle and :data:`PEAK_BAND_DEG` and :data:`PEAK_CONCAVE_DEG` of flexion either
  side of it (free times) for one clear, bell-topped speed peak there: the elbow's acceleration is
  >= 0 at every node before the peak and <= 0 after it (so the speed rises, then falls, and the
  acceleration is zero at the peak, as at the paper's via point), its speed at the
  :data:`PEAK_BAND_DEG` angles is at most ``1 - PEAK_DROP`` of the peak's (within 1 % of the peak
  over at most 8 deg of flexion), and its jerk is <= 0 between the :data:`PEAK_CONCAVE_DEG`
  angles (a concave top, not a spike on a plateau); ``"phases"`` splits it where the elbow
  passes the A/B and B/C bounds and keeps each phase's share of the duration inside the
  template's spread; ``"shape"`` keeps the elbow speed, divided by its peak, inside the recorded
  lifts' band (mean ± SD over normalised time, :func:`human_spec_shape`) with one peak where the
  mean peaks; ``"none"`` is the physical bound under the same limits.

A solve whose IPOPT status is not ``Solve_Succeeded`` raises :class:`SolverError`; it is never
returned as a result.
"""

from __future__ import annotations

import dataclasses
import logging
import math
import os
import stat
import tempfile
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from app import names as _names
from app.errors import BioPlanError
from app.planning import jit_cache
from app.planning.blas_threads import single_threaded_casadi_blas
from app.planning.energy import FRICTION_VELOCITY_SCALE
from app.planning.profiles import Trajectory, quintic, time_grid
from app.planning.symbolic import symbolic_chain

if TYPE_CHECKING:
    from app.planning.robots import Robot

__all__ = [
    "HUMAN_CONSTRAINTS",
    "OPTIMAL_OBJECTIVES",
    "ExtraConstraints",
    "OptimalResult",
    "PiecewiseCubic",
    "SolverError",
    "SolverInfo",
    "solve_optimal",
]

FloatArray = NDArray[np.float64]
logger = logging.getLogger("bioplan.planning")

#: Human-likeness options of the optimal-control problem (one home: ``app.names``).
HUMAN_CONSTRAINTS: tuple[str, ...] = _names.HUMAN_CONSTRAINTS
#: Objectives the transcription minimises: every metric, the torque change and the jerk.
OPTIMAL_OBJECTIVES: tuple[str, ...] = (*_names.OBJECTIVES, "torque_change", "jerk")
#: Default number of constant-jerk intervals.
DEFAULT_INTERVALS = 40
#: Graded ends: the first and last interval of every segment is cut into L + 1 pieces of 1/2,
#: 1/4, ..., 2^-L, 2^-L of its length. Rest to rest holds the acceleration at zero at both ends
#: where the optimum wants a step, and the human rule kinks the optimum at its segment joins; on
#: equal intervals those intervals cap the error at first order (the human arm's `tau_sq`
#: human-like optimum: 6 % above its converged value at 40 equal intervals, 0.2 % at 40 graded
#: with L = 5; benchmarks/RESULTS.md, "Graded ends"). On the first mesh L is capped so that the
#: finest piece is no shorter than the report grid's step (:func:`report_resolved_grading`): a
#: piece the reported trajectory cannot resolve would make its metrics wrong (a 6 s task on 300
#: samples missed the potential-energy change by 0.75 % at L = 5). A refinement keeps that L:
#: with halving pieces a mesh of 2N is nested on one of N, and its end pieces are half as long,
#: so the end error falls with the rest (a cap per mesh would hold it and fake convergence).
END_GRADING = 5
#: The finest grading: pieces of 2^-12 of an interval (a 1 s task on 40 intervals: 6 µs).
_MAX_END_GRADING = 12
#: IPOPT's convergence tolerance (scaled objective, O(1)).
IPOPT_TOL = 1e-8
#: Where each interval is evaluated (fractions of its length) and the composite Simpson weights
#: (times h / divisor): quarters for the integral objectives; eighths for the peak objectives,
#: whose epigraphs must also hold between the points (measured: the fine-grid peak power stays
#: within 0.3 % of the solver's with eighths, 1.4 % with quarters).
_QUARTERS = ((0.0, 0.25, 0.5, 0.75, 1.0), (1.0, 4.0, 2.0, 4.0, 1.0), 12.0)
_EIGHTHS = (tuple(k / 8 for k in range(9)), (1.0, 4.0, 2.0, 4.0, 2.0, 4.0, 2.0, 4.0, 1.0), 24.0)
_PEAK_OBJECTIVES = ("peak_power", "peak_torque")
#: Metrics of the jerk, which is constant per interval and jumps at the nodes.
_ONE_SIDED = ("jerk", "torque_change")
#: Torque limits hold at the evaluation points with this relative margin, so that they hold
#: between them too (checked on the fine grid) [-].
TORQUE_MARGIN = 2e-3
#: Weight of ∫Στ² (relative to the initial guess's) added to objectives whose optimum is not
#: unique (slack and epigraph forms): it picks the smoothest of the equally good motions and
#: conditions IPOPT (half the iterations of 1e-4 on abs_work); the objective moves by the
#: weight times the relative effort change at most (measured: under 0.01 %).
REGULARIZATION = 1e-3
_NOT_UNIQUE = ("abs_work", "pos_work", "peak_power", "peak_torque", "electrical_energy")
#: Segment interval counts are multiples of this (when there are enough intervals).
_COUNT_STEP = 4
#: Fewest intervals any segment of a split motion gets.
_MIN_SEGMENT_INTERVALS = 4
#: The ``peak`` constraint's strict peak: at this many degrees of (human-equivalent) flexion on
#: either side of the template angle the elbow is at most ``1 - PEAK_DROP`` of its peak speed;
#: with the speed rising before the peak and falling after it, the flexion range over which the
#: speed stays within 1 % of its peak is then at most 2 x 4 = 8 deg [deg], [-].
PEAK_BAND_DEG = 4.0
PEAK_DROP = 0.01
#: ... and within this many degrees of flexion of it the elbow's acceleration only falls (the
#: speed is concave there, the top of a bell) [deg].
PEAK_CONCAVE_DEG = 20.0


class SolverError(BioPlanError):
    """IPOPT did not solve the problem (infeasible, or no convergence); one line with its status.

    Attributes:
        infeasible: IPOPT proved the limits cannot be met (not merely no convergence).
    """

    def __init__(self, message: str, *, infeasible: bool = False) -> None:
        super().__init__(message)
        self.infeasible = infeasible


@dataclass(frozen=True)
class SolverInfo:
    """How the solve went.

    Attributes:
        status: IPOPT's return status (always ``Solve_Succeeded`` in a returned result).
        iterations: IPOPT iterations.
        seconds: wall time of the solve [s] (building the problem included).
        objective: the solver's objective in the metric's unit (Simpson on the nodes).
        warm_start: what the initial guess came from.
        n_intervals: constant-jerk intervals N asked for (the mesh's size, doubled by refinement).
        end_grading: L, the pieces each segment's end intervals are further cut into beyond
            one (:data:`END_GRADING` capped by :func:`report_resolved_grading`; 0 for the
            ``shape`` constraint and given meshes): the mesh has 2L more intervals per segment.
        human_constraint: ``peak``, ``phases``, ``shape`` or ``none``.
        segment_durations: (S,) durations of the split motion's segments [s].
    """

    status: str
    iterations: int
    seconds: float
    objective: float
    warm_start: str
    n_intervals: int
    human_constraint: str
    segment_durations: tuple[float, ...] = ()
    end_grading: int = 0

    def to_dict(self) -> dict[str, Any]:
        return {
            "status": self.status,
            "iterations": self.iterations,
            "seconds": self.seconds,
            "objective": self.objective,
            "warm_start": self.warm_start,
            "n_intervals": self.n_intervals,
            "human_constraint": self.human_constraint,
            "segment_durations": list(self.segment_durations),
            "end_grading": self.end_grading,
        }


@dataclass(frozen=True)
class PiecewiseCubic:
    """A C² constant-jerk trajectory through node states.

    Attributes:
        t: (N+1,) node times [s], from 0 to the duration.
        q, qd, qdd: (N+1, n) node positions [rad], velocities [rad/s], accelerations [rad/s²].
    """

    t: FloatArray
    q: FloatArray
    qd: FloatArray
    qdd: FloatArray

    def sample(self, t: FloatArray, name: str = "") -> Trajectory:
        """The trajectory on any grid (T,) within [0, duration], evaluated exactly."""
        tt = np.asarray(t, dtype=np.float64)
        k = np.clip(np.searchsorted(self.t, tt, side="right") - 1, 0, self.t.size - 2)
        h = (self.t[k + 1] - self.t[k])[:, None]
        s = (tt - self.t[k])[:, None]
        jerk = (self.qdd[k + 1] - self.qdd[k]) / h
        q = self.q[k] + self.qd[k] * s + self.qdd[k] * s**2 / 2 + jerk * s**3 / 6
        qd = self.qd[k] + self.qdd[k] * s + jerk * s**2 / 2
        qdd = self.qdd[k] + jerk * s
        # The node states define it exactly: a cubic is its own quintic Hermite interpolant, so
        # the exporter resamples it at any rate from these knots without error.
        knots = (self.t, self.q, self.qd, self.qdd)
        return Trajectory(t=tt, q=q, qd=qd, qdd=qdd, jerk=jerk, name=name, knots=knots)


@dataclass(frozen=True)
class OptimalResult:
    """An optimal-control solution.

    Attributes:
        trajectory: the solution on the requested report grid.
        knots: the exact piecewise-cubic solution (sample it on any grid).
        solver: IPOPT's status, iterations, time and objective.
    """

    trajectory: Trajectory
    knots: PiecewiseCubic
    solver: SolverInfo


@dataclass(frozen=True)
class HumanSpec:
    """The human-likeness constraint in robot joint terms.

    Attributes:
        kind: ``peak``, ``phases``, ``shape`` or ``none``.
        elbow: index of the elbow joint.
        angles: (S-1,) elbow angles [rad] where the segments meet (the peak angle, or the A/B
            and B/C phase bounds on the stroke).
        share_bounds: (S, 2) lower and upper share of the duration per segment (phases only).
        band: (time, lower, upper), each (K,): the ``shape`` band of the elbow speed divided by
            its peak [-] on normalised time [-] (shape only).
        peak_time: normalised time of the ``shape`` band's peak [-].
    """

    kind: str
    elbow: int
    angles: tuple[float, ...] = ()
    share_bounds: tuple[tuple[float, float], ...] = ()
    peak_index: int = 0
    peak_drop: float = 0.0
    drop_at: tuple[int, ...] = ()
    concave: tuple[int, int] = (0, 0)
    band: tuple[tuple[float, ...], ...] = ()
    peak_time: float = 0.0

    def rules(self) -> str:
        """The human-likeness rule in one line (for results)."""
        if self.kind == "none":
            return "none"
        if self.kind == "shape":
            return (
                "elbow speed / its peak inside the recorded lifts' band (mean ± SD) at every "
                f"instant, one peak at {100 * self.peak_time:.0f} % of the duration (elbow "
                "acceleration >= 0 before it, <= 0 after it); the lower edge is not applied in "
                "the first and last intervals, where the elbow leaves and reaches rest"
            )
        if self.kind == "phases":
            return "each A/B/C phase's share of the duration within the template's spread"
        text = (
            "one elbow-speed peak where the elbow passes the template angle: elbow "
            "acceleration >= 0 before it, <= 0 after it"
        )
        if self.drop_at:
            text += (
                f"; at most {100 * (1 - self.peak_drop):g} % of the peak speed "
                f"{PEAK_BAND_DEG:g} deg of flexion from it"
            )
        if self.concave[1] > self.concave[0]:
            text += (
                f"; speed concave (elbow jerk <= 0) within {PEAK_CONCAVE_DEG:g} deg of flexion "
                "of it"
            )
        return text


# ----------------------------------------------------------------------------------------------
# Decision variables
# ----------------------------------------------------------------------------------------------


@dataclass
class _Variables:
    """Decision variables with bounds and initial values, in the solver's (scaled) units."""

    syms: list[Any] = field(default_factory=list)
    lower: list[FloatArray] = field(default_factory=list)
    upper: list[FloatArray] = field(default_factory=list)
    guess: list[FloatArray] = field(default_factory=list)
    rules: list[tuple[int, Any]] = field(default_factory=list)

    def add(self, name: str, shape: tuple[int, int], lo: Any, hi: Any, x0: Any) -> Any:
        import casadi as ca

        sym = ca.MX.sym(name, *shape)
        size = shape[0] * shape[1]
        # Column-major, as CasADi vectorises matrices; copies, so the blocks can be edited.
        for store, value in ((self.lower, lo), (self.upper, hi), (self.guess, x0)):
            arr = np.array(np.broadcast_to(np.asarray(value, dtype=np.float64), shape))
            store.append(arr.reshape(size, order="F").copy())
        self.syms.append(sym)
        return sym

    def start_from(self, sym: Any, expr: Any) -> None:
        """Start ``sym`` at the value of ``expr`` (a function of the states) at the guess."""
        index = next(i for i, s in enumerate(self.syms) if s is sym)
        self.rules.append((index, expr))

    def apply_rules(self, par: _Params) -> None:
        """Evaluate every start rule at the guess: slacks and epigraphs start on their bounds."""
        import casadi as ca

        if not self.rules:
            return
        outputs = [ca.vec(expr) for _, expr in self.rules]
        fn = ca.Function("start", [self.vector(), par.sym], outputs)
        values = fn.call([np.concatenate(self.guess), par.values])
        for (index, _), value in zip(self.rules, values, strict=True):
            self.guess[index] = np.asarray(value, dtype=np.float64).ravel() + 1e-6

    def vector(self) -> Any:
        import casadi as ca

        return ca.vertcat(*[ca.vec(s) for s in self.syms])

    def arrays(self) -> tuple[FloatArray, FloatArray, FloatArray]:
        return np.concatenate(self.lower), np.concatenate(self.upper), np.concatenate(self.guess)


@dataclass
class _Constraints:
    exprs: list[Any] = field(default_factory=list)
    lower: list[FloatArray] = field(default_factory=list)
    upper: list[FloatArray] = field(default_factory=list)

    def add(self, expr: Any, lo: Any, hi: Any) -> None:
        import casadi as ca

        e = ca.vec(expr)
        size = e.shape[0]
        self.exprs.append(e)
        self.lower.append(np.array(np.broadcast_to(np.asarray(lo, float), (size,))))
        self.upper.append(np.array(np.broadcast_to(np.asarray(hi, float), (size,))))

    def vector(self) -> Any:
        import casadi as ca

        return ca.vertcat(*self.exprs)

    def arrays(self) -> tuple[FloatArray, FloatArray]:
        return np.concatenate(self.lower), np.concatenate(self.upper)


@dataclass
class _Params:
    """The numbers that change from call to call (start, duration, scales) as NLP parameters,
    so that a solver built once serves every task of the same structure."""

    sym: Any
    values: FloatArray
    index: dict[str, slice]

    @classmethod
    def create(cls, n: int, faces: int = 0, intervals: int = 1) -> _Params:
        import casadi as ca

        sizes = {"start": n, "T": 1, "p_scale": 1, "cost_scale": 1, "effort_scale": 1}
        # Each interval's length as a fraction of its segment's duration [-] (a parameter, so
        # that a non-uniform mesh reuses the solver of its segment counts).
        sizes["fractions"] = intervals
        sizes.update(bound=1, bound_scale=1)  # ExtraConstraints' epsilon and its scale
        if faces:  # the obstacle faces chosen at the guess (ClearanceConstraint.constrain)
            sizes["faces"] = faces
        index, offset = {}, 0
        for name, size in sizes.items():
            index[name] = slice(offset, offset + size)
            offset += size
        return cls(ca.MX.sym("p", offset), np.ones(offset), index)

    def __getitem__(self, name: str) -> Any:
        sl = self.index[name]
        return self.sym[sl.start] if sl.stop - sl.start == 1 else self.sym[sl]

    def set(self, name: str, value: Any) -> None:
        self.values[self.index[name]] = value


# ----------------------------------------------------------------------------------------------
# The transcription
# ----------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class _Problem:
    robot: Robot
    start: FloatArray
    goal: FloatArray
    duration: float
    objective: str
    human: HumanSpec
    free: tuple[int, ...]
    no_reversal: bool
    counts: tuple[int, ...]  # intervals per segment
    extra: ExtraConstraints | None = None
    # Relative interval lengths (N,), normalised to sum to 1 within each segment; None = uniform.
    weights: tuple[float, ...] | None = None
    end_grading: int = 0  # the graded pieces added at each segment's ends (END_GRADING)
    asked: int | None = None  # N asked for, when the graded pieces make the mesh larger

    @property
    def n_intervals(self) -> int:
        return sum(self.counts)

    @property
    def asked_intervals(self) -> int:
        """N, the intervals asked for (without the graded end pieces)."""
        return self.asked if self.asked is not None else self.n_intervals


@dataclass
class _Grid:
    """Symbolic states of all joints at the nodes (n, N+1) and at the evaluation points.

    Each interval k is evaluated at the fractions of its length of ``_QUARTERS`` or ``_EIGHTHS``;
    point blocks are (n, N) per fraction, so a point's interval is its column, except that with
    shared nodes (:func:`_shared_nodes`) the first block holds the N+1 nodes and the last
    fraction's block is gone. ``h`` is (1, N) [s].
    """

    q: Any
    qd: Any
    qdd: Any
    h: Any
    T: Any  # the duration, symbolic [s]
    point_q: Any = None  # (n, P): P = 5N or 9N, or 4N + 1 or 8N + 1 with shared nodes
    point_qd: Any = None
    point_qdd: Any = None
    point_jerk: Any = None
    weights: Any = None  # (1, P) composite-Simpson weights [s]


def _scales(problem: _Problem) -> FloatArray:
    """Per-joint position scale [rad]: the stroke, at least 0.1 rad."""
    return np.maximum(np.abs(problem.goal - problem.start), 0.1)


def _node_guess(warm: Trajectory, node_t: FloatArray) -> tuple[FloatArray, ...]:
    def at(values: FloatArray) -> FloatArray:
        return np.stack([np.interp(node_t, warm.t, values[:, j]) for j in range(warm.n_joints)], 1)

    return at(warm.q), at(warm.qd), at(warm.qdd)


def _segment_times(problem: _Problem, warm: Trajectory) -> FloatArray:
    """Times [s] at which the warm start's elbow passes the segment angles (monotone elbow)."""
    if not problem.human.angles:
        return np.array([0.0, problem.duration])
    e = problem.human.elbow
    direction = 1.0 if problem.goal[e] >= problem.start[e] else -1.0
    elbow = np.maximum.accumulate(direction * warm.q[:, e])
    times = [float(np.interp(direction * a, elbow, warm.t)) for a in problem.human.angles]
    return np.array([0.0, *times, problem.duration])


def _fractions(problem: _Problem) -> FloatArray:
    """(N,) each interval's length as a fraction of its segment's duration [-]."""
    if problem.weights is not None:
        return np.asarray(problem.weights, dtype=np.float64)
    return np.concatenate([np.full(c, 1.0 / c) for c in problem.counts])


def _node_times(problem: _Problem, durations: FloatArray) -> FloatArray:
    """(N+1,) node times [s] of segments of ``durations`` [s] cut into the problem's intervals."""
    parts = [np.zeros(1)]
    t0 = 0.0
    if problem.weights is None:
        for count, d in zip(problem.counts, durations, strict=True):
            parts.append(t0 + d * np.arange(1, count + 1) / count)
            t0 += d
        return np.concatenate(parts)
    fractions, first = _fractions(problem), 0
    for count, d in zip(problem.counts, durations, strict=True):
        part = fractions[first : first + count]
        if np.ptp(part) == 0.0:  # equal intervals: the nodes exactly as without weights
            parts.append(t0 + d * np.arange(1, count + 1) / count)
        else:
            inner = np.cumsum(part)
            inner[-1] = 1.0  # the segment's end, exactly
            parts.append(t0 + d * inner)
        t0, first = t0 + d, first + count
    return np.concatenate(parts)


def _state_variables(
    problem: _Problem, var: _Variables, warm: Trajectory, durations0: FloatArray
) -> tuple[Any, Any, Any]:
    """Scaled node states of the free joints, bounded by the limits, fixed at both ends."""
    T, free = problem.duration, list(problem.free)
    m, n_nodes = len(free), problem.n_intervals + 1
    sc = _scales(problem)[free][:, None]
    q0, qd0, qdd0 = _node_guess(warm, _node_times(problem, durations0))
    robot = problem.robot
    lo_q = np.where(np.isfinite(robot.q_min[free]), robot.q_min[free], -1e3)[:, None] / sc
    hi_q = np.where(np.isfinite(robot.q_max[free]), robot.q_max[free], 1e3)[:, None] / sc
    vmax = robot.qd_max[free][:, None] * T / sc
    vlo, vhi = -vmax, vmax
    if problem.no_reversal:
        d = np.sign(problem.goal - problem.start)[free][:, None]
        vlo, vhi = np.where(d > 0, 0.0, vlo), np.where(d < 0, 0.0, vhi)
    qv = var.add("q", (m, n_nodes), lo_q, hi_q, q0[:, free].T / sc)
    vv = var.add("qd", (m, n_nodes), vlo, vhi, qd0[:, free].T * T / sc)
    av = var.add("qdd", (m, n_nodes), -np.inf, np.inf, qdd0[:, free].T * T**2 / sc)
    zero = np.zeros(m)
    ends: tuple[tuple[FloatArray, FloatArray], ...] = (
        (problem.start[free] / sc[:, 0], problem.goal[free] / sc[:, 0]),
        (zero, zero),
        (zero, zero),
    )
    for store in (var.lower, var.upper, var.guess):
        for index, (first, last) in enumerate(ends):
            block = store[index].reshape((m, n_nodes), order="F")
            block[:, 0] = first
            block[:, -1] = last
    return qv, vv, av


def _build_grid(
    problem: _Problem, var: _Variables, cons: _Constraints, warm: Trajectory, par: _Params
) -> tuple[_Grid, Any]:
    """Node states, segment durations and the constant-jerk continuity constraints."""
    import casadi as ca

    n, n_nodes, T = problem.start.size, problem.n_intervals + 1, problem.duration
    free = list(problem.free)
    segs = len(problem.counts)
    durations0 = np.maximum(np.diff(_segment_times(problem, warm)), 1e-3 * T)
    durations0 = durations0 * T / durations0.sum()
    qv, vv, av = _state_variables(problem, var, warm, durations0)
    t_sym = par["T"]
    # h_k = T x share of its segment x fraction of the segment (the ``fractions`` parameter:
    # 1 / count on a uniform mesh).
    fractions = ca.reshape(par.sym[par.index["fractions"]], 1, problem.n_intervals)
    if segs > 1:
        dvar = var.add("share", (segs, 1), 0.02, 1.0, (durations0 / T)[:, None])
        cons.add(ca.sum1(dvar) - 1.0, 0.0, 0.0)
        first = np.concatenate([[0], np.cumsum(problem.counts)]).astype(int)
        h = ca.horzcat(
            *[
                t_sym * dvar[s] * fractions[:, int(first[s]) : int(first[s + 1])]
                for s in range(segs)
            ]
        )
    else:
        dvar = None
        h = t_sym * fractions
    sc = ca.DM(_scales(problem))
    rows: list[list[Any]] = [[], [], []]
    free_rows = {j: r for r, j in enumerate(free)}
    for j in range(n):
        if j in free_rows:
            r = free_rows[j]
            rows[0].append(qv[r, :] * sc[j])
            rows[1].append(vv[r, :] * sc[j] / t_sym)
            rows[2].append(av[r, :] * sc[j] / t_sym**2)
        else:
            rows[0].append(ca.repmat(par["start"][j], 1, n_nodes))
            rows[1].append(ca.MX(1, n_nodes))
            rows[2].append(ca.MX(1, n_nodes))
    grid = _Grid(
        q=ca.vertcat(*rows[0]), qd=ca.vertcat(*rows[1]), qdd=ca.vertcat(*rows[2]), h=h, T=t_sym
    )
    _continuity(problem, grid, cons)
    _evaluation_points(grid, n, _rule(problem), _shared_nodes(problem))
    return grid, dvar


def _continuity(problem: _Problem, grid: _Grid, cons: _Constraints) -> None:
    """Exact constant-jerk integration from each node to the next (free joints)."""
    import casadi as ca

    free, T = list(problem.free), grid.T
    sc = ca.repmat(ca.DM(_scales(problem)[free]), 1, problem.n_intervals)
    q, qd, qdd = grid.q[free, :], grid.qd[free, :], grid.qdd[free, :]
    hh = ca.repmat(grid.h, len(free), 1)
    qa, qb, va, vb, aa, ab = q[:, :-1], q[:, 1:], qd[:, :-1], qd[:, 1:], qdd[:, :-1], qdd[:, 1:]
    cons.add((qb - qa - hh * va - hh**2 * (2 * aa + ab) / 6) / sc, 0.0, 0.0)
    cons.add((vb - va - hh * (aa + ab) / 2) * T / sc, 0.0, 0.0)


def _evaluation_points(
    grid: _Grid,
    n: int,
    rule: tuple[tuple[float, ...], tuple[float, ...], float],
    shared_nodes: bool = False,
) -> None:
    """States at the rule's points of every interval and the composite Simpson weights
    (``shared_nodes``: the nodes once, see :func:`_merge_node_columns`)."""
    import casadi as ca

    hh = ca.repmat(grid.h, n, 1)
    qa, va, aa = grid.q[:, :-1], grid.qd[:, :-1], grid.qdd[:, :-1]
    jerk = (grid.qdd[:, 1:] - aa) / hh
    blocks: list[list[Any]] = [[], [], [], [], []]
    fractions, simpson, divisor = rule
    for frac, weight in zip(fractions, simpson, strict=True):
        if frac == 1.0:
            state = (grid.q[:, 1:], grid.qd[:, 1:], grid.qdd[:, 1:])
        elif frac == 0.0:
            state = (qa, va, aa)
        else:
            s = frac * hh
            state = (
                qa + va * s + aa * s**2 / 2 + jerk * s**3 / 6,
                va + aa * s + jerk * s**2 / 2,
                aa + jerk * s,
            )
        for store, value in zip(blocks, (*state, jerk, grid.h * (weight / divisor)), strict=True):
            store.append(value)
    if shared_nodes:  # an interval's end is the next one's start: one column per node
        _merge_node_columns(grid, blocks, fractions)
    grid.point_q, grid.point_qd, grid.point_qdd, grid.point_jerk, grid.weights = (
        ca.horzcat(*b) for b in blocks
    )


def _merge_node_columns(grid: _Grid, blocks: list[list[Any]], fractions: Sequence[float]) -> None:
    """Replace the rule's first (fraction 0) and last (fraction 1) point blocks, (n, N) each, by
    one (n, N+1) block at the nodes whose weights add both sides' (so each node is constrained
    once). The node block's jerk is the next interval's (the last node: the last interval's)."""
    import casadi as ca

    first, last = fractions.index(0.0), fractions.index(1.0)
    jerk = blocks[3][first]
    states = (grid.q, grid.qd, grid.qdd, ca.horzcat(jerk, jerk[:, -1]))
    zero = ca.MX(1, 1)
    weight = ca.horzcat(blocks[4][first], zero) + ca.horzcat(zero, blocks[4][last])
    for store, value in zip(blocks, (*states, weight), strict=True):
        store[first] = value
        del store[last]


def _bernstein_limits(problem: _Problem, grid: _Grid, cons: _Constraints) -> None:
    """Position, velocity and no-reversal bounds between nodes via Bernstein coefficients."""
    import casadi as ca

    free, robot, T = list(problem.free), problem.robot, problem.duration
    direction = np.sign(problem.goal - problem.start)
    h, t_sym = grid.h, grid.T
    for j in free:
        s = float(_scales(problem)[j])
        q, qd, qdd = grid.q[j, :], grid.qd[j, :], grid.qdd[j, :]
        ctrl_v = (qd[:-1] + qdd[:-1] * h / 2) * t_sym / s
        vmax = float(robot.qd_max[j]) * T / s
        lo = 0.0 if problem.no_reversal and direction[j] > 0 else -vmax
        hi = 0.0 if problem.no_reversal and direction[j] < 0 else vmax
        cons.add(ctrl_v, lo, hi)
        qlo, qhi = float(robot.q_min[j]), float(robot.q_max[j])
        if math.isfinite(qlo) or math.isfinite(qhi):
            ctrl_q = ca.horzcat(q[:-1] + qd[:-1] * h / 3, q[1:] - qd[1:] * h / 3) / s
            cons.add(
                ctrl_q,
                qlo / s if math.isfinite(qlo) else -np.inf,
                qhi / s if math.isfinite(qhi) else np.inf,
            )


def _human_constraints(problem: _Problem, grid: _Grid, cons: _Constraints, dvar: Any) -> None:
    """Events at the segment joins; the elbow's speed peak or the phase shares."""

    human = problem.human
    if human.kind == "none":
        return
    if human.kind == "shape":
        _shape_constraints(problem, grid, cons)
        return
    e, T = human.elbow, grid.T
    scale = float(_scales(problem)[e])
    direction = 1.0 if problem.goal[e] >= problem.start[e] else -1.0
    joins = [int(k) for k in np.cumsum(problem.counts)[:-1]]
    for node, angle in zip(joins, human.angles, strict=True):
        cons.add(grid.q[e, node] / scale, angle / scale, angle / scale)
    if human.kind == "peak":
        # One peak: the elbow accelerates up to the peak node and decelerates after it (q̈ is
        # linear between nodes, so its sign at the nodes holds everywhere: the speed rises, then
        # falls); at the side angles it is at most (1 − drop) of the peak speed.
        peak = joins[human.peak_index]
        v_peak = direction * grid.qd[e, peak]
        acc = direction * grid.qdd[e, :] * T**2 / scale
        cons.add(acc[: peak + 1], 0.0, np.inf)
        cons.add(acc[peak:], -np.inf, 0.0)
        for i in human.drop_at:
            side = direction * grid.qd[e, joins[i]] - (1.0 - human.peak_drop) * v_peak
            cons.add(side * T / scale, -np.inf, 0.0)
        first, last = (joins[i] for i in human.concave)
        if last > first:
            jerk = direction * (grid.qdd[e, first + 1 : last + 1] - grid.qdd[e, first:last])
            cons.add(jerk * T**2 / scale, -np.inf, 0.0)
    else:
        for s, (lo, hi) in enumerate(human.share_bounds):
            cons.add(dvar[s], lo, hi)


@dataclass(frozen=True)
class _ShapePieces:
    """The ``shape`` band cut at the solver's nodes and the band's own points: P pieces.

    Attributes:
        interval: (P,) the solver interval of each piece.
        start, end: (P,) where the piece starts and ends within its interval [-] (normalised
            time from the interval's start).
        lower, upper: (P, 2) the band's edges at the piece's start and end [-].
    """

    interval: NDArray[np.int64]
    start: FloatArray
    end: FloatArray
    lower: FloatArray
    upper: FloatArray


def _shape_pieces(human: HumanSpec, n_intervals: int) -> _ShapePieces:
    """Cut the band (piecewise linear between its points) at the N equal intervals' nodes, so
    that on every piece the edges are straight and the speed is one quadratic.

    The first and last intervals get no lower edge: the elbow leaves and reaches rest there
    with zero acceleration, its speed growing as t², below any edge rising from 0.
    """
    time, lower, upper = (np.asarray(b, dtype=np.float64) for b in human.band)
    edges = np.linspace(0.0, 1.0, n_intervals + 1)
    inner = time[(time > 0.0) & (time < 1.0)]
    # Band points on a node (to rounding) would leave pieces of zero length.
    inner = inner[np.abs(inner * n_intervals - np.round(inner * n_intervals)) > 1e-9]
    cuts = np.unique(np.concatenate([edges, inner]))
    a, b = cuts[:-1], cuts[1:]
    interval = np.clip(np.searchsorted(edges, 0.5 * (a + b)) - 1, 0, n_intervals - 1)
    lo = np.stack([np.interp(a, time, lower), np.interp(b, time, lower)], axis=1)
    hi = np.stack([np.interp(a, time, upper), np.interp(b, time, upper)], axis=1)
    lo[(interval == 0) | (interval == n_intervals - 1)] = 0.0
    return _ShapePieces(interval, a - edges[interval], b - edges[interval], lo, hi)


def shape_peak_node(human: HumanSpec, n_intervals: int) -> int:
    """The node (of N equal intervals) where the ``shape`` constraint puts the elbow's peak."""
    return int(np.clip(round(human.peak_time * n_intervals), 1, n_intervals - 1))


def _shape_constraints(problem: _Problem, grid: _Grid, cons: _Constraints) -> None:
    """``shape``: one speed peak at the band's peak node, the speed / peak inside the band.

    The motion is one segment of equal intervals, so node k lies at normalised time k / N and
    the band's edges are numbers there. In scaled units (v = q̇ T / stroke, a = dv/dτ, τ the
    normalised time) the speed on a piece [α, β] of an interval is a quadratic with Bernstein
    coefficients v(α), v(α) + a(α)(β − α)/2, v(β), and an edge is a straight line with
    coefficients e(α), (e(α) + e(β))/2, e(β): the speed lies within edge x peak speed on the
    whole piece when each coefficient does (linear in the unknowns: the edges multiply the
    peak node's speed). The acceleration's signs make that node the maximum.
    """
    import casadi as ca

    human, n = problem.human, problem.n_intervals
    e, T = human.elbow, grid.T
    scale = float(_scales(problem)[e])
    direction = 1.0 if problem.goal[e] >= problem.start[e] else -1.0
    v = direction * grid.qd[e, :] * T / scale
    a = direction * grid.qdd[e, :] * T**2 / scale
    peak = shape_peak_node(human, n)
    cons.add(a[: peak + 1], 0.0, np.inf)
    cons.add(a[peak:], -np.inf, 0.0)
    pieces = _shape_pieces(human, n)
    count = pieces.interval.size

    def pick(row: Any, offset: int) -> Any:
        # A sparse selection, so each piece's rows depend on its own interval's nodes only.
        rows = [int(k) + offset for k in pieces.interval]
        select = ca.Sparsity.triplet(n + 1, count, rows, list(range(count)))
        return ca.mtimes(row, ca.DM(select, 1.0))

    vk, ak, ak1 = pick(v, 0), pick(a, 0), pick(a, 1)
    jerk = (ak1 - ak) * n  # da/dτ on the interval (τ-length 1/N)
    alpha, beta = ca.DM(pieces.start).T, ca.DM(pieces.end).T
    v_a = vk + ak * alpha + jerk * alpha**2 / 2
    v_b = vk + ak * beta + jerk * beta**2 / 2
    v_mid = v_a + (ak + jerk * alpha) * (beta - alpha) / 2
    top = v[peak]
    for edge, lo, hi in ((pieces.lower, 0.0, np.inf), (pieces.upper, -np.inf, 0.0)):
        ea, eb = ca.DM(edge[:, 0]).T, ca.DM(edge[:, 1]).T
        for coef, value in ((v_a, ea), (v_mid, (ea + eb) / 2), (v_b, eb)):
            cons.add(coef - value * top, lo, hi)


# ----------------------------------------------------------------------------------------------
# Objectives
# ----------------------------------------------------------------------------------------------


def _reduced_dynamics(problem: _Problem) -> Any:
    """The SX inverse dynamics with the joints that stay put folded in as constants.

    ``(q_free, qd_free, qdd_free) -> tau`` (all n joints): a still joint's angle, speed and
    acceleration are numbers, so CasADi simplifies their terms away once, not at every point.
    """
    import casadi as ca

    n, free = problem.start.size, list(problem.free)
    chain = symbolic_chain(problem.robot)
    syms = [ca.SX.sym(name, len(free)) for name in ("q", "qd", "qdd")]
    full: list[list[Any]] = [[], [], []]
    rows = {j: r for r, j in enumerate(free)}
    for j in range(n):
        for k in range(3):
            if j in rows:
                full[k].append(syms[k][rows[j]])
            else:
                full[k].append(ca.SX(float(problem.start[j]) if k == 0 else 0.0))
    tau = chain.inverse_dynamics(*(ca.vertcat(*f) for f in full))
    return ca.Function("reduced_dynamics", syms, [tau])


#: Evaluation points from which the per-point dynamics is compiled to C (:func:`_compiled`) when
#: the compiled objects cannot be cached on disk (:mod:`app.planning.jit_cache` off): below,
#: compiling it (0.3 s, its derivatives 1-4 s more, once per process) costs more than it saves
#: (benchmarks/RESULTS.md, "Converged results: where the time goes"). The peak objectives' 160
#: intervals are 1440 points (eighths), the others' 320 are 1600 (quarters); no uniform mesh of
#: 40 x 2^k intervals has 1000-1400 points, but adaptive meshes do (6-DOF peak power, 149
#: intervals = 1341 points: 12-14 s interpreted, 4-8 s compiled; "Adaptive mesh refinement"
#: there), hence 1000 rather than 1400. With the cache on, the compiler runs once per chain
#: structure and machine, and the dynamics is compiled at every mesh.
COMPILE_FROM_POINTS = 1000
#: Compiled per-point dynamics by chain structure (None: no working C compiler).
_COMPILED: dict[tuple[Any, ...], Any] = {}


def _jit_folder() -> str:
    """Where compiled functions' C sources and libraries go: this user's own
    ``<tmp>/bioplan-jit-<uid>`` (mode 0700; a fresh private folder if that path is not this
    user's plain folder). CasADi writes them to the working directory unless told otherwise,
    and removes them itself when the function is freed, so the folder stays empty between runs.
    """
    folder = os.path.join(tempfile.gettempdir(), f"bioplan-jit-{os.getuid()}")
    try:
        os.makedirs(folder, mode=0o700, exist_ok=True)
        info = os.lstat(folder)
        if stat.S_ISDIR(info.st_mode) and info.st_uid == os.getuid():
            return folder
    except OSError:
        pass
    return tempfile.mkdtemp(prefix="bioplan-jit-")


def _jit_options() -> dict[str, Any]:
    """CasADi options of a function compiled by the system C compiler (its derivatives alike),
    every file it writes in :func:`_jit_folder`, the objects cached on disk
    (:mod:`app.planning.jit_cache`) unless that is off."""
    options: dict[str, Any] = {
        "flags": ["-O1"], "verbose": False, "directory": os.path.join(_jit_folder(), ""),
    }  # fmt: skip
    cached = jit_cache.compiler_command()
    if cached is not None:
        options["compiler"] = cached
    return {
        "jit": True,
        "compiler": "shell",
        "jit_name": "bioplan_dynamics",
        "jit_options": options,
    }


def _chain_key(problem: _Problem) -> tuple[Any, ...]:
    """What the reduced dynamics depends on: the chain's numbers, the free joints and the
    angles of the fixed ones."""
    chain = symbolic_chain(problem.robot)
    bodies = tuple(
        (b.parent, b.rotation.tobytes(), b.translation.tobytes(), b.axis.tobytes(), b.mass,
         b.com.tobytes(), b.inertia.tobytes(), b.armature)
        for b in chain.bodies
    )  # fmt: skip
    fixed = tuple(
        float(problem.start[j]) for j in range(problem.start.size) if j not in problem.free
    )
    return bodies, chain.gravity.tobytes(), problem.free, fixed


def _compiled(problem: _Problem) -> Any:
    """The reduced dynamics (:func:`_reduced_dynamics`), itself and its derivatives (the
    Jacobians and the Hessian IPOPT asks for) compiled to C by the system compiler; built once
    per chain structure in this process, the objects once per machine
    (:mod:`app.planning.jit_cache`), and reused by every mesh and task of that structure. None
    if no compiler works.

    Why: IPOPT's function evaluations (mostly the Hessian of the mapped dynamics) take half of
    each iteration in CasADi's virtual machine; compiled, a quarter of that. Only this small
    function is compiled (about 200 instructions for the 6-DOF arm, 0.2 s), never the whole
    NLP (36-70 MB of C that did not compile in 11 minutes).
    """
    import casadi as ca

    key = _chain_key(problem)
    if key not in _COMPILED:
        fn = _reduced_dynamics(problem)
        try:
            args = fn.sx_in()
            jit = _jit_options()
            _COMPILED[key] = ca.Function(
                "reduced_dynamics_c", args, fn.call(args), {**jit, "der_options": dict(jit)}
            )
        except RuntimeError as exc:  # no working C compiler: the interpreted function
            logger.info("per-point dynamics not compiled (%s): interpreted", exc)
            _COMPILED[key] = None
    return _COMPILED[key]


def _compile_from_points() -> int:
    """Evaluation points from which the dynamics is compiled: every mesh when the objects are
    cached on disk, else :data:`COMPILE_FROM_POINTS`."""
    return 0 if jit_cache.cache_folder() is not None else COMPILE_FROM_POINTS


def _torques(problem: _Problem, grid: _Grid) -> Any:
    """(n, P) joint torques at every evaluation point: one mapped call of the SX dynamics,
    compiled to C from :func:`_compile_from_points` points when a compiler works."""
    free = list(problem.free)
    points = grid.point_q.shape[1]
    fn = _compiled(problem) if points >= _compile_from_points() else None
    if fn is None:
        fn = _reduced_dynamics(problem)
    return fn.map(points)(grid.point_q[free, :], grid.point_qd[free, :], grid.point_qdd[free, :])


def _objective(
    problem: _Problem, grid: _Grid, var: _Variables, cons: _Constraints, tau: Any, par: _Params
) -> Any:
    """The objective in the metric's unit (slack, epigraph and regeneration forms)."""
    import casadi as ca

    obj, w = problem.objective, grid.weights
    if obj == "jerk":  # constant per interval: Simpson's weights integrate it exactly
        return ca.dot(w, ca.sum1(grid.point_jerk**2))
    if obj == "tau_sq":
        return ca.dot(w, ca.sum1(tau**2))
    if obj == "torque_change":
        return _torque_change(problem, grid)
    if obj == "electrical_energy":
        return _electrical(problem, grid, var, cons, tau, par)
    n_pts = grid.point_q.shape[1]
    if obj == "peak_torque":
        ratio = tau / ca.repmat(ca.DM(problem.robot.tau_max), 1, n_pts)
        z = var.add("z", (1, 1), 0.0, np.inf, 1.0)
        cons.add(z - ratio, 0.0, np.inf)
        cons.add(z + ratio, 0.0, np.inf)
        var.start_from(z, ca.mmax(ca.fabs(ratio)))
        return z
    free = list(problem.free)
    p_scale = par["p_scale"]
    scaled = tau[free, :] * grid.point_qd[free, :] / p_scale
    slack = var.add("s", (len(free), n_pts), 0.0, np.inf, 1.0)
    cons.add(slack - scaled, 0.0, np.inf)
    if obj == "pos_work":
        var.start_from(slack, ca.fmax(scaled, 0))
        return p_scale * ca.dot(w, ca.sum1(slack))
    cons.add(slack + scaled, 0.0, np.inf)
    var.start_from(slack, ca.fabs(scaled))
    if obj == "abs_work":
        return p_scale * ca.dot(w, ca.sum1(slack))
    z = var.add("z", (1, 1), 0.0, np.inf, 1.0)
    cons.add(z - ca.sum1(slack), 0.0, np.inf)
    var.start_from(z, ca.mmax(ca.sum1(ca.fabs(scaled))))
    return p_scale * z


def _power_scale(problem: _Problem) -> float:
    """A power [W] of the task's order (the quintic's peak |power|), to scale slacks to O(1)."""
    tr = quintic(problem.start, problem.goal, problem.duration, n_samples=101)
    tau = problem.robot.dynamics().inverse_dynamics(tr.q, tr.qd, tr.qdd)
    return float(max(np.abs(tau * tr.qd).sum(axis=1).max(), 1e-3))


def _electrical(
    problem: _Problem, grid: _Grid, var: _Variables, cons: _Constraints, tau: Any, par: _Params
) -> Any:
    """Bus energy ∫ (p⁺ − η p⁻) dt with p⁺ − p⁻ = P_bus (friction, copper loss, regeneration)."""
    import casadi as ca

    motors = problem.robot.motors
    eta = min(float(m.regen_efficiency) for m in motors)
    n_pts = grid.point_q.shape[1]

    def column(values: list[float]) -> Any:
        return ca.repmat(ca.DM(values), 1, n_pts)

    qd = grid.point_qd
    friction = column([m.viscous_friction for m in motors]) * qd + column(
        [m.coulomb_friction for m in motors]
    ) * ca.tanh(qd / FRICTION_VELOCITY_SCALE)
    total = tau + friction
    current = total / column([m.gear_ratio * m.torque_constant for m in motors])
    p_scale = par["p_scale"]
    bus = ca.sum1(total * qd + column([m.winding_resistance for m in motors]) * current**2)
    bus = bus / p_scale
    plus = var.add("p_plus", (1, n_pts), 0.0, np.inf, 1.0)
    var.start_from(plus, ca.fmax(bus, 0))
    minus = var.add("p_minus", (1, n_pts), 0.0, np.inf, 0.0)
    var.start_from(minus, ca.fmax(-bus, 0))
    cons.add(plus - minus - bus, 0.0, 0.0)
    return p_scale * ca.dot(grid.weights, plus - eta * minus)


def _torque_change(problem: _Problem, grid: _Grid) -> Any:
    """∫ Σ τ̇² dt with τ̇ = ∂τ/∂q q̇ + ∂τ/∂q̇ q̈ + ∂τ/∂q̈ q⃛ (constant jerk per interval)."""
    import casadi as ca

    n = problem.start.size
    chain = symbolic_chain(problem.robot)
    q, qd, qdd, jerk = (ca.SX.sym(s, n) for s in ("q", "qd", "qdd", "jerk"))
    tau = chain.inverse_dynamics(q, qd, qdd)
    dtau = ca.jtimes(tau, ca.vertcat(q, qd, qdd), ca.vertcat(qd, qdd, jerk))
    fn = ca.Function("torque_rate", [q, qd, qdd, jerk], [dtau]).map(grid.point_q.shape[1])
    rate = fn(grid.point_q, grid.point_qd, grid.point_qdd, grid.point_jerk)
    return ca.dot(grid.weights, ca.sum1(rate**2))


def _torque_limits(problem: _Problem, cons: _Constraints, tau: Any) -> None:
    import casadi as ca

    ratio = tau / ca.repmat(ca.DM(problem.robot.tau_max), 1, tau.shape[1])
    cons.add(ratio, -1.0 + TORQUE_MARGIN, 1.0 - TORQUE_MARGIN)


# ----------------------------------------------------------------------------------------------
# Extra constraints: a metric bound (epsilon-constraint fronts), controller limits, actuators
# ----------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class ExtraConstraints:
    """Constraints beyond the limits and the human-likeness rule (all optional).

    Attributes:
        metric: a second metric (:data:`OPTIMAL_OBJECTIVES`) bounded by ``bound``: the
            epsilon-constraint of a Pareto front (:mod:`app.planning.front`); None = none.
        bound: epsilon, the largest allowed value of ``metric`` in its unit (``peak_torque``: the
            largest |τ_j| / τ_max,j) [metric unit].
        controller_limits: also keep the robot's acceleration ``qdd_max`` [rad/s²] (at the
            nodes: q̈ is linear between them) and jerk ``jerk_max`` [rad/s³] (constant per
            interval) limits, as the jerk-limited baseline does.
        actuators: per joint torque–speed envelopes and RMS torque limits
            (:class:`app.planning.actuators.ActuatorLimits`), or None.
        warm: the warm start is near the optimum (a front's neighbour): IPOPT starts with a
            small barrier parameter (:data:`_WARM`; measured on the 6-DOF: 6 iterations instead
            of 10, the same optimum to 1e-8).
        clearance: spheres covering the robot's links kept above the mounting plane and out
            of the sidecar's obstacles at every evaluation point
            (:class:`app.planning.clearance.ClearanceConstraint`; an obstacle's faces are
            chosen at the warm start), or None.
    """

    metric: str | None = None
    bound: float = math.inf
    controller_limits: bool = False
    actuators: Any = None
    warm: bool = False
    clearance: Any = None

    def key(self, goal: FloatArray) -> tuple[Any, ...]:
        """What changes the NLP's structure (epsilon is a parameter, not structure; the
        actuators' numbers and the goal's holding torques are constants of its graph)."""
        clear = None if self.clearance is None else self.clearance.key()
        if self.actuators is None:
            return (self.metric, self.controller_limits, None, self.warm, clear)
        acts = self.actuators.key()
        return (self.metric, self.controller_limits, acts, goal.tobytes(), self.warm, clear)


#: IPOPT options of a warm-started solve (``ExtraConstraints.warm``).
_WARM: dict[str, Any] = {"ipopt.mu_init": 1e-4, "ipopt.warm_start_init_point": "yes"}


def _rule(problem: _Problem) -> tuple[tuple[float, ...], tuple[float, ...], float]:
    """The evaluation points per interval (fractions), Simpson weights and divisor."""
    return _EIGHTHS if _peak_rule(problem) else _QUARTERS


#: Evaluate each node once (False: as each interval's end and the next one's start, the
#: behaviour before; ``benchmarks/bench_optimal.py --variants separate_nodes`` measures it).
SHARE_NODES = True


def _shared_nodes(problem: _Problem) -> bool:
    """Constrain each node once (not as one interval's end and the next one's start), unless a
    metric needs the jerk, which jumps at a node, on both sides of it."""
    extra = problem.extra
    metrics = {problem.objective, None if extra is None else extra.metric}
    return SHARE_NODES and not metrics & set(_ONE_SIDED)


def _n_points(problem: _Problem) -> int:
    """Evaluation points of the transcription."""
    per_interval = len(_rule(problem)[0])
    if _shared_nodes(problem):
        return problem.n_intervals * (per_interval - 1) + 1
    return problem.n_intervals * per_interval


def _peak_rule(problem: _Problem) -> bool:
    """Evaluate on eighths when the objective or a bounded metric is a peak (epigraph) metric."""
    extra = problem.extra
    bounded = extra.metric if extra is not None else None
    return problem.objective in _PEAK_OBJECTIVES or bounded in _PEAK_OBJECTIVES


def _extra_constraints(
    problem: _Problem, grid: _Grid, var: _Variables, cons: _Constraints, tau: Any, par: _Params
) -> None:
    """The :class:`ExtraConstraints` of the problem, if any."""
    extra = problem.extra
    if extra is None:
        return
    if extra.metric is not None:
        if extra.metric not in OPTIMAL_OBJECTIVES:
            raise BioPlanError(
                f"unknown bounded metric {extra.metric!r}: expected one of "
                f"{', '.join(OPTIMAL_OBJECTIVES)}"
            )
        bounded = _objective(
            dataclasses.replace(problem, objective=extra.metric), grid, var, cons, tau, par
        )
        par.set("bound", extra.bound)
        par.set("bound_scale", max(abs(extra.bound), 1e-9))
        cons.add((bounded - par["bound"]) / par["bound_scale"], -np.inf, 0.0)
    if extra.controller_limits:
        _controller_limits(problem, grid, cons)
    if extra.actuators is not None:
        extra.actuators.constrain(problem.robot, problem.goal, grid, cons, tau, problem.free)
    if extra.clearance is not None:
        guess = None
        if extra.clearance.obstacles:  # their faces are chosen at the guess's points
            import casadi as ca

            at = ca.Function("guess_points", [var.vector(), par.sym], [grid.point_q])
            guess = np.asarray(at(np.concatenate(var.guess), par.values), dtype=float)
        extra.clearance.constrain(problem.robot, grid, cons, par=par, guess=guess)


def _controller_limits(problem: _Problem, grid: _Grid, cons: _Constraints) -> None:
    """|q̈| <= qdd_max at the nodes and |q⃛| <= jerk_max on every interval (free joints)."""
    robot, T = problem.robot, grid.T
    for j in problem.free:
        s = float(_scales(problem)[j])
        amax = float(np.asarray(robot.qdd_max)[j])
        jmax = float(np.asarray(robot.jerk_max)[j])
        qdd = grid.qdd[j, :]
        if math.isfinite(amax):
            cons.add(qdd * T**2 / s, -amax * float(problem.duration) ** 2 / s, np.inf)
            cons.add(qdd * T**2 / s, -np.inf, amax * float(problem.duration) ** 2 / s)
        if math.isfinite(jmax):
            step = qdd[1:] - qdd[:-1]
            cons.add((step - jmax * grid.h) * T**2 / s, -np.inf, 0.0)
            cons.add((step + jmax * grid.h) * T**2 / s, 0.0, np.inf)


# ----------------------------------------------------------------------------------------------
# Solve
# ----------------------------------------------------------------------------------------------


def _segment_counts(human: HumanSpec, n_intervals: int, shares: FloatArray) -> tuple[int, ...]:
    """Intervals per segment, in proportion to the warm start's segment durations, rounded to
    multiples of :data:`_COUNT_STEP` (so that similar tasks share one solver structure)."""
    if human.kind == "none":
        return (n_intervals,)
    step = _COUNT_STEP if n_intervals >= 4 * _COUNT_STEP * shares.size else 1
    # The peak's short segments (a few degrees each) may get fewer intervals on a coarse mesh.
    least = max(1, min(_MIN_SEGMENT_INTERVALS, n_intervals // shares.size - 1))
    raw = np.maximum(np.round(shares * n_intervals / step) * step, least)
    raw = raw.astype(int)
    raw[int(np.argmax(raw))] += n_intervals - int(raw.sum())
    if raw.min() < least:
        raise BioPlanError(
            f"{n_intervals} intervals cannot be split into {raw.size} segments of at least "
            f"{least}: expected more intervals"
        )
    return tuple(int(c) for c in raw)


def report_resolved_grading(levels: int, n_intervals: int, report_samples: int) -> int:
    """The graded ends' L, capped so that the finest piece, 2^-L of a mean interval (T / N),
    spans at least one step of the report grid (T / (report_samples - 1)): the largest L <= levels
    with 2^L <= (report_samples - 1) / N, and 0 when an interval is shorter than a step."""
    steps_per_interval = (report_samples - 1) / n_intervals
    if steps_per_interval < 2.0:
        return 0
    return max(0, min(levels, math.floor(math.log2(steps_per_interval) + 1e-9)))


def _check_options(
    objective: str,
    human: HumanSpec,
    n_intervals: int,
    grading: int = 0,
    max_iterations: int | None = None,
) -> None:
    if objective not in OPTIMAL_OBJECTIVES:
        raise BioPlanError(
            f"unknown objective {objective!r}: expected one of {', '.join(OPTIMAL_OBJECTIVES)}"
        )
    if human.kind not in HUMAN_CONSTRAINTS:
        raise BioPlanError(
            f"unknown human constraint {human.kind!r}: expected one of "
            f"{', '.join(HUMAN_CONSTRAINTS)}"
        )
    if n_intervals < 8:
        raise BioPlanError(f"n_intervals must be >= 8, got {n_intervals}")
    if max_iterations is not None and max_iterations < 1:
        raise BioPlanError(f"max_iterations must be >= 1, got {max_iterations}")
    if not 0 <= grading <= _MAX_END_GRADING:
        raise BioPlanError(
            f"end_grading must be 0 (equal intervals) to {_MAX_END_GRADING}, got {grading}"
        )


def _problem(
    robot: Robot,
    start: FloatArray,
    goal: FloatArray,
    duration: float,
    objective: str,
    human: HumanSpec,
    warm: Trajectory,
    n_intervals: int,
    no_reversal: bool,
    interval_weights: Sequence[float] | None = None,
    segment_counts: Sequence[int] | None = None,
    end_grading: int = 0,
) -> _Problem:
    moving = np.abs(goal - start) > 0
    free = tuple(int(j) for j in range(start.size) if moving[j] or not no_reversal)
    grading = 0
    if segment_counts is not None:
        counts = _checked_counts(human, n_intervals, segment_counts)
    else:
        probe = _Problem(robot, start, goal, duration, objective, human, free, no_reversal, (1,))
        shares = np.diff(_segment_times(probe, warm)) / duration
        counts = _segment_counts(human, n_intervals, shares)
        if interval_weights is None and human.kind != "shape" and end_grading > 0:
            grading = end_grading
            counts, graded = _graded_ends(counts, grading)
            interval_weights = tuple(float(w) for w in graded)
    weights = _normalised_weights(human, counts, interval_weights)
    return _Problem(
        robot, start, goal, duration, objective, human, free, no_reversal, counts, None, weights,
        grading, n_intervals,
    )  # fmt: skip


def _graded_ends(counts: tuple[int, ...], levels: int) -> tuple[tuple[int, ...], FloatArray]:
    """Segment counts and interval weights of equal intervals whose first and last in every
    segment are each cut into pieces of 1/2, 1/4, ..., 2^-L, 2^-L of their length (see
    :data:`END_GRADING`): (S,) counts, each + 2L, and their (N + 2SL,) weights."""
    pieces = np.array([2.0**-levels, *(2.0 ** -np.arange(levels, 0, -1))])  # smallest first
    per_segment = []
    for count in counts:
        # A segment of one interval: its halves, each graded towards its own end.
        inner = np.ones(count - 2) if count > 1 else np.zeros(0)
        per_segment.append(np.concatenate([pieces, inner, pieces[::-1]]))
    graded = tuple(w.size for w in per_segment)
    return graded, np.concatenate(per_segment)


def _checked_counts(human: HumanSpec, n_intervals: int, counts: Sequence[int]) -> tuple[int, ...]:
    """``segment_counts`` as given, checked against the human constraint's segments."""
    out = tuple(int(c) for c in counts)
    segments = len(human.angles) + 1 if human.kind in ("peak", "phases") else 1
    if len(out) != segments or min(out) < 1 or sum(out) != n_intervals:
        raise BioPlanError(
            f"segment_counts {list(out)}: expected {segments} positive counts summing to "
            f"n_intervals = {n_intervals} (the '{human.kind}' constraint's segments)"
        )
    return out


def _normalised_weights(
    human: HumanSpec, counts: tuple[int, ...], weights: Sequence[float] | None
) -> tuple[float, ...] | None:
    """``interval_weights`` normalised to sum to 1 within each segment (None stays None)."""
    if weights is None:
        return None
    w = np.asarray(weights, dtype=np.float64).ravel()
    n = sum(counts)
    if w.size != n or not np.all(np.isfinite(w)) or np.any(w <= 0.0):
        raise BioPlanError(
            f"interval_weights: expected {n} positive finite relative interval lengths (one per "
            f"interval), got {w.size} values with minimum {float(np.min(w)) if w.size else 0:g}"
        )
    first = np.concatenate([[0], np.cumsum(counts)]).astype(int)
    out = np.concatenate(
        [w[first[s] : first[s + 1]] / w[first[s] : first[s + 1]].sum() for s in range(len(counts))]
    )
    if human.kind == "shape" and np.ptp(w) > 1e-12 * float(np.max(w)):
        # The shape band is cut at the nodes of N equal intervals (node k at time k / N).
        raise BioPlanError(
            "interval_weights: the 'shape' human constraint needs equal intervals "
            "(its band is mapped onto the nodes k / N); expected equal weights"
        )
    return tuple(float(x) for x in out)


def _nlp(problem: _Problem, warm: Trajectory) -> tuple[dict[str, Any], dict[str, Any], Any]:
    """The NLP ({x, p, f, g}), its numeric arguments, and the exact objective f(x, p)."""
    import casadi as ca

    var, cons = _Variables(), _Constraints()
    clearance = None if problem.extra is None else problem.extra.clearance
    points = _n_points(problem)
    faces = 0 if clearance is None else clearance.n_parameters(points)
    par = _Params.create(problem.start.size, faces, problem.n_intervals)
    par.set("fractions", _fractions(problem))
    par.set("start", problem.start)
    par.set("T", problem.duration)
    par.set("p_scale", _power_scale(problem))
    grid, dvar = _build_grid(problem, var, cons, warm, par)
    _bernstein_limits(problem, grid, cons)
    _human_constraints(problem, grid, cons, dvar)
    tau = _torques(problem, grid)
    _torque_limits(problem, cons, tau)
    cost = _objective(problem, grid, var, cons, tau, par)
    _extra_constraints(problem, grid, var, cons, tau, par)
    var.apply_rules(par)
    x = var.vector()
    lbx, ubx, x0 = var.arrays()
    cost_fn = ca.Function("cost", [x, par.sym], [cost])
    ref = abs(float(cost_fn(x0, par.values)))
    par.set("cost_scale", ref if ref > 1e-9 else 1.0)
    f = cost / par["cost_scale"]
    if problem.objective in _NOT_UNIQUE:
        effort = ca.dot(grid.weights, ca.sum1(tau**2))
        effort_ref = float(ca.Function("effort", [x, par.sym], [effort])(x0, par.values))
        par.set("effort_scale", max(effort_ref, 1e-9))
        f = f + REGULARIZATION * effort / par["effort_scale"]
    lbg, ubg = cons.arrays()
    nlp = {"x": x, "p": par.sym, "f": f, "g": cons.vector()}
    args = {"x0": x0, "p": par.values, "lbx": lbx, "ubx": ubx, "lbg": lbg, "ubg": ubg}
    return nlp, args, cost_fn


#: Built IPOPT solvers by problem structure (robot model, objective, constraint, segments,
#: free joints, scales): building one costs more than solving it, and sweeps and repeated plans
#: solve the same structure again with other numbers (start, duration), passed as parameters.
_SOLVERS: dict[tuple[Any, ...], Any] = {}
_SOLVER_CACHE_SIZE = 16


def _structure_key(problem: _Problem) -> tuple[Any, ...]:
    bodies, gravity, _, _ = _chain_key(problem)
    robot = problem.robot
    return (
        bodies,
        gravity,
        np.asarray(robot.tau_max).tobytes(),
        tuple(robot.motors),
        problem.objective,
        problem.human.kind,
        problem.human.band,  # the shape band's edges are coefficients of the constraints
        problem.human.peak_time,
        # The human rules multiply the elbow's speed and acceleration by the stroke's direction
        # inside the graph: a lowering must not reuse a lifting's solver.
        tuple(np.sign(problem.goal - problem.start)),
        problem.counts,
        problem.free,
        tuple(float(problem.start[j]) for j in range(problem.start.size) if j not in problem.free),
        problem.no_reversal,
        _shared_nodes(problem),
        tuple(np.round(_scales(problem), 9)),
        None if problem.extra is None else problem.extra.key(problem.goal),
    )


def _solver(problem: _Problem, nlp: dict[str, Any], max_iterations: int | None = None) -> Any:
    """The IPOPT solver of this problem's structure and iteration cap (built once, reused)."""
    import casadi as ca

    key = (*_structure_key(problem), max_iterations)
    solver = _SOLVERS.get(key)
    if solver is None:
        extra = problem.extra
        warm = extra is not None and extra.warm
        options = {**_IPOPT_OPTIONS, **(_WARM if warm else {})}
        if max_iterations is not None:
            options["ipopt.max_iter"] = max_iterations
        single_threaded_casadi_blas()  # MUMPS's extra BLAS threads only spin
        solver = ca.nlpsol("optimal", "ipopt", nlp, options)
        if len(_SOLVERS) >= _SOLVER_CACHE_SIZE:
            _SOLVERS.pop(next(iter(_SOLVERS)))
        _SOLVERS[key] = solver
    return solver


def solve_optimal(
    robot: Robot,
    start: FloatArray,
    goal: FloatArray,
    duration: float,
    *,
    objective: str,
    human: HumanSpec,
    warm_start: Trajectory | None = None,
    warm_start_name: str = "quintic",
    n_intervals: int = DEFAULT_INTERVALS,
    no_reversal: bool = True,
    report_samples: int = 1000,
    name: str = "optimal",
    explain: bool = True,
    extra: ExtraConstraints | None = None,
    interval_weights: Sequence[float] | None = None,
    segment_counts: Sequence[int] | None = None,
    end_grading: int | None = None,
    max_iterations: int | None = None,
) -> OptimalResult:
    """Solve one optimal-control problem by direct transcription and IPOPT.

    Args:
        robot: the robot with its payload.
        start, goal: (n,) rest configurations [rad] (already validated against the limits).
        duration: motion time [s].
        objective: one of :data:`OPTIMAL_OBJECTIVES`.
        human: the human-likeness constraint (``kind="none"`` for the bound).
        warm_start, warm_start_name: the initial guess (None = the quintic), its name (reported).
        n_intervals: constant-jerk intervals N.
        no_reversal: no joint ever moves against its stroke (joints with start = goal stay put).
        report_samples, name: the returned trajectory's number of samples and name.
        explain: when infeasible, name the shortest feasible duration and the binding limit.
        extra: further constraints: a metric bound, controller limits, actuators' envelopes.
        interval_weights: (N,) relative interval lengths (> 0), normalised within each segment;
            NLP parameters, so one built solver serves every mesh of the same segment counts.
            None = equal; not for ``shape`` (its band is mapped onto the nodes k / N).
        segment_counts: (S,) intervals per segment of the split motion (sum N); None = in
            proportion to the warm start's segment durations. A refined mesh passes its own.
        end_grading: L, each segment's first and last interval cut into L + 1 halving pieces
            (``solver.end_grading``; not with ``interval_weights`` nor ``shape``); None =
            :data:`END_GRADING` capped by :func:`report_resolved_grading`.
        max_iterations: IPOPT's iteration cap (None = 1000), e.g. for a feasibility probe.

    Returns:
        The solution; ``solver.status`` is ``Solve_Succeeded``.

    Raises:
        SolverError: IPOPT found the problem infeasible or did not converge.
        BioPlanError: bad options.
    """
    started = time.perf_counter()
    default = report_resolved_grading(END_GRADING, n_intervals, report_samples)
    grading = default if end_grading is None else end_grading
    _check_options(objective, human, n_intervals, grading, max_iterations)
    start, goal = np.asarray(start, float), np.asarray(goal, float)
    if warm_start is None:
        warm_start, warm_start_name = quintic(start, goal, duration, n_samples=201), "quintic"
    problem = dataclasses.replace(_problem(
        robot, start, goal, duration, objective, human, warm_start, n_intervals, no_reversal,
        interval_weights, segment_counts, grading,
    ), extra=extra)  # fmt: skip
    nlp, args, cost_fn = _nlp(problem, warm_start)
    solver = _solver(problem, nlp, max_iterations)
    sol, stats = solver(**args), solver.stats()
    status = str(stats.get("return_status", "unknown"))
    _raise_unless_solved(status, problem, explain)
    xs = np.asarray(sol["x"], dtype=np.float64).ravel()
    knots, seg_durations = _knots(problem, xs)
    info = SolverInfo(
        status=status, iterations=int(stats.get("iter_count", 0)),
        seconds=time.perf_counter() - started, objective=float(cost_fn(xs, args["p"])),
        warm_start=warm_start_name, n_intervals=problem.asked_intervals,
        human_constraint=human.kind, segment_durations=tuple(float(d) for d in seg_durations),
        end_grading=problem.end_grading,
    )  # fmt: skip
    trajectory = knots.sample(time_grid(duration, report_samples), name=name)
    return OptimalResult(trajectory=trajectory, knots=knots, solver=info)


_IPOPT_OPTIONS: dict[str, Any] = {
    "ipopt.print_level": 0,
    "ipopt.sb": "yes",
    "print_time": False,
    "ipopt.tol": IPOPT_TOL,
    # Feasible solves here take under 700 iterations; an infeasible request with a slack
    # objective runs to this limit before the tau_sq probe settles it (_infeasible).
    "ipopt.max_iter": 1000,
    "ipopt.mu_strategy": "adaptive",
    # MUMPS's fill-reducing ordering: approximate minimum degree. Its automatic choice costs
    # 1.3-1.8x the CPU on the refined peak-power meshes (320 intervals) and saves nothing on
    # the coarse ones (benchmarks/RESULTS.md, "MUMPS ordering").
    "ipopt.mumps_pivot_order": 0,
    # The MX graph calls the (reduced) SX dynamics once, mapped over the points; expanding it
    # to SX evaluates faster but costs more to build than it saves on these problems
    # (measured, curtain_wall_6dof: 3.2 s built + solved unexpanded, 5.3 s expanded).
    # Hessians are exact either way.
    "expand": False,
}


def _raise_unless_solved(status: str, problem: _Problem, explain: bool) -> None:
    """Raise the :class:`SolverError` of IPOPT's ``status`` unless it is ``Solve_Succeeded``
    (``explain``: an infeasible problem's error names the shortest feasible duration)."""
    if status != "Solve_Succeeded":
        infeasible = _infeasible(status, problem)
        hint = _feasible_hint(problem) if infeasible and explain else None
        raise SolverError(
            _failure_message(status, problem, infeasible, hint), infeasible=infeasible
        )


def _knots(problem: _Problem, xs: FloatArray) -> tuple[PiecewiseCubic, FloatArray]:
    """The node states [SI] and the segment durations [s] of a solution vector."""
    free = list(problem.free)
    m, n_nodes, T = len(free), problem.n_intervals + 1, problem.duration
    sc = _scales(problem)[free][:, None]
    blocks = [
        xs[i * m * n_nodes : (i + 1) * m * n_nodes].reshape((m, n_nodes), order="F")
        for i in range(3)
    ]
    segs = len(problem.counts)
    shares = xs[3 * m * n_nodes : 3 * m * n_nodes + segs] if segs > 1 else np.ones(1)
    durations = T * shares / shares.sum()
    node_t = _node_times(problem, durations)
    node_t[-1] = T
    n = problem.start.size
    q = np.tile(problem.start, (n_nodes, 1))
    qd, qdd = np.zeros((n_nodes, n)), np.zeros((n_nodes, n))
    q[:, free] = (blocks[0] * sc).T
    qd[:, free] = (blocks[1] * sc / T).T
    qdd[:, free] = (blocks[2] * sc / T**2).T
    return PiecewiseCubic(t=node_t, q=q, qd=qd, qdd=qdd), durations


def _infeasible(status: str, problem: _Problem) -> bool:
    """Whether the limits cannot be met, not merely that IPOPT did not converge.

    The slack and epigraph objectives make IPOPT wander on an infeasible problem until its
    iteration limit; the smooth ``tau_sq`` problem of the same constraints proves infeasibility
    in a few iterations, so a failure of another objective is settled by one ``tau_sq`` solve.
    """
    if "Infeasible" in status or "Restoration" in status:
        return True
    if problem.objective == "tau_sq":
        return False
    try:
        solve_optimal(
            problem.robot, problem.start, problem.goal, problem.duration, objective="tau_sq",
            human=problem.human, n_intervals=problem.n_intervals,
            no_reversal=problem.no_reversal, report_samples=11, explain=False,
            interval_weights=problem.weights, segment_counts=problem.counts,
            extra=problem.extra,
        )  # fmt: skip
    except SolverError as exc:
        return exc.infeasible
    return False


def _feasible_hint(problem: _Problem) -> str:
    """What is feasible instead: the shortest duration and the limit that binds there."""
    from app.planning.shortest_duration import shortest_feasible_duration

    found = shortest_feasible_duration(
        problem.robot, problem.start, problem.goal, problem.duration, human=problem.human,
        n_intervals=problem.asked_intervals, no_reversal=problem.no_reversal,
    )  # fmt: skip
    return found.describe()


def _failure_message(status: str, problem: _Problem, infeasible: bool, hint: str | None) -> str:
    robot = problem.robot
    what = (
        f"{problem.objective} on {robot.name} in {problem.duration:g} s with "
        f"{robot.payload.mass:g} kg (human constraint {problem.human.kind})"
    )
    if infeasible:
        return (
            f"infeasible: IPOPT found no trajectory for {what} within the joint position, "
            f"velocity and torque limits ({status}): "
            + (hint or "expected a longer duration, a lighter payload or wider limits")
        )
    return f"IPOPT did not converge for {what} ({status}): no result is reported"


def human_spec_peak(
    elbow: int,
    peak_angle: float,
    *,
    near: tuple[float | None, float | None] = (None, None),
    wide: tuple[float | None, float | None] = (None, None),
    drop: float = PEAK_DROP,
) -> HumanSpec:
    """The ``peak`` constraint: one elbow-speed peak where the elbow passes ``peak_angle`` [rad].

    The elbow accelerates until it passes ``peak_angle`` and decelerates after it. Where it
    passes the ``near`` angles [rad] (before, after the peak on the stroke; None = none) its
    speed is at most ``1 - drop`` of the peak speed; between the ``wide`` angles (before, after)
    its acceleration only falls (constant jerk <= 0 along the stroke): the speed is concave
    around the peak, a bell's top, not a spike on a plateau.
    """
    order = (wide[0], near[0], float(peak_angle), near[1], wide[1])
    kept = [i for i, a in enumerate(order) if a is not None]
    angles = tuple(float(order[i]) for i in kept)  # type: ignore[arg-type]
    index = {slot: k for k, slot in enumerate(kept)}
    drop_at = tuple(index[slot] for slot in (1, 3) if slot in index)
    return HumanSpec(
        kind="peak",
        elbow=elbow,
        angles=angles,
        peak_index=index[2],
        peak_drop=float(drop) if drop_at else 0.0,
        drop_at=drop_at,
        concave=(index.get(0, index[2]), index.get(4, index[2])),
    )


def human_spec_shape(
    elbow: int,
    time: Sequence[float],
    lower: Sequence[float],
    upper: Sequence[float],
    peak_time: float,
) -> HumanSpec:
    """The ``shape`` constraint: the elbow speed / its peak inside ``lower``..``upper`` [-] at the
    normalised times ``time`` [-] (each (K,), piecewise linear between them), one peak at
    ``peak_time`` [-] (app.planning.human_constraints.speed_band gives all four)."""
    return HumanSpec(
        kind="shape",
        elbow=elbow,
        band=(
            tuple(float(v) for v in time),
            tuple(float(v) for v in lower),
            tuple(float(v) for v in upper),
        ),
        peak_time=float(peak_time),
    )


def human_spec_phases(
    elbow: int, bound_angles: Sequence[float], share_bounds: Sequence[tuple[float, float]]
) -> HumanSpec:
    """The ``phases`` constraint: phase shares of the duration within ``share_bounds``."""
    return HumanSpec(
        kind="phases",
        elbow=elbow,
        angles=tuple(float(a) for a in bound_angles),
        share_bounds=tuple((float(lo), float(hi)) for lo, hi in share_bounds),
    )
