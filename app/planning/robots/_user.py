"""User robots: a URDF (optionally with an MJCF, or an MJCF alone), locks, sidecar, roles.

``user_robot`` turns files into a :class:`Robot` the planner and the simulator can use:

* locked joints (fingers, grippers, a torso) leave the model through Pinocchio's
  ``buildReducedModel`` and are welded in MuJoCo; a mimic joint follows its locked leader;
  unlocked prismatic or mimic joints are refused with the ``--lock`` that would fix it;
* the shoulder and elbow are the joints the user names, else the first two parallel,
  horizontal revolute axes a link apart (a pitch pair: UR's shoulder_lift/elbow, Panda's
  joints 2/4), else joints 2 and 3;
* without an MJCF, MuJoCo compiles the URDF itself (geometry stripped: the simulation needs
  none, and MuJoCo reads neither ``package://`` paths nor COLLADA meshes); with one, the two
  are compared joint by joint at load (``check_same_robot``).
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from app.planning.energy import NOT_MODELLED, MotorModel
from app.planning.robots._identified import identified_urdf, with_friction
from app.planning.robots._sidecar import Sidecar, read_sidecar
from app.planning.robots._types import Payload, Robot, RobotError
from app.planning.robots._urdf import UrdfJoint, UrdfModel, parse_urdf, read_xml

__all__ = ["locks_from_display", "mujoco_ready_urdf", "user_robot"]

#: Heuristic pitch pair: axes within this of horizontal and of parallel, anchors this far apart.
_HORIZONTAL = 0.2
_PARALLEL = 0.2
_MIN_LINK_M = 0.05


def _listing(names: Sequence[str]) -> str:
    return ", ".join(names)


def locks_from_display(file: str | Path, values: Mapping[str, float]) -> dict[str, float]:
    """Lock values typed by a person (deg; m for prismatic joints) in SI units (rad; m).

    Args:
        file: the robot's URDF.
        values: joint name -> value [deg, or m for prismatic joints].

    Raises:
        RobotError: a name that is not a movable joint of the file (the joints are listed).
    """
    model = parse_urdf(Path(file))
    out: dict[str, float] = {}
    for name, value in values.items():
        try:
            joint = model.joint(name)
        except KeyError:
            raise RobotError(
                f"{Path(file).name}: cannot lock '{name}': no such movable joint "
                f"(expected one of {_listing(model.joint_names)})"
            ) from None
        out[name] = float(value) if joint.kind == "prismatic" else math.radians(float(value))
    return out


def _resolve_locks(model: UrdfModel, file: str, locks: Mapping[str, float]) -> dict[str, float]:
    """Checked locks (SI), with mimic joints of locked leaders added; refuses what cannot move."""
    out: dict[str, float] = {}
    for name, value in locks.items():
        try:
            joint = model.joint(name)
        except KeyError:
            raise RobotError(
                f"{file}: cannot lock '{name}': no such movable joint "
                f"(expected one of {_listing(model.joint_names)})"
            ) from None
        if not (math.isfinite(value) and joint.lower - 1e-12 <= value <= joint.upper + 1e-12):
            shown = value if joint.kind == "prismatic" else math.degrees(value)
            lo, hi = (
                (joint.lower, joint.upper)
                if joint.kind == "prismatic"
                else (math.degrees(joint.lower), math.degrees(joint.upper))
            )
            raise RobotError(
                f"{file}: lock {name}={shown:g} {joint.unit}: expected a value within its "
                f"limits [{lo:g}, {hi:g}] {joint.unit}"
            )
        out[name] = float(value)
    for joint in model.joints:
        if joint.mimic is not None and joint.name not in out and joint.mimic[0] in out:
            leader, multiplier, offset = joint.mimic
            out[joint.name] = multiplier * out[leader] + offset
    for joint in model.joints:
        if joint.name in out:
            continue
        if joint.mimic is not None:
            raise RobotError(
                f"{file}: joint '{joint.name}' mimics '{joint.mimic[0]}': expected both locked "
                f"(--lock {joint.mimic[0]}=VALUE locks it too)"
            )
        if joint.kind == "prismatic":
            raise RobotError(
                f"{file}: joint '{joint.name}' is prismatic (a gripper?): expected it locked "
                f"(--lock {joint.name}=VALUE, metres)"
            )
    return out


def _pitch_pair(
    file: Path, locks: Mapping[str, float], free: Sequence[str]
) -> tuple[int, int] | None:
    """The first two parallel horizontal revolute axes a link apart, at the zero pose."""
    import pinocchio as pin

    from app.planning.dynamics import PinocchioDynamics

    model = PinocchioDynamics(file, locks=locks).model
    data = model.createData()
    pin.computeJointJacobians(model, data, pin.neutral(model))
    axes, anchors = [], []
    for j in range(1, model.njoints):
        jac = pin.getJointJacobian(model, data, j, pin.ReferenceFrame.WORLD)
        axes.append(np.array(jac[3:6, model.joints[j].idx_v]))
        anchors.append(np.array(data.oMi[j].translation))
    for i in range(len(free)):
        if abs(axes[i][2]) > _HORIZONTAL:
            continue
        for j in range(i + 1, len(free)):
            parallel = np.linalg.norm(np.cross(axes[i], axes[j])) < _PARALLEL
            offset = anchors[j] - anchors[i]
            apart = np.linalg.norm(offset - (offset @ axes[i]) * axes[i]) > _MIN_LINK_M
            if parallel and apart:
                return i, j
    return None


def _roles(
    file: Path,
    free: list[str],
    locks: Mapping[str, float],
    shoulder: str | None,
    elbow: str | None,
) -> tuple[int, int, str]:
    """(shoulder index, elbow index, how they were chosen)."""
    for role, name in (("shoulder", shoulder), ("elbow", elbow)):
        if name is not None and name not in free:
            why = "it is locked" if name in locks else "no such free joint"
            raise RobotError(
                f"{file.name}: {role} joint '{name}': {why} (expected one of {_listing(free)})"
            )
    if shoulder is not None and elbow is not None:
        if shoulder == elbow:
            raise RobotError(
                f"{file.name}: shoulder and elbow are both '{shoulder}': expected two joints"
            )
        return free.index(shoulder), free.index(elbow), "given"
    pair = _pitch_pair(file, locks, free)
    how = "first two parallel horizontal revolute axes a link apart"
    if pair is None:
        pair = (1, 2) if len(free) >= 3 else (0, 1)
        how = f"no pitch pair found: joints {pair[0] + 1} and {pair[1] + 1}"
    s, e = pair
    if shoulder is not None:
        s = free.index(shoulder)
        e = e if e != s else (s + 1) % len(free)
    if elbow is not None:
        e = free.index(elbow)
        s = s if s != e else (e - 1) % len(free)
    return s, e, how


def _motors(
    file: str, free: Sequence[str], sidecar: Sidecar | None
) -> tuple[tuple[MotorModel, ...], str]:
    if sidecar is None or not sidecar.motors:
        return tuple(NOT_MODELLED for _ in free), "not modelled (no sidecar with motors)"
    unknown = sorted(set(sidecar.motors) - set(free))
    if unknown:
        raise RobotError(
            f"{sidecar.path.name}: motors.{unknown[0]} is not a free joint of {file}: expected "
            f"one of {_listing(free)}"
        )
    missing = [name for name in free if name not in sidecar.motors]
    if missing:
        raise RobotError(
            f"{sidecar.path.name}: no motor for joint '{missing[0]}': expected one motor per "
            f"free joint ({_listing(free)})"
        )
    return tuple(sidecar.motors[name] for name in free), f"sidecar {sidecar.path.name}"


def _default_task(q_min: Any, q_max: Any, shoulder: int, elbow: int) -> tuple[Any, Any]:
    """Start at zero, clipped 1 deg inside the limits (a start on a limit leaves a plan no room
    for round-off); shoulder 20 deg and elbow 150 deg toward the side with more room."""
    margin = np.minimum(math.radians(1.0), (q_max - q_min) / 10.0)
    start = np.clip(np.zeros(len(q_min)), q_min + margin, q_max - margin)
    goal = start.copy()
    for joint, stroke in ((shoulder, 20.0), (elbow, 150.0)):
        up, down = q_max[joint] - start[joint], start[joint] - q_min[joint]
        goal[joint] += math.radians(stroke) if up >= down else -math.radians(stroke)
    return start, np.clip(goal, q_min, q_max)


def mujoco_ready_urdf(urdf: Path) -> Path:
    """A copy of ``urdf`` that MuJoCo's URDF compiler accepts: geometry stripped, every link kept.

    The simulation needs no geometry (contacts are off), and MuJoCo can read neither
    ``package://`` mesh paths nor COLLADA files. ``fusestatic="false"`` keeps links behind fixed
    joints as bodies, so a payload body keeps its name. Written once, content-addressed.
    """
    from app.planning.robots._loader import write_cached

    root = read_xml(urdf, "URDF")
    for link in root.findall("link"):
        for tag in ("visual", "collision"):
            for element in link.findall(tag):
                link.remove(element)
    for element in root.findall("mujoco"):
        root.remove(element)
    extension = ET.SubElement(root, "mujoco")
    compiler = ET.SubElement(extension, "compiler")
    compiler.set("fusestatic", "false")
    compiler.set("discardvisual", "true")
    compiler.set("angle", "radian")
    text = ET.tostring(root, encoding="unicode")
    return write_cached(text, urdf.stem + ".mujoco", ".urdf")


def _payload(
    sidecar: Sidecar | None, mass: float | None, default_body: str, links: Sequence[str], file: str
) -> tuple[Payload, str, str]:
    fields = sidecar.payload if sidecar is not None else None
    body = (fields.body if fields is not None else None) or default_body
    if body not in links:
        raise RobotError(
            f"{sidecar.path.name if sidecar else file}: payload.body '{body}' is not a link of "
            f"{file}: expected one of {_listing(links)}"
        )
    kg = mass if mass is not None else (fields.mass if fields and fields.mass is not None else 0.0)
    com = fields.com if fields and fields.com is not None else (0.0, 0.0, 0.0)
    if fields is not None and fields.size is not None and all(v > 0 for v in fields.size):
        return Payload.box(kg, fields.size, com), body, "sidecar box"
    return Payload.point(kg, com), body, "point mass" + (" (sidecar)" if fields else "")


def _sidecar_of(urdf: Path, model: UrdfModel, sidecar: Path | None) -> Sidecar | None:
    car = read_sidecar(sidecar) if sidecar is not None else None
    if car is not None and car.robot is not None and car.robot != model.name:
        raise RobotError(
            f"{car.path.name}: robot is '{car.robot}' but {urdf.name} is '{model.name}': "
            "expected the sidecar of this robot"
        )
    return car


def _free_joints(
    urdf: Path, model: UrdfModel, car: Sidecar | None, locks: Mapping[str, float] | None
) -> tuple[dict[str, float], list[str], list[str]]:
    """(all locks [SI], every movable joint in Pinocchio's order, the free ones)."""
    from app.planning.dynamics import PinocchioDynamics

    display = dict(car.locks) if car is not None else {}
    merged = {**(locks_from_display(urdf, display) if display else {}), **dict(locks or {})}
    all_locks = _resolve_locks(model, urdf.name, merged)
    order = PinocchioDynamics.joint_order(urdf)
    free = [name for name in order if name not in all_locks]
    if len(free) < 2:
        raise RobotError(
            f"{urdf.name}: {len(free)} free joint(s) {free}: expected at least two "
            "(human shoulder and elbow map onto two joints)"
        )
    return all_locks, order, free


def _speed_limits(
    joints: Sequence[UrdfJoint], car: Sidecar | None, mjcf_only: bool
) -> NDArray[np.float64]:
    """The file's speed limits, the sidecar's overrides; an MJCF's (it has none) unlimited."""
    from app.planning.robots._mjcf_urdf import UNLIMITED_SPEED

    free = [j.name for j in joints]
    speeds = dict(car.velocity_limits) if car is not None else {}
    for name in speeds:
        if name not in free:
            raise RobotError(
                f"{car.path.name if car else ''}: velocity_limits.{name} is not a free joint: "
                f"expected one of {_listing(free)}"
            )
    default = [
        math.inf if mjcf_only and j.velocity == UNLIMITED_SPEED else j.velocity for j in joints
    ]
    return np.array([speeds.get(j.name, d) for j, d in zip(joints, default, strict=True)])


def user_robot(
    urdf: Path,
    *,
    mjcf: Path | None = None,
    payload: float | None = None,
    shoulder_joint: str | None = None,
    elbow_joint: str | None = None,
    locks: Mapping[str, float] | None = None,
    sidecar: Path | None = None,
    package_dirs: Sequence[Path] = (),
    mjcf_only: bool = False,
) -> Robot:
    """A robot from a user URDF; see :func:`app.planning.robots.load_robot` for the arguments."""
    model = parse_urdf(urdf)
    car = _sidecar_of(urdf, model, sidecar)
    all_locks, order, free = _free_joints(urdf, model, car, locks)
    joints = [model.joint(name) for name in free]
    shoulder, elbow, how = _roles(
        urdf,
        free,
        all_locks,
        shoulder_joint or (car.shoulder_joint if car else None),
        elbow_joint or (car.elbow_joint if car else None),
    )
    q_min = np.array([j.lower for j in joints])
    q_max = np.array([j.upper for j in joints])
    motors, motor_source = _motors(urdf.name, free, car)
    motors = with_friction(motors, free, car)
    model_urdf = identified_urdf(urdf, car)  # the sidecar's identified link inertias applied
    if model_urdf != urdf and mjcf is not None and not mjcf_only:
        raise RobotError(
            f"{car.path.name if car else urdf.name}: identified links with MJCF {mjcf.name}: "
            "expected the URDF alone (MuJoCo then compiles the identified URDF)"
        )
    body_payload, body, payload_kind = _payload(
        car, payload, joints[-1].child, model.links, urdf.name
    )
    start, goal = _default_task(q_min, q_max, shoulder, elbow)
    robot = Robot(
        name=model.name,
        joint_names=tuple(free),
        urdf_path=model_urdf.resolve(),
        mjcf_path=(
            mjcf.resolve()
            if mjcf is not None and model_urdf == urdf
            else mujoco_ready_urdf(model_urdf)
        ),
        q_min=q_min,
        q_max=q_max,
        qd_max=_speed_limits(joints, car, mjcf_only),
        tau_max=np.array([j.effort for j in joints]),
        motors=motors,
        payload=body_payload,
        payload_body=body,
        default_start=start,
        default_goal=goal,
        shoulder_joint=shoulder,
        elbow_joint=elbow,
        parameters=_parameters(
            urdf, mjcf, mjcf_only, motor_source, body, payload_kind, how, all_locks
        ),
        locks=all_locks,
        all_joint_names=tuple(order),
        package_dirs=tuple(package_dirs),
        spec={
            "source": str(urdf.resolve()),
            "mjcf": None if mjcf is None else str(mjcf.resolve()),
            "payload": float(body_payload.mass),
            "shoulder_joint": free[shoulder],
            "elbow_joint": free[elbow],
            "locks": dict(all_locks),
            "sidecar": None if car is None else str(car.path),
            "package_dirs": [str(Path(p).resolve()) for p in package_dirs],
            **({"mjcf_only": True} if mjcf_only else {}),
        },
    )
    if mjcf is not None:
        from app.planning.robots._consistency import check_same_robot

        check_same_robot(robot)
    return robot


def _parameters(
    urdf: Path,
    mjcf: Path | None,
    mjcf_only: bool,
    motor_source: str,
    body: str,
    payload_kind: str,
    how: str,
    locks: Mapping[str, float],
) -> tuple[dict[str, object], ...]:
    if mjcf_only:
        simulator = "MJCF (the URDF was generated from it)"
    elif mjcf is not None:
        simulator = f"MJCF {mjcf.name}, checked against the URDF at load"
    else:
        simulator = "MuJoCo's URDF compiler on the URDF (geometry stripped)"
    rows: list[dict[str, object]] = [
        {"name": "urdf", "value": str(urdf), "unit": "", "source": "user file"},
        {"name": "simulation model", "value": simulator, "unit": "", "source": "load_robot"},
        {"name": "motors", "value": motor_source, "unit": "", "source": "sidecar or default"},
        {"name": "payload.body", "value": body, "unit": "", "source": payload_kind},
        {"name": "shoulder/elbow", "value": how, "unit": "", "source": "load_robot"},
    ]
    for name, value in locks.items():
        rows.append(
            {"name": f"lock.{name}", "value": value, "unit": "rad or m", "source": "locked"}
        )
    return tuple(rows)
