"""Particle swarm optimisation with batched evaluation and feasibility rules.

A global-best PSO (Kennedy & Eberhart 1995) with a linearly decreasing inertia weight
(Shi & Eberhart 1998). The whole swarm is evaluated in one call per iteration, so the cost
function can vectorise over particles (the planner evaluates 40 trajectories' dynamics at once).

Constraints are handled by Deb's feasibility rules, no penalty weights: a feasible point beats
an infeasible one, two feasible points compare by cost, two infeasible ones by violation (then
by cost). Non-finite costs (and NaN violations) count as infeasible with infinite violation.

Motion: v <- w v + c1 r1 (p_best - x) + c2 r2 (g_best - x) with r1, r2 ~ U(0, 1) per
component; w falls linearly from ``inertia[0]`` at the first move to ``inertia[1]`` at the last;
each velocity component is clamped to ±velocity_clamp (upper - lower). Positions are clipped to
the box and the velocity components that hit a wall are set to zero (absorbing walls), so
particles never leave the box.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from app.errors import BioPlanError

FloatArray = NDArray[np.float64]
CostFunction = Callable[[FloatArray], FloatArray | tuple[FloatArray, FloatArray]]


@dataclass(frozen=True, eq=False)
class PSOResult:
    """The outcome of :func:`pso_minimize`.

    Attributes:
        best_position: (D,) the best particle position found.
        best_cost: its cost.
        best_violation: its constraint violation (0 = feasible).
        history: (iterations,) the incumbent's cost after each iteration.
        iterations: iterations run (swarm evaluations), at most the requested number.
        evaluations: cost evaluations, particles x iterations.
        seconds: wall time [s].
        seed: the seed used.
        stopped_early: True when stagnation stopped the run before its last iteration.
    """

    best_position: FloatArray
    best_cost: float
    best_violation: float
    history: FloatArray
    iterations: int
    evaluations: int
    seconds: float
    seed: int
    stopped_early: bool

    @property
    def feasible(self) -> bool:
        return self.best_violation == 0.0


def _evaluate(fn: CostFunction, x: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Call the cost on the whole swarm; non-finite costs become infeasible (violation inf)."""
    n = x.shape[0]
    out = fn(x.copy())  # a copy: the cost function must not be able to move the swarm
    if isinstance(out, tuple):
        if len(out) != 2:
            raise BioPlanError(
                f"the cost function must return cost (P,) or (cost (P,), violation (P,)); "
                f"got a tuple of {len(out)}"
            )
        cost = np.asarray(out[0], dtype=np.float64)
        viol = np.asarray(out[1], dtype=np.float64)
    else:
        cost = np.asarray(out, dtype=np.float64)
        viol = np.zeros(n)
    if cost.shape != (n,) or viol.shape != (n,):
        raise BioPlanError(
            f"the cost function must return arrays of shape ({n},) for {n} particles, got cost "
            f"{cost.shape} and violation {viol.shape}"
        )
    if np.any(viol < 0.0):
        raise BioPlanError(
            f"constraint violations must be >= 0 (0 = feasible), got min {viol.min():.6g}"
        )
    bad = ~np.isfinite(cost) | np.isnan(viol)
    if np.any(bad):
        cost = np.where(bad, np.inf, cost)
        viol = np.where(bad, np.inf, viol)
    return cost, viol


def _better(c1: FloatArray, v1: FloatArray, c2: FloatArray, v2: FloatArray) -> NDArray[np.bool_]:
    """Deb's feasibility rules as a lexicographic order on (violation, cost): strictly better."""
    result: NDArray[np.bool_] = (v1 < v2) | ((v1 == v2) & (c1 < c2))
    return result


def _check_vector(label: str, value: ArrayLike) -> FloatArray:
    arr = np.asarray(value, dtype=np.float64)
    if arr.ndim != 1 or arr.size == 0 or not np.all(np.isfinite(arr)):
        raise BioPlanError(f"{label} must be a finite 1-D array (D,), got shape {arr.shape}")
    return arr


def _move(
    rng: np.random.Generator,
    x: FloatArray,
    v: FloatArray,
    p_x: FloatArray,
    g_x: FloatArray,
    weights: tuple[float, float, float],
    v_max: FloatArray,
    box: tuple[FloatArray, FloatArray],
) -> tuple[FloatArray, FloatArray]:
    """One swarm move: new positions and velocities (absorbing walls at the box)."""
    w, cognitive, social = weights
    lo, hi = box
    r1 = rng.random(x.shape)
    r2 = rng.random(x.shape)
    v = w * v + cognitive * r1 * (p_x - x) + social * r2 * (g_x - x)
    np.clip(v, -v_max, v_max, out=v)
    x = x + v
    hit = (x < lo) | (x > hi)
    np.clip(x, lo, hi, out=x)
    v[hit] = 0.0
    return x, v


def _check_options(
    lower: ArrayLike,
    upper: ArrayLike,
    particles: int,
    iterations: int,
    cognitive: float,
    social: float,
    velocity_clamp: float,
    stagnation_iterations: int | None,
    stagnation_tol: float,
) -> tuple[FloatArray, FloatArray]:
    """The checked bounds (D,) of :func:`pso_minimize`; a one-line error for bad options."""
    lo = _check_vector("lower", lower)
    hi = _check_vector("upper", upper)
    if lo.shape != hi.shape or not np.all(hi > lo):
        raise BioPlanError(
            f"lower and upper must have the same shape (D,) with upper > lower, got "
            f"{lo.tolist()} and {hi.tolist()}"
        )
    if particles < 1 or iterations < 1:
        raise BioPlanError(f"particles and iterations must be >= 1, got {particles}, {iterations}")
    if cognitive < 0 or social < 0 or not velocity_clamp > 0:
        raise BioPlanError(
            "cognitive and social must be >= 0 and velocity_clamp > 0, got "
            f"{cognitive}, {social}, {velocity_clamp}"
        )
    if stagnation_iterations is not None and stagnation_iterations < 1:
        raise BioPlanError(
            f"stagnation_iterations must be >= 1 or None, got {stagnation_iterations}"
        )
    if not stagnation_tol >= 0:
        raise BioPlanError(f"stagnation_tol must be >= 0, got {stagnation_tol}")

    return lo, hi


def _initial_swarm(
    rng: np.random.Generator,
    box: tuple[FloatArray, FloatArray],
    particles: int,
    v_max: FloatArray,
    initial: ArrayLike | None,
) -> tuple[FloatArray, FloatArray]:
    """Positions (P, D) uniform in the box (particle 0 at ``initial``) and velocities (P, D)."""
    lo, hi = box
    x = lo + rng.random((particles, lo.size)) * (hi - lo)
    if initial is not None:
        x0 = _check_vector("initial", initial)
        if x0.shape != lo.shape:
            raise BioPlanError(f"initial must have shape {lo.shape}, got {x0.shape}")
        x[0] = np.clip(x0, lo, hi)
    v = (2.0 * rng.random((particles, lo.size)) - 1.0) * v_max
    return x, v


def _significant(
    old_cost: float, old_viol: float, new_cost: float, new_viol: float, tol: float
) -> bool:
    """Whether the incumbent moved enough to reset the stagnation count (see ``pso_minimize``)."""
    gain = old_cost - new_cost
    return new_viol < old_viol or (
        new_viol == old_viol
        and gain > 0.0
        and (not np.isfinite(old_cost) or gain > tol * abs(old_cost))
    )


@dataclass(eq=False)
class _Swarm:
    """The mutable swarm: positions ``x`` and velocities ``v`` (P, D), each particle's best
    position ``p_x`` (P, D) with its cost and violation ``p_cost``, ``p_viol`` (P,), and the
    incumbent (the best of the personal bests) ``g_x`` (D,), ``g_cost``, ``g_viol``."""

    x: FloatArray
    v: FloatArray
    p_x: FloatArray
    p_cost: FloatArray
    p_viol: FloatArray
    g_x: FloatArray
    g_cost: float
    g_viol: float

    @classmethod
    def start(cls, x: FloatArray, v: FloatArray, cost: FloatArray, viol: FloatArray) -> _Swarm:
        """The swarm after its first evaluation: every particle is its own best."""
        g = int(np.lexsort((cost, viol))[0])
        return cls(x, v, x.copy(), cost, viol, x[g].copy(), float(cost[g]), float(viol[g]))

    def record(self, cost: FloatArray, viol: FloatArray, tol: float) -> bool:
        """Take the costs (P,) and violations (P,) of the current positions into the personal
        bests and the incumbent; True when the incumbent improved significantly (relative
        ``tol``, see :func:`_significant`)."""
        improved = _better(cost, viol, self.p_cost, self.p_viol)
        self.p_x[improved] = self.x[improved]
        self.p_cost = np.where(improved, cost, self.p_cost)
        self.p_viol = np.where(improved, viol, self.p_viol)
        g = int(np.lexsort((self.p_cost, self.p_viol))[0])
        new_cost, new_viol = float(self.p_cost[g]), float(self.p_viol[g])
        significant = _significant(self.g_cost, self.g_viol, new_cost, new_viol, tol)
        if new_viol < self.g_viol or (new_viol == self.g_viol and new_cost < self.g_cost):
            self.g_x, self.g_cost, self.g_viol = self.p_x[g].copy(), new_cost, new_viol
        return significant


@dataclass(frozen=True)
class _Motion:
    """The motion coefficients: inertia (start, end) and the weights c1, c2."""

    inertia: tuple[float, float]
    cognitive: float
    social: float

    def weights(self, move: int, n_moves: int) -> tuple[float, float, float]:
        """(w, c1, c2) for move ``move`` (1-based) of ``n_moves``: w falls linearly."""
        w_start, w_end = self.inertia
        w = w_start if n_moves <= 1 else w_start + (w_end - w_start) * (move - 1) / (n_moves - 1)
        return w, self.cognitive, self.social


def _iterate(
    fn: CostFunction,
    swarm: _Swarm,
    rng: np.random.Generator,
    iterations: int,
    box: tuple[FloatArray, FloatArray],
    v_max: FloatArray,
    motion: _Motion,
    stagnation_iterations: int | None,
    stagnation_tol: float,
    callback: Callable[[int, float], None] | None,
) -> tuple[FloatArray, bool]:
    """The iterations of :func:`pso_minimize` after the swarm's first evaluation: move,
    evaluate, record, until ``iterations`` or stagnation. Returns the incumbent's cost after each
    iteration done (done,) and whether stagnation stopped the run before its last iteration."""
    history = np.empty(iterations)
    history[0] = swarm.g_cost
    if callback is not None:
        callback(1, swarm.g_cost)
    stall = 0
    for it in range(1, iterations):
        swarm.x, swarm.v = _move(
            rng, swarm.x, swarm.v, swarm.p_x, swarm.g_x,
            motion.weights(it, iterations - 1), v_max, box,
        )  # fmt: skip
        significant = swarm.record(*_evaluate(fn, swarm.x), stagnation_tol)
        history[it] = swarm.g_cost
        if callback is not None:
            callback(it + 1, swarm.g_cost)
        stall = 0 if significant else stall + 1
        if stagnation_iterations is not None and stall >= stagnation_iterations:
            return history[: it + 1].copy(), it + 1 < iterations
    return history, False


def pso_minimize(
    fn: CostFunction,
    lower: ArrayLike,
    upper: ArrayLike,
    *,
    particles: int = 40,
    iterations: int = 100,
    seed: int = 0,
    inertia: tuple[float, float] = (0.9, 0.4),
    cognitive: float = 1.5,
    social: float = 1.5,
    velocity_clamp: float = 0.2,
    stagnation_iterations: int | None = 20,
    stagnation_tol: float = 1e-9,
    callback: Callable[[int, float], None] | None = None,
    initial: ArrayLike | None = None,
) -> PSOResult:
    """Minimise ``fn`` over the box [lower, upper] with a global-best particle swarm.

    Each iteration evaluates the whole swarm in one call, ``fn(X)`` with X (P, D), which returns
    the costs (P,) or ``(cost (P,), violation (P,))`` with violation >= 0 and 0 meaning feasible.
    Iteration 1 evaluates the initial swarm (uniform in the box; particle 0 at ``initial`` when
    given); each later iteration first moves the swarm, then evaluates it, so exactly
    ``particles * iterations`` evaluations are made (as pyswarms counts them).

    Constraints follow Deb's feasibility rules and the motion has absorbing walls (see the
    module docstring). ``history`` records the incumbent's cost, which never increases once a
    feasible point exists (before that it follows the least-violating point).

    Args:
        fn: the batched cost, (P, D) -> (P,) or ((P,), (P,)); it receives a copy of the swarm.
        lower: (D,) lower bounds.
        upper: (D,) upper bounds, > lower.
        particles: swarm size P >= 1.
        iterations: maximum number of iterations (swarm evaluations) >= 1.
        seed: random seed, the only source of randomness (``np.random.default_rng(seed)``): the
            same inputs and seed give the same result bit for bit (except ``seconds``).
        inertia: (start, end) inertia weights.
        cognitive: c1, attraction to the particle's own best, >= 0.
        social: c2, attraction to the swarm's best, >= 0.
        velocity_clamp: maximum speed per component per iteration, fraction of box width, > 0.
        stagnation_iterations: stop early after this many consecutive iterations in which the
            incumbent neither lowers its violation nor improves its cost by more than
            ``stagnation_tol * |cost|``; None disables early stopping.
        stagnation_tol: relative improvement regarded as significant, >= 0.
        callback: called after every iteration with (iterations done, incumbent cost).
        initial: (D,) a known solution placed as particle 0 (clipped to the box).

    Returns:
        The best point found with its cost, violation and the convergence history.

    Raises:
        BioPlanError: bad bounds or options, or a cost function that returns the wrong shapes
            or negative violations.
    """
    lo, hi = _check_options(
        lower, upper, particles, iterations, cognitive, social, velocity_clamp,
        stagnation_iterations, stagnation_tol,
    )  # fmt: skip
    started = time.perf_counter()
    rng = np.random.default_rng(seed)
    v_max = velocity_clamp * (hi - lo)
    x, v = _initial_swarm(rng, (lo, hi), particles, v_max, initial)
    swarm = _Swarm.start(x, v, *_evaluate(fn, x))
    motion = _Motion((float(inertia[0]), float(inertia[1])), cognitive, social)
    history, stopped_early = _iterate(
        fn, swarm, rng, iterations, (lo, hi), v_max, motion,
        stagnation_iterations, stagnation_tol, callback,
    )  # fmt: skip
    return PSOResult(
        best_position=swarm.g_x,
        best_cost=swarm.g_cost,
        best_violation=swarm.g_viol,
        history=history,
        iterations=history.size,
        evaluations=history.size * particles,
        seconds=time.perf_counter() - started,
        seed=seed,
        stopped_early=stopped_early,
    )
