"""Exact symbolic inverse dynamics (CasADi SX) of any robot the project loads.

The ``pin`` wheels ship no ``pinocchio.casadi``, so the recursive Newton-Euler algorithm is
written out here on CasADi expressions, from the very model ``Robot.dynamics()`` uses: Pinocchio's
joint placements, joint axes and link inertias, with the payload merged into its body and the
motors' armature on the diagonal. So it holds for the built-ins, user URDFs and reduced models
alike, and agrees with ``pinocchio.rnea`` to round-off (``tests/planning/test_symbolic.py``).

Conventions are Pinocchio's: each joint frame i sits at
``parent_M_i(q) = placement_i * R(u_i, q_i)``, a rotation about the joint's unit axis u_i;
velocities, accelerations and forces are spatial vectors in the joint's own frame; gravity
enters as the base's acceleration -g.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

if TYPE_CHECKING:
    from app.planning.robots import Robot

__all__ = ["SymbolicChain", "symbolic_chain"]

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class _Body:
    """One joint and the body it moves, in the parent joint's frame (numbers, not symbols)."""

    parent: int  # index into the chain's bodies, -1 for the base
    rotation: FloatArray  # (3, 3) placement rotation in the parent frame
    translation: FloatArray  # (3,) placement translation in the parent frame [m]
    axis: FloatArray  # (3,) unit joint axis in the joint frame
    mass: float  # [kg]
    com: FloatArray  # (3,) centre of mass in the joint frame [m]
    inertia: FloatArray  # (3, 3) inertia about the centre of mass [kg m^2]
    armature: float  # reflected rotor inertia [kg m^2]


def _joint_axes(model: Any) -> list[FloatArray]:
    """Each joint's unit axis in its own frame: the angular part of its motion subspace (read
    from the local joint Jacobian, so every revolute kind, aligned or not, bounded or not,
    is handled alike)."""
    import pinocchio as pin

    data = model.createData()
    pin.computeJointJacobians(model, data, pin.neutral(model))
    axes = []
    for joint_id in range(1, model.njoints):
        jac = pin.getJointJacobian(model, data, joint_id, pin.ReferenceFrame.LOCAL)
        axes.append(np.array(jac[3:6, model.joints[joint_id].idx_v], dtype=np.float64))
    return axes


@dataclass(frozen=True)
class SymbolicChain:
    """A serial or branched chain of revolute joints, ready for symbolic RNEA.

    Attributes:
        bodies: one entry per joint, root to tip (Pinocchio's order).
        gravity: (3,) gravity in the base frame [m/s^2].
    """

    bodies: tuple[_Body, ...]
    gravity: FloatArray

    @property
    def n_joints(self) -> int:
        return len(self.bodies)

    def inverse_dynamics(self, q: Any, qd: Any, qdd: Any) -> Any:
        """τ = M(q) q̈ + C(q, q̇) q̇ + g(q) as CasADi expressions.

        Args:
            q, qd, qdd: (n,) CasADi SX/MX column vectors (or anything indexable with n
                entries) of joint positions [rad], velocities [rad/s], accelerations [rad/s²].

        Returns:
            (n, 1) joint torques [Nm] (rigid bodies + payload + armature), a CasADi expression.
        """
        import casadi as ca

        n = self.n_joints
        rot: list[Any] = []
        pos: list[Any] = []
        vel: list[tuple[Any, Any]] = []
        acc: list[tuple[Any, Any]] = []
        base_acc = (ca.DM.zeros(3), ca.DM(-self.gravity))
        for i, body in enumerate(self.bodies):
            r = ca.DM(body.rotation) @ _rodrigues(ca, body.axis, q[i])
            p = ca.DM(body.translation)
            if body.parent < 0:
                w_p, v_p = ca.DM.zeros(3), ca.DM.zeros(3)
                dw_p, dv_p = base_acc
            else:
                w_p, v_p = vel[body.parent]
                dw_p, dv_p = acc[body.parent]
            axis = ca.DM(body.axis)
            # Parent motion seen in this frame, then the joint's own motion S q̇.
            w = r.T @ w_p + axis * qd[i]
            v = r.T @ (v_p + ca.cross(w_p, p))
            dw = r.T @ dw_p + axis * qdd[i] + ca.cross(w, axis * qd[i])
            dv = r.T @ (dv_p + ca.cross(dw_p, p))
            # The linear part of v × (S q̇): v_lin × (u q̇).
            dv = dv + ca.cross(v, axis * qd[i])
            rot.append(r)
            pos.append(p)
            vel.append((w, v))
            acc.append((dw, dv))
        forces = [self._body_force(ca, b, vel[i], acc[i]) for i, b in enumerate(self.bodies)]
        tau: list[Any] = [None] * n
        for i in range(n - 1, -1, -1):
            body = self.bodies[i]
            n_i, f_i = forces[i]
            tau[i] = ca.dot(ca.DM(body.axis), n_i) + body.armature * qdd[i]
            if body.parent >= 0:
                n_p, f_p = forces[body.parent]
                f_rot = rot[i] @ f_i
                forces[body.parent] = (n_p + rot[i] @ n_i + ca.cross(pos[i], f_rot), f_p + f_rot)
        return ca.vertcat(*tau)

    def joint_placements(self, q: Any) -> list[tuple[Any, Any]]:
        """Forward kinematics: every joint frame's pose in the base frame as CasADi expressions.

        Args:
            q: (n,) joint positions [rad] (CasADi SX/MX or anything indexable).

        Returns:
            One (rotation (3, 3), translation (3, 1) [m]) per joint, root to tip: a point x of
            joint i's frame is at ``rotation @ x + translation`` in the base frame (Pinocchio's
            ``data.oMi``).
        """
        import casadi as ca

        out: list[tuple[Any, Any]] = []
        for i, body in enumerate(self.bodies):
            local_r = ca.DM(body.rotation) @ _rodrigues(ca, body.axis, q[i])
            local_p = ca.DM(body.translation)
            if body.parent < 0:
                out.append((local_r, local_p))
            else:
                parent_r, parent_p = out[body.parent]
                out.append((parent_r @ local_r, parent_p + parent_r @ local_p))
        return out

    @staticmethod
    def _body_force(ca: Any, body: _Body, v: tuple[Any, Any], a: tuple[Any, Any]) -> Any:
        """Spatial force I a + v ×* (I v) on one body, (moment about the origin, force)."""
        c = ca.DM(body.com)
        ic = ca.DM(body.inertia)

        def momentum(w: Any, lin: Any) -> tuple[Any, Any]:
            linear = body.mass * (lin - ca.cross(c, w))
            return ic @ w + ca.cross(c, linear), linear

        w, lin = v
        k_v, l_v = momentum(w, lin)
        k_a, l_a = momentum(*a)
        return k_a + ca.cross(w, k_v) + ca.cross(lin, l_v), l_a + ca.cross(w, l_v)

    def function(self) -> Any:
        """The inverse dynamics as a ``casadi.Function`` ``(q, qd, qdd) -> tau`` on SX."""
        import casadi as ca

        n = self.n_joints
        q, qd, qdd = (ca.SX.sym(name, n) for name in ("q", "qd", "qdd"))
        return ca.Function(
            "inverse_dynamics",
            [q, qd, qdd],
            [self.inverse_dynamics(q, qd, qdd)],
            ["q", "qd", "qdd"],
            ["tau"],
        )


def _rodrigues(ca: Any, axis: FloatArray, angle: Any) -> Any:
    """Rotation matrix about the unit ``axis`` by ``angle`` (a CasADi scalar)."""
    k = ca.DM([[0.0, -axis[2], axis[1]], [axis[2], 0.0, -axis[0]], [-axis[1], axis[0], 0.0]])
    return ca.DM.eye(3) + ca.sin(angle) * k + (1.0 - ca.cos(angle)) * (k @ k)


def symbolic_chain(robot: Robot) -> SymbolicChain:
    """The robot's chain (payload and armature included) from its Pinocchio model.

    Args:
        robot: any loaded robot; its ``dynamics()`` must be a ``PinocchioDynamics``.

    Returns:
        The chain, cached on the robot.
    """
    key = ("symbolic_chain",)
    cached = robot._cache.get(key)
    if cached is not None:
        result: SymbolicChain = cached
        return result
    model = robot.dynamics().model  # type: ignore[attr-defined]
    index = {joint_id: i for i, joint_id in enumerate(range(1, model.njoints))}
    axes = _joint_axes(model)
    bodies = []
    for joint_id in range(1, model.njoints):
        placement = model.jointPlacements[joint_id]
        inertia = model.inertias[joint_id]
        parent = int(model.parents[joint_id])
        bodies.append(
            _Body(
                parent=index.get(parent, -1),
                rotation=np.array(placement.rotation, dtype=np.float64),
                translation=np.array(placement.translation, dtype=np.float64),
                axis=axes[joint_id - 1],
                mass=float(inertia.mass),
                com=np.array(inertia.lever, dtype=np.float64),
                inertia=np.array(inertia.inertia, dtype=np.float64),
                armature=float(model.armature[model.joints[joint_id].idx_v]),
            )
        )
    chain = SymbolicChain(bodies=tuple(bodies), gravity=np.array(model.gravity.linear, float))
    robot._cache[key] = chain
    return chain
