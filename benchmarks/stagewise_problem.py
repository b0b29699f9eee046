"""The ``bound`` optimal control written stage by stage, for CasADi's ``fatrop`` (experiment).

Benchmark code, not part of the package. Issue 25, item 6 ("Fast"): :mod:`app.planning.optimal`
orders its unknowns as the states of every node, then the segment durations and the objective's
slacks; ``fatrop`` (a Riccati-based interior-point method for optimal-control problems) and
``sqpmethod`` + ``hpipm`` refuse that at build time. This module writes the *same* problem for
the physical bound (no human constraint, one segment of equal intervals, rest to rest, no
reversal) in the order they need:

``w = [x_0, u_0, x_1, u_1, ..., x_{N-1}, u_{N-1}, x_N]`` and
``g = [x_1 - F(x_0, u_0), c_0(x_0, u_0), x_2 - F(x_1, u_1), c_1, ...]``:

* state x_k (scaled as in :mod:`app.planning.optimal`: q / stroke, q̇ T / stroke, q̈ T² / stroke
  of the free joints), plus the peak-power epigraph variable z carried as a constant state
  (z_{k+1} = z_k: a global variable in stage-wise form);
* control u_k: the change of the scaled acceleration over interval k (the constant jerk times
  the interval, O(1) at any N); with ``epigraph="slacks"`` also the per-joint power slacks of
  the interval's points;
* F: the exact constant-jerk integration (linear), so the trajectory family, its node states
  and the optimum are those of ``optimal`` at the same N;
* c_k: the interval's Bernstein limits (velocity, position, no reversal), the torque limits at
  its evaluation points and, for ``peak_power``, the epigraph rows. Each node is constrained
  once (``optimal`` evaluates an interval's end and the next one's start, the same point, twice:
  identical rows that only add degeneracy; the start node's torque, the holding torque at rest,
  is fixed by the task and left out); the objective's quadrature is ``optimal``'s, all
  points included. With fatrop, rest to rest is written as equality rows of the first and last
  stage rather than as bounds with lower = upper.

The physics is the project's: ``optimal``'s reduced symbolic dynamics (the same SX function, or
its compiled C), scales, quadrature points, torque margin, regularisation and guess, reached
through ``optimal``'s private helpers (an experiment beside it, not a second implementation:
``tests/planning/test_stagewise.py`` fails if they drift apart). Supported objectives: ``tau_sq``
and ``peak_power``. Solvers: ``fatrop`` (manual structure) or ``ipopt`` (the same stage-wise NLP,
to see what the formulation alone does for IPOPT). Results: benchmarks/RESULTS.md, "Stage-wise
transcription for fatrop".
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from app.errors import BioPlanError
from app.planning import optimal as _opt
from app.planning.profiles import Trajectory, quintic

if TYPE_CHECKING:
    from app.planning.robots import Robot

__all__ = ["STAGEWISE_OBJECTIVES", "STAGEWISE_SOLVERS", "StagewiseResult", "solve_stagewise"]

FloatArray = NDArray[np.float64]

#: Objectives written stage-wise so far.
STAGEWISE_OBJECTIVES: tuple[str, ...] = ("tau_sq", "peak_power")
#: Solvers of the stage-wise NLP.
STAGEWISE_SOLVERS: tuple[str, ...] = ("fatrop", "ipopt")
#: fatrop's options: IPOPT's tolerance and iteration limit of the project's solves.
_FATROP_OPTIONS: dict[str, Any] = {
    "fatrop.print_level": 0,
    "fatrop.tol": _opt.IPOPT_TOL,
    "fatrop.max_iter": 1000,
    "print_time": False,
}


@dataclass(frozen=True)
class StagewiseResult:
    """A stage-wise solve.

    Attributes:
        knots: the node states (the project's :class:`~app.planning.optimal.PiecewiseCubic`).
        objective: the solver's objective in the metric's unit (Simpson on the evaluation
            points, as ``optimal``'s ``SolverInfo.objective``) [N²m²s or W].
        status: the solver's return status (``Solve_Succeeded`` for IPOPT; fatrop's own, with
            ``success`` true).
        iterations: interior-point iterations.
        build_seconds: building the NLP and the solver [s] (wall).
        solve_seconds: the solve [s] (wall).
        sizes: ``{"nx", "nu", "ng", "N", "variables", "constraints"}``.
    """

    knots: _opt.PiecewiseCubic
    objective: float
    status: str
    iterations: int
    build_seconds: float
    solve_seconds: float
    sizes: dict[str, int]


@dataclass(frozen=True)
class _Layout:
    """Sizes of one stage: m free joints, P constraint points per interval, the peak
    objective's epigraph (``signs``, ``slacks``) or None."""

    m: int
    points: int
    epigraph: str | None

    @property
    def peak(self) -> bool:
        return self.epigraph is not None

    @property
    def nx(self) -> int:
        return 3 * self.m + (1 if self.peak else 0)

    @property
    def nu(self) -> int:
        return self.m + (self.m * self.points if self.epigraph == "slacks" else 0)


class StagewiseProblem:
    """The stage-wise NLP of one task (build once, :meth:`solve` as often as wanted).

    Args:
        robot: the robot with its payload.
        start, goal: (n,) rest configurations [rad].
        duration: motion time T [s].
        objective: ``tau_sq`` or ``peak_power``.
        n_intervals: constant-jerk intervals N (>= 8).
        warm_start: the initial guess (None: the quintic).
        solver: ``fatrop`` or ``ipopt``.
        no_reversal: no joint moves against its stroke; joints with start = goal stay put.
        epigraph: how ``peak_power``'s Σ_j |τ_j q̇_j| <= z is written: ``signs`` (one row
            Σ_j σ_j τ_j q̇_j <= z per sign vector σ, 2^m rows per point, no slacks) or
            ``slacks`` (``optimal``'s form: s_j >= ±τ_j q̇_j, Σ_j s_j <= z, the slacks as
            controls). The same feasible set and optimum.
        z_start: ``peak_power``: the epigraph variable starts at this multiple of the guess's
            peak (1: just above it, as ``optimal`` starts it; the objective's scale is taken
            at 1 either way) [-].
        compile_dynamics: evaluate the per-point dynamics and its derivatives as C compiled
            by the system compiler (``optimal``'s cached ``_compiled`` function), the stage
            function an MX graph calling it; False: the SX dynamics inlined in each stage.
    """

    def __init__(
        self,
        robot: Robot,
        start: FloatArray,
        goal: FloatArray,
        duration: float,
        *,
        objective: str,
        n_intervals: int,
        warm_start: Trajectory | None = None,
        solver: str = "fatrop",
        no_reversal: bool = True,
        epigraph: str = "signs",
        z_start: float = 1.0,
        compile_dynamics: bool = False,
    ) -> None:
        _check(objective, solver, n_intervals, epigraph)
        self.z_start = float(z_start)
        self.compile_dynamics = compile_dynamics
        started = time.perf_counter()
        start, goal = np.asarray(start, float), np.asarray(goal, float)
        moving = np.abs(goal - start) > 0
        free = tuple(int(j) for j in range(start.size) if moving[j] or not no_reversal)
        human = _opt.HumanSpec("none", robot.elbow_joint)
        self.problem = _opt._Problem(
            robot, start, goal, duration, objective, human, free, no_reversal, (n_intervals,)
        )
        rule = _opt._EIGHTHS if objective in _opt._PEAK_OBJECTIVES else _opt._QUARTERS
        self.rule = rule
        # Constraint points per interval: the quadrature's, less its start (the previous end).
        self.layout = _Layout(
            len(free), len(rule[0]) - 1, epigraph if objective == "peak_power" else None
        )
        self.solver_name = solver
        self.ends_as_rows = solver == "fatrop"
        warm = warm_start if warm_start is not None else quintic(start, goal, duration)
        self._build(warm)
        self.build_seconds = time.perf_counter() - started

    # -- building ------------------------------------------------------------------------------

    def _stage_function(self) -> Any:
        """``(x_k, u_k, T) -> (F(x_k, u_k), c_k, cost_k, effort_k, |power_k|)`` (SX or MX)."""
        import casadi as ca

        prob, lay = self.problem, self.layout
        m, n_int = lay.m, prob.n_intervals
        # MX when the per-point dynamics is compiled C (it cannot be inlined into SX).
        kind: Any = ca.MX if self.compile_dynamics else ca.SX
        x: Any = kind.sym("x", lay.nx)
        u: Any = kind.sym("u", lay.nu)
        t_sym: Any = kind.sym("T")
        q, v, a, w = x[:m], x[m : 2 * m], x[2 * m : 3 * m], u[:m]
        d = 1.0 / n_int  # interval length in normalised time
        q1 = q + v * d + a * d**2 / 2 + w * d**2 / 6
        v1 = v + a * d + w * d / 2
        nxt = [q1, v1, a + w] + ([x[3 * m]] if lay.peak else [])
        rows, lo, hi = self._bernstein(q, v, a, q1, v1)
        tau, qd_pts = self._point_torques(q, v, a, w, t_sym)
        _, simpson, divisor = self.rule
        weights = ca.DM([s / divisor for s in simpson]).T * t_sym * d  # (1, P) [s]
        effort = ca.dot(weights, ca.sum1(tau**2))
        # The limits hold where the quadrature evaluates, but each node only once: the start
        # of interval k is the end of interval k-1 (duplicate rows are degenerate for fatrop).
        tau_c, qd_c = tau[:, 1:], qd_pts[:, 1:]
        ratio = tau_c / ca.repmat(ca.DM(prob.robot.tau_max), 1, lay.points)
        margin = 1.0 - _opt.TORQUE_MARGIN
        rows.append(ca.vec(ratio))
        lo.append(np.full(ratio.numel(), -margin))
        hi.append(np.full(ratio.numel(), margin))
        free = list(prob.free)
        power = tau_c[free, :] * qd_c  # (m, P) [W]
        cost = effort
        if lay.peak:
            for expr in self._epigraph_rows(power / self.p_scale, x[3 * m], u[m:]):
                rows.append(ca.vec(expr))
                lo.append(np.zeros(expr.numel()))
                hi.append(np.full(expr.numel(), np.inf))
            cost = 0 * t_sym  # the epigraph variable, on the last state (:meth:`_build`)
        self.path_lower, self.path_upper = np.concatenate(lo), np.concatenate(hi)
        out = [ca.vertcat(*nxt), ca.vertcat(*rows), cost, effort, ca.vec(ca.fabs(power))]
        return ca.Function("stage", [x, u, t_sym], out)

    def _epigraph_rows(self, scaled: Any, z: Any, slacks: Any) -> list[Any]:
        """Rows >= 0 that say Σ_j |scaled_j| <= z at every point ((m, P) scaled powers)."""
        import itertools

        import casadi as ca

        lay = self.layout
        if lay.epigraph == "slacks":
            slack = ca.reshape(slacks, lay.m, lay.points)
            return [slack - scaled, slack + scaled, z - ca.sum1(slack)]
        signs = np.array(list(itertools.product((1.0, -1.0), repeat=lay.m)))  # (2^m, m)
        return [z - ca.mtimes(ca.DM(signs), scaled)]

    def _bernstein(self, q: Any, v: Any, a: Any, q1: Any, v1: Any) -> tuple[list[Any], ...]:
        """Velocity and position Bernstein coefficients of one interval (scaled), with bounds."""
        prob = self.problem
        free, d = list(prob.free), 1.0 / prob.n_intervals
        scales = _opt._scales(prob)[free]
        vmax = prob.robot.qd_max[free] * prob.duration / scales
        vlo, vhi = -vmax, vmax.copy()
        if prob.no_reversal:
            direction = np.sign(prob.goal - prob.start)[free]
            vlo, vhi = np.where(direction > 0, 0.0, vlo), np.where(direction < 0, 0.0, vhi)
        qlo, qhi = prob.robot.q_min[free] / scales, prob.robot.q_max[free] / scales
        rows = [v + a * d / 2, q + v * d / 3, q1 - v1 * d / 3]
        return rows, [vlo, qlo, qlo], [vhi, qhi, qhi]

    def _point_torques(self, q: Any, v: Any, a: Any, w: Any, t_sym: Any) -> tuple[Any, Any]:
        """(n, P) torques [Nm] and (m, P) free-joint speeds [rad/s] at the interval's points."""
        import casadi as ca

        prob = self.problem
        free = list(prob.free)
        sc = ca.DM(_opt._scales(prob)[free])
        d = 1.0 / prob.n_intervals
        compiled = _opt._compiled(prob) if self.compile_dynamics else None
        fn = compiled if compiled is not None else _opt._reduced_dynamics(prob)
        cols: list[list[Any]] = [[], [], []]
        for frac in self.rule[0]:
            s = frac * d
            cols[0].append(q + v * s + a * s**2 / 2 + w / d * s**3 / 6)
            cols[1].append(v + a * s + w / d * s**2 / 2)
            cols[2].append(a + w / d * s)
        qp, vp, ap = (ca.horzcat(*c) for c in cols)
        scale = ca.repmat(sc, 1, len(self.rule[0]))
        qd_pts = vp * scale / t_sym
        tau = fn.map(len(self.rule[0]))(qp * scale, qd_pts, ap * scale / t_sym**2)
        return tau, qd_pts

    def _build(self, warm: Trajectory) -> None:
        """The NLP in stage order, its bounds and guess, and the solver."""
        import casadi as ca

        prob, lay = self.problem, self.layout
        n_int = prob.n_intervals
        self.p_scale = _opt._power_scale(prob)
        stage = self._stage_function()
        width = lay.nx + lay.nu
        wsym = ca.MX.sym("w", n_int * width + lay.nx)
        t_par = ca.MX.sym("T")
        cols = ca.reshape(wsym[: n_int * width], width, n_int)
        x_last = wsym[n_int * width :]
        nxt, path, cost, effort, _ = stage.map(n_int)(cols[: lay.nx, :], cols[lay.nx :, :], t_par)
        x_next = ca.horzcat(cols[: lay.nx, 1:], x_last)
        blocks = ca.vertcat(x_next - nxt, path)
        self.ng = int(path.shape[0])
        lbx, ubx, x0 = self._bounds_and_guess(warm, stage)
        lbg = np.tile(np.concatenate([np.zeros(lay.nx), self.path_lower]), n_int)
        ubg = np.tile(np.concatenate([np.zeros(lay.nx), self.path_upper]), n_int)
        if self.ends_as_rows:
            # Rest to rest as equality rows of the first and last stage, not as bounds with
            # lower = upper (IPOPT removes fixed variables; for fatrop, measured on peak_power:
            # the same iterations either way, so this is not what it struggles with).
            fixed = 3 * lay.m
            first, last = x0[:fixed], x0[-lay.nx :][:fixed]
            g = ca.vertcat(blocks[:, 0], cols[:fixed, 0], ca.vec(blocks[:, 1:]), x_last[:fixed])
            split = lay.nx + self.ng
            lbg = np.concatenate([lbg[:split], first, lbg[split:], last])
            ubg = np.concatenate([ubg[:split], first, ubg[split:], last])
            for index in (*range(fixed), *range(lbx.size - lay.nx, lbx.size - lay.nx + fixed)):
                lbx[index], ubx[index] = -np.inf, np.inf
        else:
            g = ca.vec(blocks)
        self.args: dict[str, Any] = {
            "x0": x0,
            "lbx": lbx,
            "ubx": ubx,
            "p": prob.duration,
            "lbg": lbg,
            "ubg": ubg,
        }
        total_cost = ca.sum2(cost)
        if lay.peak:
            total_cost = self.p_scale * x_last[3 * lay.m]
        self.cost_fn = ca.Function("cost", [wsym, t_par], [total_cost])
        effort_fn = ca.Function("effort", [wsym, t_par], [ca.sum2(effort)])
        cost_scale = abs(float(self.cost_fn(x0, prob.duration)))
        if lay.peak:  # the epigraph variable may start above the guess's peak
            x0[-1] *= self.z_start
            x0[3 * lay.m : n_int * width : width] = x0[-1]
        f = total_cost / (cost_scale if cost_scale > 1e-9 else 1.0)
        if lay.peak:
            effort_scale = max(float(effort_fn(x0, prob.duration)), 1e-9)
            f = f + _opt.REGULARIZATION * ca.sum2(effort) / effort_scale
        self.nlp = {"x": wsym, "p": t_par, "f": f, "g": g}
        self.solver = self._solver(self.nlp)

    def _solver(self, nlp: dict[str, Any]) -> Any:
        import casadi as ca

        lay, n_int = self.layout, self.problem.n_intervals
        if self.solver_name == "ipopt":
            return ca.nlpsol("stagewise", "ipopt", nlp, dict(_opt._IPOPT_OPTIONS))
        structure: dict[str, Any] = {
            "structure_detection": "manual",
            "N": n_int,
            "nx": [lay.nx] * (n_int + 1),
            "nu": [lay.nu] * n_int + [0],
            "ng": [self.ng + 3 * lay.m] + [self.ng] * (n_int - 1) + [3 * lay.m],
        }
        return ca.nlpsol("stagewise", "fatrop", nlp, {**_FATROP_OPTIONS, **structure})

    def _bounds_and_guess(
        self, warm: Trajectory, stage: Any
    ) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Bounds and guess of w, stage by stage (the project's node bounds and guess)."""
        prob, lay = self.problem, self.layout
        free, n_int, T = list(prob.free), prob.n_intervals, prob.duration
        sc = _opt._scales(prob)[free]
        node_t = np.linspace(0.0, T, n_int + 1)
        q0, qd0, qdd0 = _opt._node_guess(warm, node_t)
        guess = np.hstack([q0[:, free] / sc, qd0[:, free] * T / sc, qdd0[:, free] * T**2 / sc])
        guess[0, : lay.m] = prob.start[free] / sc
        guess[-1, : lay.m] = prob.goal[free] / sc
        guess[[0, -1], lay.m :] = 0.0
        robot = prob.robot
        lo_q = np.where(np.isfinite(robot.q_min[free]), robot.q_min[free], -1e3) / sc
        hi_q = np.where(np.isfinite(robot.q_max[free]), robot.q_max[free], 1e3) / sc
        vmax = robot.qd_max[free] * T / sc
        vlo, vhi = -vmax, vmax.copy()
        if prob.no_reversal:
            direction = np.sign(prob.goal - prob.start)[free]
            vlo, vhi = np.where(direction > 0, 0.0, vlo), np.where(direction < 0, 0.0, vhi)
        xlo = np.tile(np.concatenate([lo_q, vlo, np.full(lay.m, -np.inf)]), (n_int + 1, 1))
        xhi = np.tile(np.concatenate([hi_q, vhi, np.full(lay.m, np.inf)]), (n_int + 1, 1))
        for row, value in ((0, guess[0]), (-1, guess[-1])):
            xlo[row], xhi[row] = value, value
        controls = np.diff(guess[:, 2 * lay.m :], axis=0)  # (N, m): Δ scaled acceleration
        if lay.peak:
            controls, guess, xlo, xhi = self._epigraph_guess(stage, guess, controls, xlo, xhi)
        ulo = np.tile(np.r_[np.full(lay.m, -np.inf), np.zeros(lay.nu - lay.m)], (n_int, 1))
        uhi = np.full((n_int, lay.nu), np.inf)
        return (
            _interleave(xlo, ulo),
            _interleave(xhi, uhi),
            _interleave(guess, controls),
        )

    def _epigraph_guess(
        self, stage: Any, guess: FloatArray, controls: FloatArray, xlo: FloatArray, xhi: Any
    ) -> tuple[FloatArray, ...]:
        """Slacks and z start on their bounds at the guess (+1e-6), as ``optimal`` starts them."""
        lay, n_int, T = self.layout, self.problem.n_intervals, self.problem.duration
        extra = np.zeros((n_int, lay.nu - lay.m))
        x_aug = np.hstack([guess, np.zeros((n_int + 1, 1))])
        u_aug = np.hstack([controls, extra])
        out = stage.map(n_int)(x_aug[:-1].T, u_aug.T, T)
        power = np.asarray(out[4], dtype=np.float64).T / self.p_scale  # (N, m P)
        z0 = float(power.reshape(n_int, lay.points, lay.m).sum(axis=2).max()) + 1e-6
        x_aug[:, -1] = z0
        if lay.epigraph == "slacks":
            u_aug[:, lay.m :] = power + 1e-6
        inf = np.full((n_int + 1, 1), np.inf)
        return u_aug, x_aug, np.hstack([xlo, np.zeros_like(inf)]), np.hstack([xhi, inf])

    # -- solving -------------------------------------------------------------------------------

    def solve(self) -> StagewiseResult:
        """Solve from the guess; raise :class:`~app.planning.optimal.SolverError` on failure."""
        started = time.perf_counter()
        sol = self.solver(**self.args)
        seconds = time.perf_counter() - started
        stats = self.solver.stats()
        status = str(stats.get("return_status", "unknown"))
        if not stats.get("success", False):
            raise _opt.SolverError(
                f"{self.solver_name} did not solve the stage-wise {self.problem.objective} "
                f"bound on {self.problem.robot.name} (status {status} after "
                f"{int(stats.get('iter_count', 0))} iterations): no result is reported"
            )
        ws = np.asarray(sol["x"], dtype=np.float64).ravel()
        return StagewiseResult(
            knots=self._knots(ws),
            objective=float(self.cost_fn(ws, self.problem.duration)),
            status=status,
            iterations=int(stats.get("iter_count", 0)),
            build_seconds=self.build_seconds,
            solve_seconds=seconds,
            sizes={
                "nx": self.layout.nx, "nu": self.layout.nu, "ng": self.ng,
                "N": self.problem.n_intervals, "variables": ws.size,
                "constraints": self.args["lbg"].size,
            },
        )  # fmt: skip

    def _knots(self, ws: FloatArray) -> _opt.PiecewiseCubic:
        prob, lay = self.problem, self.layout
        n_int, T, m = prob.n_intervals, prob.duration, lay.m
        width = lay.nx + lay.nu
        states = np.vstack([ws[: n_int * width].reshape(n_int, width)[:, : lay.nx], ws[-lay.nx :]])
        free = list(prob.free)
        sc = _opt._scales(prob)[free]
        n_nodes = n_int + 1
        q = np.tile(prob.start, (n_nodes, 1))
        qd, qdd = np.zeros_like(q), np.zeros_like(q)
        q[:, free] = states[:, :m] * sc
        qd[:, free] = states[:, m : 2 * m] * sc / T
        qdd[:, free] = states[:, 2 * m : 3 * m] * sc / T**2
        return _opt.PiecewiseCubic(t=np.linspace(0.0, T, n_nodes), q=q, qd=qd, qdd=qdd)


def _interleave(states: FloatArray, controls: FloatArray) -> FloatArray:
    """[x_0, u_0, x_1, u_1, ..., x_N] from (N+1, nx) states and (N, nu) controls."""
    body = np.hstack([states[:-1], controls]).ravel()
    return np.concatenate([body, states[-1]])


def _check(objective: str, solver: str, n_intervals: int, epigraph: str) -> None:
    if epigraph not in ("signs", "slacks"):
        raise BioPlanError(f"unknown epigraph {epigraph!r}: expected signs or slacks")
    if objective not in STAGEWISE_OBJECTIVES:
        raise BioPlanError(
            f"stage-wise objective {objective!r} not written: expected one of "
            f"{', '.join(STAGEWISE_OBJECTIVES)}"
        )
    if solver not in STAGEWISE_SOLVERS:
        raise BioPlanError(
            f"unknown stage-wise solver {solver!r}: expected one of {', '.join(STAGEWISE_SOLVERS)}"
        )
    if n_intervals < 8:
        raise BioPlanError(f"n_intervals must be >= 8, got {n_intervals}")


def solve_stagewise(
    robot: Robot,
    start: FloatArray,
    goal: FloatArray,
    duration: float,
    *,
    objective: str,
    n_intervals: int = _opt.DEFAULT_INTERVALS,
    warm_start: Trajectory | None = None,
    solver: str = "fatrop",
    no_reversal: bool = True,
    epigraph: str = "signs",
    z_start: float = 1.0,
    compile_dynamics: bool = False,
) -> StagewiseResult:
    """Build and solve the stage-wise ``bound`` (see :class:`StagewiseProblem`)."""
    return StagewiseProblem(
        robot, start, goal, duration, objective=objective, n_intervals=n_intervals,
        warm_start=warm_start, solver=solver, no_reversal=no_reversal, epigraph=epigraph,
        z_start=z_start, compile_dynamics=compile_dynamics,
    ).solve()  # fmt: skip
