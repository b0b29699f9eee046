"""Identification of a robot's inertial parameters and friction from logs, and validation.

The rigid-body torque is linear in the 10 inertial parameters of each body (Pinocchio's order:
m, m c, I about the joint origin in the joint frame): τ = Y(q, q̇, q̈) θ, with Y from
``pin.computeJointTorqueRegressor``. Per joint j a friction and offset model is added:
τ_f = b_j q̇_j + c_j tanh(q̇_j / ε) + o_j (ε as in the energy model).

Steps of :func:`identify`:

1. Each log is matched to the robot's joints and filtered with a zero-phase Butterworth filter
   (4th order, ``filtfilt``, default cutoff :data:`DEFAULT_CUTOFF_HZ`; no delay): positions (or
   logged velocities) and torques alike; velocities and accelerations are central differences of
   the filtered signals. The last ``validate_fraction`` of each log is held back.
2. Y is stacked over the samples (decimated to about 10 samples per cutoff period), and reduced
   to the identifiable *base parameters* by QR with column pivoting: β = θ_1 + K θ_2.
3. Least squares on the base parameters (:attr:`Identification.base_parameters`), then a
   physically consistent fit: every link's parameters through the log-Cholesky factor of its
   pseudo-inertia (Rucker & Wensing 2022: positive mass, positive-definite inertia obeying the
   triangle inequality by construction), friction b, c >= 0, solved with
   ``scipy.optimize.least_squares`` on the QR-compressed problem, with a weak pull towards the
   URDF's values (the directions the motion does not excite keep the URDF's values).

With ``identify_payload`` the links keep their values (the URDF's, or a sidecar's identified
ones) and a point payload (mass >= 0, centre of mass in the payload body's frame) is identified
with the friction: a payload trades off against the links' own parameters otherwise.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from app.errors import BioPlanError
from app.planning.energy import FRICTION_VELOCITY_SCALE

if TYPE_CHECKING:
    from app.planning.robots import Robot
    from app.recordings.robot_logs import RobotLog

__all__ = [
    "DEFAULT_CUTOFF_HZ",
    "FilteredMotion",
    "Identification",
    "IdentificationError",
    "IdentifyOptions",
    "filter_motion",
    "identify",
    "torque_fit",
]

FloatArray = NDArray[np.float64]

#: Default cutoff of the zero-phase low-pass filter [Hz].
DEFAULT_CUTOFF_HZ = 10.0
#: Samples kept per cutoff period for the regression (decimation of fast logs).
SAMPLES_PER_PERIOD = 10.0
#: Filter order (Butterworth; filtfilt doubles it and removes the delay).
FILTER_ORDER = 4
#: Fewest regression samples per identified parameter.
MIN_SAMPLES_PER_PARAMETER = 5
#: Most residual evaluations of the consistent fit.
MAX_ITERATIONS = 300
#: Shortest log (fit part) that identification accepts [s].
MIN_DURATION = 2.0


class IdentificationError(BioPlanError):
    """A log cannot identify or validate the robot (too short, no torque, bad option)."""


@dataclass(frozen=True)
class IdentifyOptions:
    """Options of ``bioplan identify`` (defaults, ranges and units in one place).

    Attributes:
        validate_fraction: last fraction of each log held back to validate the fit, in [0, 0.9).
        cutoff_hz: zero-phase low-pass cutoff [Hz] (> 0, below the Nyquist rate).
        regularisation: weight of the pull towards the URDF's parameters [Nm^2 per unit
            relative deviation] (>= 0); small: it settles only what the motion cannot.
        identify_payload: identify a point payload at the payload body (mass, centre of mass)
            and the friction only; the links keep their URDF (or sidecar-identified) values.
    """

    validate_fraction: float = 0.2
    cutoff_hz: float = DEFAULT_CUTOFF_HZ
    regularisation: float = 1e-4
    identify_payload: bool = False

    def __post_init__(self) -> None:
        if not (0.0 <= self.validate_fraction < 0.9):
            raise IdentificationError(
                f"validate_fraction is {self.validate_fraction}: expected a value in [0, 0.9)"
            )
        if not (math.isfinite(self.cutoff_hz) and self.cutoff_hz > 0.0):
            raise IdentificationError(f"cutoff_hz is {self.cutoff_hz}: expected a value > 0 Hz")
        if not (math.isfinite(self.regularisation) and self.regularisation >= 0.0):
            raise IdentificationError(
                f"regularisation is {self.regularisation}: expected a value >= 0"
            )


# -- filtering -----------------------------------------------------------------------------


@dataclass(frozen=True)
class FilteredMotion:
    """A log's motion after the zero-phase filter: t (T,), q, qd, qdd, tau (T, n) [SI]."""

    t: FloatArray
    q: FloatArray
    qd: FloatArray
    qdd: FloatArray
    tau: FloatArray | None
    cutoff_hz: float
    #: (T, n) the smooth Coulomb law tanh(q̇/ε), passed through the same filter as the torque
    #: (a friction step the filter smooths in the measurement is smoothed in the model too).
    sign: FloatArray | None = None


def _lowpass(x: FloatArray, rate: float, cutoff: float) -> FloatArray:
    from scipy.signal import butter, sosfiltfilt

    sos = butter(FILTER_ORDER, cutoff, fs=rate, output="sos")
    # Odd extension over three cutoff periods: shorter transients at the ends.
    pad = min(int(3.0 * rate / cutoff), x.shape[0] - 1)
    result: FloatArray = sosfiltfilt(sos, x, axis=0, padlen=pad)
    return result


def filter_motion(log: RobotLog, cutoff_hz: float = DEFAULT_CUTOFF_HZ) -> FilteredMotion:
    """Zero-phase low-pass filtered positions, speeds, accelerations and torques of a log.

    The positions (and the logged speeds, when present) pass a 4th-order Butterworth filter
    forwards and backwards (``sosfiltfilt``: zero delay, 8th-order magnitude); speeds are
    central differences of the filtered positions when not logged, accelerations central
    differences of the filtered speeds. Torques pass the same filter, so that measured and
    predicted torque see the same bandwidth.

    Raises:
        IdentificationError: the cutoff is not below the Nyquist rate, or the log is too short
            for the filter.
    """
    rate = log.rate
    if cutoff_hz >= 0.5 * rate:
        raise IdentificationError(
            f"{log.path.name}: cutoff {cutoff_hz:g} Hz is not below the Nyquist rate "
            f"{0.5 * rate:g} Hz of the log: expected a lower cutoff"
        )
    if log.n_samples < 30:
        raise IdentificationError(
            f"{log.path.name}: {log.n_samples} samples: expected at least 30 to filter"
        )
    t = log.t
    q = _lowpass(log.position, rate, cutoff_hz)
    if log.velocity is not None:
        qd = _lowpass(log.velocity, rate, cutoff_hz)
    else:
        qd = np.gradient(q, t, axis=0)
    qdd = np.gradient(qd, t, axis=0)
    tau = None if log.effort is None else _lowpass(log.effort, rate, cutoff_hz)
    sign = _lowpass(np.tanh(qd / FRICTION_VELOCITY_SCALE), rate, cutoff_hz)
    return FilteredMotion(t=t, q=q, qd=qd, qdd=qdd, tau=tau, cutoff_hz=cutoff_hz, sign=sign)


# -- the regressor -------------------------------------------------------------------------


def _pseudo(theta: FloatArray) -> FloatArray:
    """Pinocchio's 10 parameters -> 4x4 pseudo-inertia [[Σ, h], [hᵀ, m]], Σ = tr(I)/2 - I."""
    m, hx, hy, hz, ixx, ixy, iyy, ixz, iyz, izz = theta
    inertia = np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]])
    out = np.zeros((4, 4))
    out[:3, :3] = 0.5 * np.trace(inertia) * np.eye(3) - inertia
    out[:3, 3] = out[3, :3] = (hx, hy, hz)
    out[3, 3] = m
    return out


def _theta(pseudo: FloatArray) -> FloatArray:
    sigma = pseudo[:3, :3]
    inertia = np.trace(sigma) * np.eye(3) - sigma
    h = pseudo[:3, 3]
    return np.array(
        [
            pseudo[3, 3],
            *h,
            inertia[0, 0],
            inertia[0, 1],
            inertia[1, 1],
            inertia[0, 2],
            inertia[1, 2],
            inertia[2, 2],
        ]
    )


def _log_cholesky(phi: FloatArray) -> FloatArray:
    """10 log-Cholesky coordinates -> 10 physically consistent parameters."""
    alpha, d1, d2, d3, s12, s23, s13, t1, t2, t3 = phi
    # Bounded exponents: a wild trial step of the solver gives a large residual, not overflow.
    alpha, d1, d2, d3 = (min(max(v, -30.0), 30.0) for v in (alpha, d1, d2, d3))
    u = math.exp(alpha) * np.array(
        [
            [math.exp(d1), s12, s13, t1],
            [0.0, math.exp(d2), s23, t2],
            [0.0, 0.0, math.exp(d3), t3],
            [0.0, 0.0, 0.0, 1.0],
        ]
    )
    return _theta(u @ u.T)


def _log_cholesky_jacobian(phi: FloatArray, step: float = 1e-6) -> FloatArray:
    """(10, 10) d θ / d φ of :func:`_log_cholesky` by central differences."""
    out = np.empty((10, 10))
    for i in range(10):
        delta = np.zeros(10)
        delta[i] = step
        out[:, i] = (_log_cholesky(phi + delta) - _log_cholesky(phi - delta)) / (2.0 * step)
    return out


def _payload_jacobian(model: _Model, x: FloatArray, step: float = 1e-7) -> FloatArray:
    """(10, 4) d θ_payload / d (mass, com) by central differences (the mass kept >= 0)."""
    j = model.payload_joint
    out = np.empty((10, 4))
    for i in range(4):
        delta = np.zeros(4)
        delta[i] = step
        plus, minus = x + delta, x - delta
        minus[0] = max(minus[0], 0.0)
        width = plus[i] - minus[i]
        out[:, i] = (
            model.payload_theta(plus[0], plus[1:])[10 * j : 10 * j + 10]
            - model.payload_theta(minus[0], minus[1:])[10 * j : 10 * j + 10]
        ) / width
    return out


def _log_cholesky_of(theta: FloatArray, floor: float = 1e-6) -> FloatArray:
    """Inverse of :func:`_log_cholesky`; a degenerate body is nudged to a tiny consistent one."""
    pseudo = _pseudo(theta)
    scale = max(float(theta[0]), 1e-3)
    pseudo = pseudo + floor * scale * np.eye(4)
    flip = pseudo[::-1, ::-1]
    lower = np.linalg.cholesky(flip)
    u = lower[::-1, ::-1]
    alpha = math.log(u[3, 3])
    u = u / u[3, 3]
    return np.array(
        [
            alpha,
            math.log(u[0, 0]),
            math.log(u[1, 1]),
            math.log(u[2, 2]),
            u[0, 1],
            u[1, 2],
            u[0, 2],
            u[0, 3],
            u[1, 3],
            u[2, 3],
        ]
    )


class _Model:
    """The robot's Pinocchio model without payload, and what is known beside the links."""

    def __init__(self, robot: Robot) -> None:
        import pinocchio as pin

        from app.planning.dynamics import _build_model, _reduce
        from app.planning.robots import link_inertials, parse_urdf

        self.pin = pin
        model = _build_model(robot.urdf_path)
        if robot.locks:
            model = _reduce(pin, model, robot.locks, robot.urdf_path.name)
        names = tuple(model.names[1:])
        if names != tuple(robot.joint_names):
            raise IdentificationError(
                f"{robot.urdf_path.name}: Pinocchio's joints {list(names)} differ from the "
                f"robot's {list(robot.joint_names)}: expected the same order"
            )
        self.model, self.data = model, model.createData()
        self.n = int(model.nv)
        urdf = parse_urdf(robot.urdf_path)
        inertials = link_inertials(robot.urdf_path)
        self.links = tuple(urdf.joint(name).child for name in robot.joint_names)
        total = np.concatenate(
            [model.inertias[j].toDynamicParameters() for j in range(1, self.n + 1)]
        )
        child = np.zeros(10 * self.n)
        for j, link in enumerate(self.links):
            body = inertials.get(link)
            if body is not None and body.mass > 0.0:
                child[10 * j : 10 * j + 10] = pin.Inertia(
                    body.mass, np.array(body.com), body.matrix()
                ).toDynamicParameters()
        self.theta_links = child  # the identified links, URDF values (joint frames)
        self.theta_rest = total - child  # fixed children and locked subtrees (constant)
        frame = model.frames[model.getFrameId(robot.payload_body, pin.FrameType.BODY)]
        self.payload_joint = int(frame.parentJoint) - 1
        self.payload_placement = frame.placement
        self.payload_body = robot.payload_body
        p = robot.payload
        self.theta_payload = self.payload_theta(p.mass, p.com, p.inertia)
        self.armature = robot.armature

    def payload_theta(self, mass: float, com: Any, inertia: Any = None) -> FloatArray:
        """(10 n,) parameters of a payload at the payload body (com in its frame)."""
        out = np.zeros(10 * self.n)
        if mass <= 0.0:
            return out
        rotational = np.zeros((3, 3)) if inertia is None else np.asarray(inertia, float)
        body = self.pin.Inertia(float(mass), np.asarray(com, float), rotational)
        j = self.payload_joint
        out[10 * j : 10 * j + 10] = self.payload_placement.act(body).toDynamicParameters()
        return out

    def regressor(self, q: FloatArray, qd: FloatArray, qdd: FloatArray) -> FloatArray:
        """(T n, 10 n) stacked joint-torque regressor rows (sample-major)."""
        pin, model, data = self.pin, self.model, self.data
        rows = np.empty((q.shape[0], self.n, 10 * self.n))
        for k in range(q.shape[0]):
            rows[k] = pin.computeJointTorqueRegressor(model, data, q[k], qd[k], qdd[k])
        return rows.reshape(-1, 10 * self.n)


def _friction_columns(qd: FloatArray, sign: FloatArray | None = None) -> FloatArray:
    """(T n, 3 n) columns of viscous, Coulomb and offset terms per joint (sample-major)."""
    samples, n = qd.shape
    out = np.zeros((samples, n, 3 * n))
    index = np.arange(n)
    out[:, index, index] = qd
    out[:, index, n + index] = np.tanh(qd / FRICTION_VELOCITY_SCALE) if sign is None else sign
    out[:, index, 2 * n + index] = 1.0
    return out.reshape(-1, 3 * n)


def _random_regressor(model: _Model, samples: int = 100, seed: int = 0) -> FloatArray:
    """The regressor at random states: the base parameters are a property of the model's
    structure, not of how well one log excites it (a weakly excited parameter stays one)."""
    rng = np.random.default_rng(seed)
    q, qd, qdd = (rng.uniform(-math.pi, math.pi, (samples, model.n)) for _ in range(3))
    return model.regressor(q, qd, qdd)


def _base_columns(
    y: FloatArray, tol: float = 1e-8
) -> tuple[NDArray[np.intp], NDArray[np.intp], FloatArray]:
    """(independent columns, dependent columns, K) of QR with pivoting: Y θ = Y_1 (θ_1 + K θ_2)."""
    from scipy.linalg import qr, solve_triangular

    norms = np.linalg.norm(y, axis=0)
    usable = np.flatnonzero(norms > tol * max(norms.max(), 1e-30))
    _, r, perm = qr(y[:, usable], mode="economic", pivoting=True)
    diag = np.abs(np.diag(r))
    rank = int(np.sum(diag > tol * diag[0] * max(1.0, math.sqrt(y.shape[1]))))
    independent = usable[perm[:rank]]
    dependent = usable[perm[rank:]]
    k = solve_triangular(r[:rank, :rank], r[:rank, rank:])
    return independent, dependent, k


@dataclass
class Identification:
    """What :func:`identify` found.

    Attributes:
        joint_names: (n,) joints.
        n_base: number of identifiable base parameters of the links.
        base_parameters: (n_base,) least-squares base parameters (no consistency imposed).
        links: link -> {mass [kg], com [m], inertia [kg m^2] (ixx ixy ixz iyy iyz izz about
            the centre of mass)}, physically consistent.
        friction: joint -> {viscous [Nm s/rad], coulomb [Nm], offset [Nm]}.
        payload: {mass, com, body} when identified, else None.
        fit: joint -> {rms_measured, residual_rms, r2} on the fitted part.
        held_back: joint -> {...} on the held-back part (empty when none is held back).
        samples: regression samples used; seconds: wall time [s].
        notes: how the logs were read and repaired.
    """

    joint_names: tuple[str, ...]
    n_base: int
    base_parameters: FloatArray
    links: dict[str, dict[str, Any]]
    friction: dict[str, dict[str, float]]
    payload: dict[str, Any] | None
    fit: dict[str, dict[str, float]]
    held_back: dict[str, dict[str, float]]
    samples: int
    cutoff_hz: float
    notes: list[str] = field(default_factory=list)
    seconds: float = 0.0

    def to_dict(self) -> dict[str, Any]:
        return {
            "joints": list(self.joint_names),
            "n_base_parameters": self.n_base,
            "base_parameters": [float(v) for v in self.base_parameters],
            "links": self.links,
            "friction": self.friction,
            "payload": self.payload,
            "fit": self.fit,
            "held_back": self.held_back,
            "samples": self.samples,
            "filter": _filter_note(self.cutoff_hz),
            "notes": list(self.notes),
            "seconds": self.seconds,
        }


def _filter_note(cutoff: float) -> dict[str, Any]:
    return {
        "kind": f"Butterworth order {FILTER_ORDER}, zero-phase (sosfiltfilt)",
        "cutoff_hz": cutoff,
        "delay_s": 0.0,
    }


def torque_fit(
    measured: FloatArray, predicted: FloatArray, names: Sequence[str]
) -> dict[str, dict[str, float]]:
    """Per joint: rms of the measured torque, rms of the residual [Nm], and R²."""
    out = {}
    for j, name in enumerate(names):
        m, p = measured[:, j], predicted[:, j]
        residual = m - p
        spread = float(np.sum((m - m.mean()) ** 2))
        out[name] = {
            "rms_measured": float(np.sqrt(np.mean(m * m))),
            "residual_rms": float(np.sqrt(np.mean(residual * residual))),
            "r2": float(1.0 - np.sum(residual * residual) / spread) if spread > 0 else float("nan"),
        }
    return out


# -- identification ------------------------------------------------------------------------


@dataclass
class _Stack:
    y: FloatArray  # (rows, 10 n) link regressor
    f: FloatArray  # (rows, 3 n) friction columns
    target: FloatArray  # (rows,) measured torque less the known part
    rows: int


def _prepared(
    robot: Robot, logs: Sequence[RobotLog], options: IdentifyOptions
) -> tuple[list[FilteredMotion], list[FilteredMotion], list[str]]:
    fits, held, notes = [], [], []
    for log in logs:
        matched = log.matched(robot.joint_names, motors=robot.motors)
        if matched.effort is None:
            raise IdentificationError(
                f"{log.path.name}: no joint torque (effort, target_moment or currents with a "
                "sidecar's motors): expected measured torques to identify from"
            )
        notes += [f"{log.path.name}: {note}" for note in matched.notes]
        motion = filter_motion(matched, options.cutoff_hz)
        cut = round(motion.t.size * (1.0 - options.validate_fraction))
        fits.append(_slice(motion, slice(0, cut)))
        if options.validate_fraction > 0.0:
            held.append(_slice(motion, slice(cut, None)))
    return fits, held, notes


def _slice(m: FilteredMotion, part: slice) -> FilteredMotion:
    return FilteredMotion(
        t=m.t[part],
        q=m.q[part],
        qd=m.qd[part],
        qdd=m.qdd[part],
        tau=None if m.tau is None else m.tau[part],
        cutoff_hz=m.cutoff_hz,
        sign=None if m.sign is None else m.sign[part],
    )


def _decimated(m: FilteredMotion) -> FilteredMotion:
    rate = (m.t.size - 1) / max(m.t[-1] - m.t[0], 1e-12)
    step = max(1, int(rate / (SAMPLES_PER_PERIOD * m.cutoff_hz)))
    # Drop the filter's edge transients (two cutoff periods at each end).
    edge = min(int(2.0 * rate / m.cutoff_hz), m.t.size // 10)
    return _slice(m, slice(edge, m.t.size - edge, step))


def _stack(model: _Model, motions: Sequence[FilteredMotion]) -> _Stack:
    ys, fs, targets = [], [], []
    for motion in motions:
        m = _decimated(motion)
        assert m.tau is not None
        y = model.regressor(m.q, m.qd, m.qdd)
        known = y @ model.theta_rest + (m.qdd * model.armature).reshape(-1)
        ys.append(y)
        fs.append(_friction_columns(m.qd, m.sign))
        targets.append(m.tau.reshape(-1) - known)
    y = np.concatenate(ys)
    return _Stack(y=y, f=np.concatenate(fs), target=np.concatenate(targets), rows=y.shape[0])


def _scales(theta: FloatArray, n: int) -> FloatArray:
    """Typical size of each parameter (for the pull towards the URDF)."""
    out = np.empty(10 * n)
    for j in range(n):
        m = max(float(theta[10 * j]), 0.1)
        out[10 * j] = m
        out[10 * j + 1 : 10 * j + 4] = 0.1 * m
        out[10 * j + 4 : 10 * j + 10] = 0.01 * m
    return out


def _check_duration(
    logs: Sequence[RobotLog], fits: Sequence[FilteredMotion], options: IdentifyOptions
) -> None:
    """Raise when the fit parts of the logs hold less than :data:`MIN_DURATION` of motion."""
    duration = sum(float(m.t[-1] - m.t[0]) for m in fits)
    if duration < MIN_DURATION:
        raise IdentificationError(
            f"{', '.join(log.path.name for log in logs)}: {duration:.3g} s of motion to fit: "
            f"expected at least {MIN_DURATION:g} s (after holding back "
            f"{100 * options.validate_fraction:g} %)"
        )


@dataclass(frozen=True)
class _Projected:
    """The linear problem reduced to the base parameters and compressed by QR.

    Attributes:
        columns: (10 f,) the link-parameter columns identified (10 per free link, f links).
        independent: (n_base,) indices into ``columns`` of the base parameters' θ_1.
        dependent: (10 f - n_base,) indices into ``columns`` of θ_2.
        k: (n_base, 10 f - n_base) β = θ_1 + K θ_2.
        selection: (n_base, 10 f) β = selection @ θ.
        r_mat: (p, p) R of the design's QR, p = n_base + 3 n (+ 10 with a payload).
        rhs: (p,) Qᵀ times the measured torque less the known part [N m].
        ols: (p,) unconstrained least squares: base parameters, friction, payload.
        rows: regression rows (samples times joints).
    """

    columns: NDArray[np.intp]
    independent: NDArray[np.intp]
    dependent: NDArray[np.intp]
    k: FloatArray
    selection: FloatArray
    r_mat: FloatArray
    rhs: FloatArray
    ols: FloatArray
    rows: int

    @property
    def n_base(self) -> int:
        return int(self.independent.size)


def _project(
    model: _Model, stack: _Stack, free_links: Sequence[int], options: IdentifyOptions
) -> _Projected:
    """Reduce the stacked regression to the base parameters (step 2) and solve it by ordinary
    least squares (first half of step 3); raise when there are too few rows for them."""
    n = model.n
    target = stack.target.copy()
    if not options.identify_payload:
        target -= stack.y @ model.theta_payload
    else:
        target -= stack.y @ model.theta_links
    columns = np.array([c for j in free_links for c in range(10 * j, 10 * j + 10)], dtype=np.intp)
    if columns.size:
        independent, dependent, k = _base_columns(_random_regressor(model)[:, columns])
    else:
        independent = dependent = np.zeros(0, dtype=np.intp)
        k = np.zeros((0, 0))
    n_base = independent.size
    minimum = MIN_SAMPLES_PER_PARAMETER * (n_base + 3 * n)
    if stack.rows < minimum:
        raise IdentificationError(
            f"{stack.rows} regression rows: expected at least {minimum} (a longer log, or a "
            "faster one)"
        )
    design = np.hstack([stack.y[:, columns[independent]], stack.f])
    if options.identify_payload:
        payload_cols = np.arange(10 * model.payload_joint, 10 * model.payload_joint + 10)
        design = np.hstack([design, stack.y[:, payload_cols]])
    q_mat, r_mat = np.linalg.qr(design)
    rhs = q_mat.T @ target
    selection = np.zeros((n_base, columns.size))
    selection[np.arange(n_base), independent] = 1.0
    selection[:, dependent] = k
    return _Projected(
        columns=columns,
        independent=independent,
        dependent=dependent,
        k=k,
        selection=selection,
        r_mat=r_mat,
        rhs=rhs,
        ols=np.linalg.lstsq(r_mat, rhs, rcond=None)[0],
        rows=stack.rows,
    )


def _consistent_fit(
    model: _Model, problem: _Projected, phi0: FloatArray, unpack: Any, options: IdentifyOptions
) -> Any:
    """The physically consistent fit (second half of step 3): Levenberg-Marquardt from
    ``phi0`` on the QR-compressed residual plus the weak pull towards the URDF's values.
    Returns scipy's ``OptimizeResult``."""
    from scipy.optimize import least_squares

    n, n_base, count = model.n, problem.n_base, problem.columns.size
    independent, dependent, k = problem.independent, problem.dependent, problem.k
    r_mat, rhs, selection = problem.r_mat, problem.rhs, problem.selection
    prior = model.theta_links[problem.columns]
    scales = _scales(model.theta_links, n)[problem.columns]
    weight = math.sqrt(options.regularisation)
    norm = 1.0 / math.sqrt(problem.rows)

    def linear(x: FloatArray) -> FloatArray:
        theta, friction, payload = unpack(x)
        base = theta[independent] + k @ theta[dependent]
        parts = [base, friction]
        if options.identify_payload:
            parts.append(payload)
        return np.concatenate(parts)

    def residual(x: FloatArray) -> FloatArray:
        theta, _, _ = unpack(x)
        return np.concatenate([norm * (r_mat @ linear(x) - rhs), weight * (theta - prior) / scales])

    def jacobian(x: FloatArray) -> FloatArray:
        d_theta = np.zeros((count, count))
        for i in range(count // 10):
            block = slice(10 * i, 10 * i + 10)
            d_theta[block, block] = _log_cholesky_jacobian(x[block])
        d_linear = np.zeros((r_mat.shape[1], x.size))
        d_linear[:n_base, :count] = selection @ d_theta
        d_friction = np.ones(3 * n)
        d_friction[: 2 * n] = 2.0 * x[count : count + 2 * n]
        d_linear[n_base : n_base + 3 * n, count : count + 3 * n] = np.diag(d_friction)
        if options.identify_payload:
            root = x[count + 3 * n :].copy()
            d_payload = _payload_jacobian(model, np.concatenate([[root[0] ** 2], root[1:]]))
            d_payload[:, 0] *= 2.0 * root[0]
            d_linear[n_base + 3 * n :, count + 3 * n :] = d_payload
        d_reg = np.zeros((count, x.size))
        d_reg[:, :count] = weight * d_theta / scales[:, None]
        return np.vstack([norm * (r_mat @ d_linear), d_reg])

    return least_squares(
        residual, phi0, jac=jacobian, method="lm", x_scale="jac", max_nfev=MAX_ITERATIONS
    )


def identify(
    robot: Robot, logs: Sequence[RobotLog], options: IdentifyOptions | None = None
) -> Identification:
    """Identify link inertias, friction and offsets (and optionally a payload) from logs.

    Args:
        robot: the robot (URDF values are the prior; its payload and armature are known).
        logs: robot logs with joint torques, matched to the robot's joints by name.
        options: see :class:`IdentifyOptions`.

    Returns:
        The identified, physically consistent parameters and the fit on held-back data.

    Raises:
        IdentificationError: a log without torques, logs too short for the parameters, a bad
            option; RecordingError: a log whose joints do not match the robot's.
    """
    import time

    start = time.perf_counter()
    options = options or IdentifyOptions()
    if not logs:
        raise IdentificationError("no log given: expected at least one robot log")
    model = _Model(robot)
    fits, held, notes = _prepared(robot, logs, options)
    _check_duration(logs, fits, options)
    stack = _stack(model, fits)
    # With a payload to identify, the links keep their (URDF or identified) values.
    free_links = [] if options.identify_payload else list(range(model.n))
    problem = _project(model, stack, free_links, options)
    phi0, _, unpack = _parameterisation(
        model, free_links, problem.ols, model.n, problem.n_base, options, problem.selection
    )
    solution = _consistent_fit(model, problem, phi0, unpack, options)
    notes.append(f"consistent fit: {solution.nfev} evaluations, {solution.message.rstrip('.')}")
    theta, friction, payload_theta = unpack(solution.x)
    result = _result(robot, model, free_links, theta, friction, payload_theta, options, notes)
    result.n_base = problem.n_base
    result.base_parameters = problem.ols[: problem.n_base]
    result.samples = stack.rows // model.n
    result.fit = _evaluate(robot, model, result, fits)
    result.held_back = _evaluate(robot, model, result, held) if held else {}
    result.seconds = time.perf_counter() - start
    return result


def _consistent_start(
    model: _Model, free_links: Sequence[int], beta: FloatArray, selection: FloatArray
) -> FloatArray:
    """Link parameters nearest the URDF's (scaled) that reproduce the least-squares base
    parameters, each link's pseudo-inertia then clipped to positive definite."""
    if not free_links:
        return np.zeros(0)
    columns = np.concatenate([np.arange(10 * j, 10 * j + 10) for j in free_links])
    prior = model.theta_links[columns]
    scales = _scales(model.theta_links, model.n)[columns]
    scaled = selection * scales
    theta = prior + scales * (np.linalg.pinv(scaled, rcond=1e-10) @ (beta - selection @ prior))
    for i in range(len(free_links)):
        block = slice(10 * i, 10 * i + 10)
        pseudo = _pseudo(theta[block])
        values, vectors = np.linalg.eigh(pseudo)
        floor = 1e-6 * max(float(prior[10 * i]), 1e-3)
        theta[block] = _theta(vectors @ np.diag(np.maximum(values, floor)) @ vectors.T)
    result: FloatArray = theta
    return result


def _parameterisation(
    model: _Model,
    free_links: Sequence[int],
    ols: FloatArray,
    n: int,
    n_base: int,
    options: IdentifyOptions,
    selection: FloatArray,
) -> tuple[FloatArray, tuple[FloatArray, FloatArray], Any]:
    """(initial x, bounds, unpack(x) -> (θ of the free links, friction (3n), payload θ))."""
    start_theta = _consistent_start(model, free_links, ols[:n_base], selection)
    phis = [_log_cholesky_of(start_theta[10 * i : 10 * i + 10]) for i in range(len(free_links))]
    # b = u², c = v² (>= 0) and a payload mass p² keep Levenberg-Marquardt unbounded.
    friction0 = ols[n_base : n_base + 3 * n].copy()
    friction0[: 2 * n] = np.sqrt(np.maximum(friction0[: 2 * n], 1e-6))
    start = [np.concatenate([np.zeros(0), *phis]), friction0]
    if options.identify_payload:
        mass0 = float(ols[-10]) if ols[-10] > 0.0 else 0.1
        start.append(np.array([math.sqrt(mass0), 0.0, 0.0, 0.0]))
    x0 = np.concatenate(start)
    lo, hi = np.full(x0.size, -np.inf), np.full(x0.size, np.inf)
    count = 10 * len(free_links)
    j = model.payload_joint

    def unpack(x: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
        theta = np.concatenate(
            [np.zeros(0)] + [_log_cholesky(x[10 * i : 10 * i + 10]) for i in range(len(free_links))]
        )
        friction = x[count : count + 3 * n].copy()
        friction[: 2 * n] **= 2
        payload = np.zeros(10)
        if options.identify_payload:
            mass, com = x[count + 3 * n] ** 2, x[count + 3 * n + 1 : count + 3 * n + 4]
            payload = model.payload_theta(mass, com)[10 * j : 10 * j + 10]
        return theta, friction, payload

    return x0, (lo, hi), unpack


def _strictly_realisable(inertia: FloatArray, margin: float = 1e-4) -> FloatArray:
    """The inertia about the centre of mass with its second moments Σ = tr(I)/2 - I kept at
    least ``margin`` times the largest: the triangle inequality then holds strictly (MuJoCo
    refuses A + B = C, which a flat body identified at the edge of consistency can reach)."""
    sigma = 0.5 * np.trace(inertia) * np.eye(3) - inertia
    values, vectors = np.linalg.eigh(sigma)
    floor = max(margin * float(values.max()), 1e-12)
    sigma = vectors @ np.diag(np.maximum(values, floor)) @ vectors.T
    result: FloatArray = np.trace(sigma) * np.eye(3) - sigma
    return result


def _result(
    robot: Robot,
    model: _Model,
    free_links: Sequence[int],
    theta: FloatArray,
    friction: FloatArray,
    payload_theta: FloatArray,
    options: IdentifyOptions,
    notes: list[str],
) -> Identification:
    import pinocchio as pin

    n = model.n
    links: dict[str, dict[str, Any]] = {}
    for i, j in enumerate(free_links):
        body = pin.Inertia.FromDynamicParameters(theta[10 * i : 10 * i + 10])
        inertia = _strictly_realisable(np.array(body.inertia))
        links[model.links[j]] = {
            "mass": float(body.mass),
            "com": [float(v) for v in body.lever],
            "inertia": [
                float(inertia[a, b]) for a, b in ((0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2))
            ],
        }
    names = robot.joint_names
    joint_friction = {
        name: {
            "viscous": float(friction[j]),
            "coulomb": float(friction[n + j]),
            "offset": float(friction[2 * n + j]),
        }
        for j, name in enumerate(names)
    }
    payload = None
    if options.identify_payload:
        mass = float(payload_theta[0])
        placement = model.payload_placement
        com_joint = payload_theta[1:4] / mass if mass > 0 else np.zeros(3)
        com = placement.actInv(com_joint) if mass > 0 else np.zeros(3)
        payload = {"mass": mass, "com": [float(v) for v in com], "body": model.payload_body}
    return Identification(
        joint_names=tuple(names),
        n_base=0,
        base_parameters=np.zeros(0),
        links=links,
        friction=joint_friction,
        payload=payload,
        fit={},
        held_back={},
        samples=0,
        cutoff_hz=options.cutoff_hz,
        notes=notes,
    )


def predicted_torque(model: _Model, result: Identification, motion: FilteredMotion) -> FloatArray:
    """(T, n) torque the identified model predicts for a filtered motion [Nm]."""
    import pinocchio as pin

    n = model.n
    theta = model.theta_rest.copy()
    for j, link in enumerate(model.links):
        body = result.links.get(link)
        if body is None:
            theta[10 * j : 10 * j + 10] += model.theta_links[10 * j : 10 * j + 10]
            continue
        from app.planning.robots import LinkInertial

        inertial = LinkInertial(body["mass"], tuple(body["com"]), tuple(body["inertia"]))
        theta[10 * j : 10 * j + 10] += pin.Inertia(
            inertial.mass, np.array(inertial.com), inertial.matrix()
        ).toDynamicParameters()
    if result.payload is not None:
        theta += model.payload_theta(result.payload["mass"], result.payload["com"])
    else:
        theta += model.theta_payload
    y = model.regressor(motion.q, motion.qd, motion.qdd)
    friction = np.array(
        [
            [f["viscous"] for f in result.friction.values()]
            + [f["coulomb"] for f in result.friction.values()]
            + [f["offset"] for f in result.friction.values()]
        ]
    ).ravel()
    tau = y @ theta + _friction_columns(motion.qd, motion.sign) @ friction
    torque: FloatArray = tau.reshape(-1, n) + motion.qdd * model.armature
    return torque


def _evaluate(
    robot: Robot, model: _Model, result: Identification, motions: Sequence[FilteredMotion]
) -> dict[str, dict[str, float]]:
    measured, predicted = [], []
    for motion in motions:
        m = _decimated(motion)
        assert m.tau is not None
        measured.append(m.tau)
        predicted.append(predicted_torque(model, result, m))
    return torque_fit(np.concatenate(measured), np.concatenate(predicted), robot.joint_names)


def write_sidecar(
    path: str | Path,
    robot: Robot,
    result: Identification,
    *,
    base: Mapping[str, Any] | None = None,
    comment: str = "",
) -> None:
    """Write a sidecar with the identified links, friction (and payload), keeping ``base``'s
    other sections (motors, locks, roles) — written atomically, no half-written file."""
    import os
    import tempfile

    import yaml

    data: dict[str, Any] = dict(base or {})
    data["robot"] = robot.name
    data["links"] = {name: dict(body) for name, body in result.links.items()}
    data["friction"] = {name: dict(f) for name, f in result.friction.items()}
    if result.payload is not None:
        payload = dict(data.get("payload") or {})
        payload.update(result.payload)
        data["payload"] = payload
    text = yaml.safe_dump(data, sort_keys=False, default_flow_style=None, width=100)
    if comment:
        text = "".join(f"# {line}\n" for line in comment.splitlines()) + text
    target = Path(path)
    fd, tmp = tempfile.mkstemp(dir=target.parent, prefix=".tmp-", suffix=".yaml")
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as handle:
            handle.write(text)
        os.replace(tmp, target)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
