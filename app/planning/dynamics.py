"""Rigid-body inverse dynamics tau = M(q) qdd + C(q, qd) qd + g(q) for whole trajectories.

Two implementations of one protocol (``Dynamics``):

* ``PlanarArm2DOF``: the paper's 2-link planar arm in closed form (Lagrangian), with general
  link masses, lengths, centres of mass and inertias and a point payload at the hand.
* ``PinocchioDynamics``: any fixed-base chain of revolute joints from a URDF, batched through
  Pinocchio's ``rneaInParallel`` (no Python loop per sample).

Every method takes any leading batch shape, e.g. (T, n) for a trajectory or (B, T, n) for a
batch of trajectories. Angles follow the project's convention (see ``app.planning.robots``):
human arm in the sagittal plane, x forward, z up, q1 = shoulder flexion, q2 = elbow flexion.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol, runtime_checkable

import numpy as np
from numpy.typing import ArrayLike, NDArray

from app.errors import BioPlanError
from app.planning.payload import Payload, RobotError

if TYPE_CHECKING:
    from app.planning.robots import Robot

__all__ = ["STANDARD_GRAVITY", "Dynamics", "PinocchioDynamics", "PlanarArm2DOF", "robot_dynamics"]

STANDARD_GRAVITY = 9.81  # [m/s^2], the default of both Pinocchio and MuJoCo

FloatArray = NDArray[np.float64]


@runtime_checkable
class Dynamics(Protocol):
    """Inverse dynamics, energies and hand position of an n-joint arm, batched over samples."""

    @property
    def n_joints(self) -> int: ...

    def inverse_dynamics(self, q: ArrayLike, qd: ArrayLike, qdd: ArrayLike) -> FloatArray:
        """(..., n) q [rad], qd [rad/s], qdd [rad/s^2] -> (..., n) joint torques [Nm]."""
        ...

    def mass_matrix(self, q: ArrayLike) -> FloatArray:
        """(..., n) positions [rad] -> (..., n, n) joint-space inertia [kg m^2]."""
        ...

    def potential_energy(self, q: ArrayLike) -> FloatArray:
        """(..., n) positions [rad] -> (...,) gravitational energy incl. payload [J]."""
        ...

    def kinetic_energy(self, q: ArrayLike, qd: ArrayLike) -> FloatArray:
        """(..., n) positions [rad] and velocities [rad/s] -> (...,) kinetic energy [J]."""
        ...

    def end_effector_position(self, q: ArrayLike) -> FloatArray:
        """(..., n) positions [rad] -> (..., 3) payload centre / hand position [m]."""
        ...


def _batch(name: str, value: ArrayLike, n: int, unit: str) -> FloatArray:
    """``value`` as a float array of shape (..., n), or a ValueError naming what is wrong."""
    try:
        array = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise BioPlanError(
            f"{name} is not numeric: expected an array (..., {n}) [{unit}]"
        ) from None
    if array.ndim == 0 or array.shape[-1] != n:
        raise BioPlanError(f"{name} has shape {array.shape}: expected (..., {n}) [{unit}]")
    if not np.isfinite(array).all():
        raise BioPlanError(f"{name} contains NaN or inf: expected finite values [{unit}]")
    return array


def _same_shape(reference: FloatArray, name: str, other: FloatArray) -> None:
    if other.shape != reference.shape:
        raise BioPlanError(
            f"{name} has shape {other.shape} but q has shape {reference.shape}: "
            "expected equal shapes"
        )


# --------------------------------------------------------------------------------------------
# Closed-form planar 2-DOF arm
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class PlanarArm2DOF:
    """The 2-link planar arm in closed form (Lagrangian), sagittal plane x-z, z up.

    Shoulder at the origin; elbow = l1 (sin q1, 0, -cos q1); the forearm points along
    (sin(q1+q2), 0, -cos(q1+q2)). Centres of mass lie on the link axes; inertias are about the
    centre of mass and the axis normal to the plane (y). The payload is a mass at the end of
    link 2 (distance l2 from the elbow), optionally with its own inertia about that point.

    Attributes:
        l1, lc1, m1, i1: upper-arm length [m], shoulder-to-CoM distance [m], mass [kg],
            inertia about its CoM [kg m^2].
        l2, lc2, m2, i2: the same for forearm + hand; l2 is the elbow-to-payload distance.
        payload_mass: payload mass at the end of link 2 [kg].
        payload_inertia: payload inertia about its centre, normal to the plane [kg m^2].
        armature: (2,) reflected rotor inertia added to M's diagonal [kg m^2].
        gravity: gravitational acceleration [m/s^2], acting along -z.
    """

    l1: float
    lc1: float
    m1: float
    i1: float
    l2: float
    lc2: float
    m2: float
    i2: float
    payload_mass: float = 0.0
    payload_inertia: float = 0.0
    armature: tuple[float, float] = (0.0, 0.0)
    gravity: float = STANDARD_GRAVITY

    def __post_init__(self) -> None:
        for name in ("l1", "l2", "m1", "m2"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0.0):
                raise BioPlanError(f"PlanarArm2DOF {name}={value}: expected a finite value > 0")
        for name in ("i1", "i2", "payload_mass", "payload_inertia", "gravity"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0.0):
                raise BioPlanError(f"PlanarArm2DOF {name}={value}: expected a finite value >= 0")
        for name in ("lc1", "lc2"):
            if not math.isfinite(getattr(self, name)):
                raise BioPlanError(f"PlanarArm2DOF {name}: expected a finite distance [m]")
        armature = tuple(float(a) for a in self.armature)
        if len(armature) != 2 or not all(math.isfinite(a) and a >= 0.0 for a in armature):
            raise BioPlanError(f"PlanarArm2DOF armature={self.armature}: expected two values >= 0")
        object.__setattr__(self, "armature", armature)

    @property
    def n_joints(self) -> int:
        return 2

    @classmethod
    def from_robot(cls, robot: Robot, *, armature: bool = True) -> PlanarArm2DOF:
        """The closed-form model of ``human_arm_2dof`` (any subject and payload).

        Reads the link parameters from the robot's parameter table (computed from de Leva's
        table, not from the URDF), so it is an independent check of the URDF and Pinocchio.

        Raises:
            ValueError: the robot is not a planar 2-link arm with a payload at the grip.
        """
        try:
            values = {
                key: float(robot.parameter(f"{link}.{name}"))  # type: ignore[arg-type]
                for link, key_prefix in (("upper_arm", "1"), ("forearm_hand", "2"))
                for name, key in (
                    ("length", f"l{key_prefix}"),
                    ("com_distance", f"lc{key_prefix}"),
                    ("mass", f"m{key_prefix}"),
                    ("inertia_yy", f"i{key_prefix}"),
                )
            }
        except RobotError:
            raise BioPlanError(
                f"robot '{robot.name}' has no planar 2-link segment table: expected human_arm_2dof"
            ) from None
        payload = robot.payload
        if payload.mass > 0.0 and not np.allclose(payload.com, [0.0, 0.0, -values["l2"]]):
            raise BioPlanError(
                f"robot '{robot.name}' payload centre {payload.com.tolist()}: "
                f"expected the grip (0, 0, {-values['l2']})"
            )
        arm = robot.armature if armature else np.zeros(2)
        return cls(
            **values,
            payload_mass=payload.mass,
            payload_inertia=float(payload.inertia[1, 1]),
            armature=(float(arm[0]), float(arm[1])),
        )

    # Lumped constants of the Lagrangian (link 2 and payload seen from the elbow).
    def _constants(self) -> tuple[float, float, float, float, float]:
        m2p = self.m2 + self.payload_mass
        s2 = self.m2 * self.lc2 + self.payload_mass * self.l2  # first moment of link 2 + payload
        j2 = self.i2 + self.m2 * self.lc2**2 + self.payload_mass * self.l2**2 + self.payload_inertia
        j1 = self.i1 + self.m1 * self.lc1**2 + m2p * self.l1**2
        s1 = self.m1 * self.lc1 + m2p * self.l1  # first moment of everything along link 1
        return j1, j2, self.l1 * s2, s1, s2

    def mass_matrix(self, q: ArrayLike) -> FloatArray:
        """(..., 2) [rad] -> (..., 2, 2) [kg m^2]."""
        qa = _batch("q", q, 2, "rad")
        j1, j2, h, _, _ = self._constants()
        c2 = np.cos(qa[..., 1])
        out = np.empty((*qa.shape[:-1], 2, 2))
        out[..., 0, 0] = j1 + j2 + 2.0 * h * c2 + self.armature[0]
        out[..., 0, 1] = out[..., 1, 0] = j2 + h * c2
        out[..., 1, 1] = j2 + self.armature[1]
        return out

    def inverse_dynamics(self, q: ArrayLike, qd: ArrayLike, qdd: ArrayLike) -> FloatArray:
        """(..., 2) q [rad], qd [rad/s], qdd [rad/s^2] -> (..., 2) joint torques [Nm]."""
        qa = _batch("q", q, 2, "rad")
        va = _batch("qd", qd, 2, "rad/s")
        aa = _batch("qdd", qdd, 2, "rad/s^2")
        _same_shape(qa, "qd", va)
        _same_shape(qa, "qdd", aa)
        j1, j2, h, s1, s2 = self._constants()
        q1, q2 = qa[..., 0], qa[..., 1]
        v1, v2 = va[..., 0], va[..., 1]
        a1, a2 = aa[..., 0], aa[..., 1]
        c2, sn2 = np.cos(q2), np.sin(q2)
        m11 = j1 + j2 + 2.0 * h * c2 + self.armature[0]
        m12 = j2 + h * c2
        m22 = j2 + self.armature[1]
        g12 = self.gravity * s2 * np.sin(q1 + q2)
        out = np.empty(qa.shape)
        out[..., 0] = (
            m11 * a1
            + m12 * a2
            - h * sn2 * (2.0 * v1 * v2 + v2 * v2)
            + self.gravity * s1 * np.sin(q1)
            + g12
        )
        out[..., 1] = m12 * a1 + m22 * a2 + h * sn2 * v1 * v1 + g12
        return out

    def potential_energy(self, q: ArrayLike) -> FloatArray:
        """(..., 2) [rad] -> (...,) [J], zero with all masses at shoulder height."""
        qa = _batch("q", q, 2, "rad")
        _, _, _, s1, s2 = self._constants()
        result: FloatArray = -self.gravity * (
            s1 * np.cos(qa[..., 0]) + s2 * np.cos(qa[..., 0] + qa[..., 1])
        )
        return result

    def kinetic_energy(self, q: ArrayLike, qd: ArrayLike) -> FloatArray:
        """(..., 2) [rad], (..., 2) [rad/s] -> (...,) [J] (incl. armature)."""
        qa = _batch("q", q, 2, "rad")
        va = _batch("qd", qd, 2, "rad/s")
        _same_shape(qa, "qd", va)
        m = self.mass_matrix(qa)
        result: FloatArray = 0.5 * np.einsum("...i,...ij,...j->...", va, m, va)
        return result

    def end_effector_position(self, q: ArrayLike) -> FloatArray:
        """(..., 2) [rad] -> (..., 3) payload / grip position [m], shoulder at the origin."""
        qa = _batch("q", q, 2, "rad")
        q1, q12 = qa[..., 0], qa[..., 0] + qa[..., 1]
        out = np.zeros((*qa.shape[:-1], 3))
        out[..., 0] = self.l1 * np.sin(q1) + self.l2 * np.sin(q12)
        out[..., 2] = -self.l1 * np.cos(q1) - self.l2 * np.cos(q12)
        return out


# --------------------------------------------------------------------------------------------
# General chains through Pinocchio
# --------------------------------------------------------------------------------------------

_REVOLUTE = (
    "JointModelRX",
    "JointModelRY",
    "JointModelRZ",
    "JointModelRevoluteUnaligned",
    "JointModelRUBX",
    "JointModelRUBY",
    "JointModelRUBZ",
    "JointModelRevoluteUnboundedUnaligned",
)


def _pinocchio() -> Any:
    import pinocchio

    return pinocchio


def _align_negative_axes(pin: Any, model: Any) -> Any:
    """The same model with joints about -x, -y or -z turned into Pinocchio's RX, RY or RZ.

    URDF axes such as (0, -1, 0) (the project's flexion convention) parse as the generic
    ``RevoluteUnaligned`` joint, about 10 % slower in RNEA than the axis-aligned types. A
    rotation about -e equals F R_e(q) F^-1 with F a half turn about another axis, so each
    such joint frame is turned by F and everything expressed in it (the body inertia, the
    children's placements, the frames) by F^-1. Joint angles, torques and every frame's world
    pose (oMf) are unchanged; only the joint frames (oMi) of those joints turn by a half turn.
    """
    model = model.copy()
    types = (pin.JointModelRX, pin.JointModelRY, pin.JointModelRZ)
    for j in range(1, model.njoints):
        joint = model.joints[j]
        if joint.shortname() != "JointModelRevoluteUnaligned":
            continue
        axis = np.array(joint.extract().axis)
        k = int(np.argmax(np.abs(axis)))
        if axis[k] != -1.0 or np.count_nonzero(axis) != 1:
            continue
        flip = pin.SE3(np.diag([1.0, -1.0, -1.0] if k == 2 else [-1.0, -1.0, 1.0]), np.zeros(3))
        aligned = pin.JointModel(types[k]())
        aligned.setIndexes(j, joint.idx_q, joint.idx_v)
        model.joints[j] = aligned
        model.jointPlacements[j] = model.jointPlacements[j] * flip
        model.inertias[j] = flip.actInv(model.inertias[j])
        for child in range(j + 1, model.njoints):
            if model.parents[child] == j:
                model.jointPlacements[child] = flip.actInv(model.jointPlacements[child])
        for index in range(len(model.frames)):
            frame = model.frames[index]
            if frame.parentJoint == j:
                frame.placement = flip.actInv(frame.placement)
                model.frames[index] = frame
    return model


def _build_model(path: Path) -> Any:
    pin = _pinocchio()
    if not path.is_file():
        raise RobotError(f"{path.name}: no such file ({path}): expected a URDF file")
    try:
        return pin.buildModelFromUrdf(str(path))
    except Exception as exc:  # urdfdom/pinocchio raise ValueError/RuntimeError
        detail = " ".join(str(exc).split())
        raise RobotError(
            f"{path.name}: pinocchio cannot build it ({detail}): expected a URDF"
        ) from None


def _reduce(pin: Any, model: Any, locks: Mapping[str, float], file: str) -> Any:
    """Pinocchio's reduced model with ``locks`` (joint name -> value [rad or m]) held fixed."""
    reference = pin.neutral(model)
    ids = []
    for name, value in locks.items():
        if not model.existJointName(name):
            raise RobotError(
                f"{file}: cannot lock '{name}': expected one of {list(model.names[1:])}"
            )
        joint_id = model.getJointId(name)
        joint = model.joints[joint_id]
        if joint.nq == 2:  # continuous joint: (cos, sin)
            reference[joint.idx_q : joint.idx_q + 2] = (math.cos(value), math.sin(value))
        else:
            reference[joint.idx_q] = value
        ids.append(joint_id)
    try:
        return pin.buildReducedModel(model, sorted(ids), reference)
    except ValueError as exc:  # e.g. a fixed joint and a link of the same name (b1-z1)
        detail = " ".join(str(exc).split())
        raise RobotError(
            f"{file}: pinocchio cannot lock its joints ({detail}): expected unique frame names "
            "(rename the joint or the link that shares a name with another frame)"
        ) from None


class PinocchioDynamics:
    """Rigid-body dynamics of a URDF chain of revolute joints through Pinocchio, batched.

    Inverse dynamics, mass matrix and kinetic energy go through ``pin.rneaInParallel`` (the
    mass matrix column by column as M e_j = RNEA(q, 0, e_j) without gravity, the kinetic energy
    as qd . RNEA(q, 0, qd) / 2), so no Python loop runs per sample. Potential energy and the
    end-effector position use a vectorised forward-kinematics pass over the joints (a loop over
    joints, not samples). Gravity is Pinocchio's default, 9.81 m/s^2 along -z.

    An instance holds per-thread scratch data: share it between processes freely, but give
    each Python thread its own instance.

    Attributes:
        n_joints: number of joints n.
        joint_names: (n,) joint names in Pinocchio's (root-to-tip) order.
        payload_body: the URDF link whose frame the payload and the end effector refer to.
    """

    def __init__(
        self,
        urdf: str | Path,
        *,
        payload: Payload | None = None,
        payload_body: str | None = None,
        armature: ArrayLike | None = None,
        num_threads: int = 1,
        locks: Mapping[str, float] | None = None,
    ) -> None:
        """Build the model.

        Args:
            urdf: URDF file.
            payload: rigid payload appended to ``payload_body`` (com and inertia in its frame).
            payload_body: URDF link carrying the payload / defining the end effector; None =
                the link moved by the last joint.
            armature: (n,) reflected rotor inertia added to M's diagonal [kg m^2].
            num_threads: threads for ``rneaInParallel`` (1 = one core).
            locks: joints held at fixed values (name -> rad, or m for prismatic joints);
                Pinocchio's reduced model (``buildReducedModel``) has only the other joints.

        Raises:
            RobotError: missing / malformed URDF, non-revolute joint, unknown payload body.
            ValueError: bad armature or thread count.
        """
        # Constructor arguments, enough to rebuild the C++ objects after pickling.
        self._args: dict[str, Any] = {
            "urdf": Path(urdf),
            "payload": payload,
            "payload_body": payload_body,
            "armature": None if armature is None else np.array(armature, dtype=np.float64),
            "num_threads": num_threads,
            "locks": dict(locks or {}),
        }
        pin = _pinocchio()
        path = Path(urdf)
        model = _build_model(path)
        if locks:
            model = _reduce(pin, model, locks, path.name)
        model = _align_negative_axes(pin, model)
        for joint_id in range(1, model.njoints):
            kind = model.joints[joint_id].shortname()
            if kind not in _REVOLUTE:
                raise RobotError(
                    f"{path.name}: joint '{model.names[joint_id]}' is {kind}: "
                    "expected revolute or continuous joints only (lock the others)"
                )
        if model.nv == 0:
            raise RobotError(f"{path.name}: no movable joint: expected at least one")
        n = int(model.nv)
        self._n: int = n
        self.joint_names: tuple[str, ...] = tuple(model.names[1:])

        self._attach_payload(pin, model, path, payload, payload_body)

        if armature is not None:
            arm = np.asarray(armature, dtype=np.float64)
            if arm.shape != (n,) or not np.all(np.isfinite(arm)) or np.any(arm < 0.0):
                raise BioPlanError(f"armature {arm.tolist()}: expected {n} finite values >= 0")
            model.armature = arm.copy()
        if not (isinstance(num_threads, int) and num_threads >= 1):
            raise BioPlanError(f"num_threads={num_threads}: expected an integer >= 1")

        self._pin = pin
        self._model = model
        self._threads = num_threads
        self._pool = pin.ModelPool(model, num_threads)
        model0 = model.copy()
        model0.gravity = pin.Motion.Zero()
        self._pool0 = pin.ModelPool(model0, num_threads)

        # Configuration layout: continuous joints use (cos, sin) in Pinocchio.
        self._idx_q = np.array([model.joints[j].idx_q for j in range(1, model.njoints)])
        self._unbounded = np.array([model.joints[j].nq == 2 for j in range(1, model.njoints)])
        self._nq = int(model.nq)
        self._idx_v = [0] + [int(model.joints[j].idx_v) for j in range(1, model.njoints)]

        self._kinematics_tables(pin, model)

    def _attach_payload(
        self, pin: Any, model: Any, path: Path, payload: Payload | None, payload_body: str | None
    ) -> None:
        """Find the end-effector / payload frame and merge the payload into its body."""
        if payload_body is None:
            frame_id = next(
                i
                for i, frame in enumerate(model.frames)
                if frame.type == pin.FrameType.BODY and frame.parentJoint == model.njoints - 1
            )
        else:
            if not model.existFrame(payload_body, pin.FrameType.BODY):
                raise RobotError(
                    f"{path.name}: no link '{payload_body}': expected the payload body's name"
                )
            frame_id = model.getFrameId(payload_body, pin.FrameType.BODY)
        frame = model.frames[frame_id]
        self.payload_body: str = frame.name
        self._ee_joint = int(frame.parentJoint)
        com = payload.com if payload is not None else np.zeros(3)
        self._ee_point = np.asarray(frame.placement.act(np.asarray(com, dtype=np.float64)))
        if payload is not None and payload.mass > 0.0:
            inertia = pin.Inertia(payload.mass, np.asarray(com), np.asarray(payload.inertia))
            model.inertias[self._ee_joint] = model.inertias[self._ee_joint] + frame.placement.act(
                inertia
            )

    def _kinematics_tables(self, pin: Any, model: Any) -> None:
        """Forward-kinematics tables (joint frames relative to the parent joint at q = 0)."""
        data = model.createData()
        pin.computeJointJacobians(model, data, pin.neutral(model))
        self._parents = [int(model.parents[j]) for j in range(model.njoints)]
        self._place_r = [np.array(model.jointPlacements[j].rotation) for j in range(model.njoints)]
        self._place_t = [
            np.array(model.jointPlacements[j].translation) for j in range(model.njoints)
        ]
        self._k1: list[FloatArray] = [np.zeros((3, 3))]
        self._k2: list[FloatArray] = [np.zeros((3, 3))]
        for j in range(1, model.njoints):
            column = model.joints[j].idx_v
            jac = pin.getJointJacobian(model, data, j, pin.ReferenceFrame.LOCAL)
            axis = np.array(jac[3:6, column])
            skew = np.array(
                [[0.0, -axis[2], axis[1]], [axis[2], 0.0, -axis[0]], [-axis[1], axis[0], 0.0]]
            )
            # R(theta) = I + sin(theta) K + (1 - cos(theta)) K^2 (Rodrigues), pre-multiplied
            # by the constant placement rotation.
            self._k1.append(self._place_r[j] @ skew)
            self._k2.append(self._place_r[j] @ skew @ skew)
        self._mass = np.array([model.inertias[j].mass for j in range(model.njoints)])
        self._lever = [np.array(model.inertias[j].lever) for j in range(model.njoints)]
        self._gravity = np.array(model.gravity.linear)

    def __getstate__(self) -> dict[str, Any]:
        # Pinocchio models and pools are rebuilt from the URDF in the receiving process.
        return dict(self._args)

    def __setstate__(self, state: dict[str, Any]) -> None:
        args = dict(state)
        self.__init__(args.pop("urdf"), **args)  # type: ignore[misc]

    # -- protocol --------------------------------------------------------------------------

    @property
    def n_joints(self) -> int:
        return self._n

    @property
    def model(self) -> Any:
        """The ``pinocchio.Model`` (payload and armature included); do not modify it."""
        return self._model

    @staticmethod
    def joint_order(urdf: str | Path) -> list[str]:
        """Names of the movable joints of a URDF in Pinocchio's order."""
        return list(_build_model(Path(urdf)).names[1:])

    def _to_pin_q(self, q: FloatArray) -> FloatArray:
        """(N, n) angles -> (nq, N) Fortran-ordered Pinocchio configurations."""
        if not self._unbounded.any():
            return q.T
        out = np.empty((q.shape[0], self._nq))
        bounded = ~self._unbounded
        out[:, self._idx_q[bounded]] = q[:, bounded]
        out[:, self._idx_q[self._unbounded]] = np.cos(q[:, self._unbounded])
        out[:, self._idx_q[self._unbounded] + 1] = np.sin(q[:, self._unbounded])
        return out.T

    def _rnea(self, pool: Any, q: FloatArray, v: FloatArray, a: FloatArray) -> FloatArray:
        """(N, n) x3 C-contiguous -> (N, n) torques; one C++ call for the whole batch."""
        tau = np.empty(q.shape)
        if q.shape[0]:
            # (N, n) C-ordered arrays are (n, N) Fortran-ordered views: no copies.
            self._pin.rneaInParallel(self._threads, pool, self._to_pin_q(q), v.T, a.T, tau.T)
        return tau

    def _flat(self, name: str, value: ArrayLike, unit: str) -> tuple[FloatArray, tuple[int, ...]]:
        array = _batch(name, value, self._n, unit)
        return np.ascontiguousarray(array.reshape(-1, self._n)), array.shape

    def inverse_dynamics(self, q: ArrayLike, qd: ArrayLike, qdd: ArrayLike) -> FloatArray:
        """Joint torques for whole trajectories in one batched C++ call.

        Args:
            q: (..., n) joint positions [rad].
            qd: (..., n) joint velocities [rad/s].
            qdd: (..., n) joint accelerations [rad/s^2].

        Returns:
            (..., n) joint torques [Nm] (rigid bodies + payload + armature, no friction).
        """
        qf, shape = self._flat("q", q, "rad")
        vf, vshape = self._flat("qd", qd, "rad/s")
        af, ashape = self._flat("qdd", qdd, "rad/s^2")
        if vshape != shape or ashape != shape:
            bad, other = ("qd", vshape) if vshape != shape else ("qdd", ashape)
            raise BioPlanError(
                f"{bad} has shape {other} but q has shape {shape}: expected equal shapes"
            )
        return self._rnea(self._pool, qf, vf, af).reshape(shape)

    def mass_matrix(self, q: ArrayLike) -> FloatArray:
        """(..., n) [rad] -> (..., n, n) joint-space inertia incl. armature [kg m^2].

        Column j is RNEA(q, 0, e_j) without gravity: n batched calls, no per-sample loop.
        """
        qf, shape = self._flat("q", q, "rad")
        n = self._n
        zeros = np.zeros_like(qf)
        out = np.empty((qf.shape[0], n, n))
        for j in range(n):
            unit = np.zeros_like(qf)
            unit[:, j] = 1.0
            out[:, :, j] = self._rnea(self._pool0, qf, zeros, unit)
        # RNEA's columns are exact up to rounding; symmetrise so that M is exactly symmetric.
        out = 0.5 * (out + np.swapaxes(out, 1, 2))
        return out.reshape((*shape[:-1], n, n))

    def kinetic_energy(self, q: ArrayLike, qd: ArrayLike) -> FloatArray:
        """(..., n) [rad], (..., n) [rad/s] -> (...,) kinetic energy incl. armature [J]."""
        qf, shape = self._flat("q", q, "rad")
        vf, vshape = self._flat("qd", qd, "rad/s")
        if vshape != shape:
            raise BioPlanError(
                f"qd has shape {vshape} but q has shape {shape}: expected equal shapes"
            )
        m_qd = self._rnea(self._pool0, qf, np.zeros_like(qf), vf)
        result: FloatArray = 0.5 * np.einsum("ij,ij->i", vf, m_qd).reshape(shape[:-1])
        return result

    def _forward(self, qf: FloatArray) -> tuple[list[FloatArray], list[FloatArray]]:
        """World rotations (N, 3, 3) and positions (N, 3) of every joint frame."""
        count = qf.shape[0]
        rot = [np.broadcast_to(np.eye(3), (count, 3, 3))]
        pos = [np.zeros((count, 3))]
        for j in range(1, len(self._parents)):
            parent = self._parents[j]
            theta = qf[:, self._idx_v[j]][:, None, None]
            local = (
                self._place_r[j]
                + np.sin(theta) * self._k1[j]
                + (1.0 - np.cos(theta)) * (self._k2[j])
            )
            rot.append(rot[parent] @ local)
            pos.append(pos[parent] + rot[parent] @ self._place_t[j])
        return rot, pos

    def potential_energy(self, q: ArrayLike) -> FloatArray:
        """(..., n) [rad] -> (...,) gravitational potential energy incl. payload [J].

        Zero with every centre of mass at the height of the URDF's root frame origin.
        """
        qf, shape = self._flat("q", q, "rad")
        rot, pos = self._forward(qf)
        energy = np.zeros(qf.shape[0])
        for j in range(1, len(self._parents)):
            if self._mass[j] == 0.0:
                continue
            com = pos[j] + rot[j] @ self._lever[j]
            energy -= self._mass[j] * (com @ self._gravity)
        return energy.reshape(shape[:-1])

    def end_effector_position(self, q: ArrayLike) -> FloatArray:
        """(..., n) [rad] -> (..., 3) payload centre (payload body origin if none) [m]."""
        qf, shape = self._flat("q", q, "rad")
        rot, pos = self._forward(qf)
        point: FloatArray = pos[self._ee_joint] + rot[self._ee_joint] @ self._ee_point
        return point.reshape((*shape[:-1], 3))


def robot_dynamics(robot: Robot, *, armature: bool = True, threads: int = 1) -> Dynamics:
    """A robot's rigid-body dynamics with its payload (and its motors' armature), cached on the
    robot (``Robot.dynamics()`` calls this).

    Args:
        robot: the robot (its URDF, payload, payload body, motors and locks).
        armature: add each motor's reflected rotor inertia N^2 J_m to the joint's diagonal.
        threads: threads for batched inverse dynamics (1 = one core).

    Returns:
        A ``PinocchioDynamics`` built from ``robot.urdf_path``.
    """
    key = ("dynamics", bool(armature), int(threads))
    if key not in robot._cache:
        robot._cache[key] = PinocchioDynamics(
            robot.urdf_path,
            payload=robot.payload,
            payload_body=robot.payload_body,
            armature=robot.armature if armature else None,
            num_threads=threads,
            locks=robot.locks,
        )
    result: Dynamics = robot._cache[key]
    return result
