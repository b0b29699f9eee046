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
from app.planning.robots._cache import write_cached
from app.planning.robots._identified import identified_urdf, with_friction
from app.planning.robots._sidecar import Sidecar, read_sidecar
from app.planning.robots._types import (
    DEFAULT_JERK_TIME,
    DEFAULT_RAMP_TIME,
    Payload,
    Robot,
    RobotError,
)
from app.planning.robots._urdf import UrdfJoint, UrdfModel, parse_urdf, read_xml

__all__ = ["locks_from_display", "missing_meshes", "mujoco_ready_urdf", "user_robot"]

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
        joint = _lockable_joint(model, Path(file).name, name)
        out[name] = float(value) if joint.kind == "prismatic" else math.radians(float(value))
    return out


def missing_meshes(robot: Robot) -> list[str]:
    """The mesh references of a user URDF that resolve to no file (``package://`` paths
    against the robot's package folders, relative ones against the URDF's folder), each once,
    in file order: the viewer draws those links without their bodies. Empty for a built-in
    robot or an MJCF alone (MuJoCo opens every file an MJCF names at load).
    """
    from app.planning.robots._package import resolve_mesh

    source = robot.spec.get("source") if robot.spec else None
    if not isinstance(source, str) or not source.lower().endswith(".urdf"):
        return []
    urdf = Path(source)
    if not urdf.is_file():
        return []
    out: list[str] = []
    for reference in parse_urdf(urdf).meshes:
        if reference and reference not in out:
            found = resolve_mesh(
                reference, base_dir=urdf.parent, package_dirs=tuple(robot.package_dirs)
            )
            if found is None:
                out.append(reference)
    return out


def _lockable_joint(model: UrdfModel, file: str, name: str) -> UrdfJoint:
    """The movable joint ``name`` of ``model`` (from ``file``), which a lock may hold."""
    try:
        return model.joint(name)
    except KeyError:
        raise RobotError(
            f"{file}: cannot lock '{name}': no such movable joint "
            f"(expected one of {_listing(model.joint_names)})"
        ) from None


def _checked_locks(model: UrdfModel, file: str, locks: Mapping[str, float]) -> dict[str, float]:
    """Locks (SI) of known joints within their limits (any finite value for a joint without
    limits: a caster, a wheel, a continuous joint), with mimic joints of locked leaders added."""
    out: dict[str, float] = {}
    for name, value in locks.items():
        joint = _lockable_joint(model, file, name)
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
    return _with_mimics(model, out)


def _with_mimics(model: UrdfModel, locks: dict[str, float]) -> dict[str, float]:
    out = dict(locks)
    for joint in model.joints:
        if joint.mimic is not None and joint.name not in out and joint.mimic[0] in out:
            leader, multiplier, offset = joint.mimic
            out[joint.name] = multiplier * out[leader] + offset
    return out


def _neutral(joint: UrdfJoint) -> float:
    """A lock value for a joint that cannot move the arm (another branch): zero, clipped into
    its limits."""
    return float(min(max(0.0, joint.lower), joint.upper))


def _branches(model: UrdfModel, free: Sequence[str]) -> list[list[str]]:
    """The free joints as maximal serial runs: a run starts at a free joint whose nearest free
    ancestor is none or has several free children, and follows single free children."""
    free_set = set(free)
    above: dict[str, str | None] = {}
    for name in free:
        chain = [j for j in model.ancestors(model.joint(name).child)[:-1] if j in free_set]
        above[name] = chain[-1] if chain else None
    below: dict[str | None, list[str]] = {}
    for name in free:
        below.setdefault(above[name], []).append(name)
    heads = [n for n in free if above[n] is None or len(below.get(above[n], [])) > 1]
    runs = []
    for head in heads:
        run = [head]
        while len(below.get(run[-1], [])) == 1:
            run.append(below[run[-1]][0])
        runs.append(run)
    return runs


def _shown_runs(runs: Sequence[Sequence[str]], most: int = 8) -> str:
    text = "; ".join(_run_text(r) for r in runs[:most])
    return text + (f"; and {len(runs) - most} more" if len(runs) > most else "")


def _run_text(run: Sequence[str]) -> str:
    return run[0] if len(run) == 1 else f"{run[0]}…{run[-1]} ({len(run)} joints)"


def _arm_chain(
    model: UrdfModel, file: str, base: str, tip: str | None, locked: Mapping[str, float]
) -> tuple[dict[str, float], list[tuple[str, str]]]:
    """Joints off the arm named by its base link (and tip link): (automatic locks of the
    joints on other branches, which cannot move the arm's links; the reasons of the joints the
    user must lock: the base's movable ancestors place it, the joints the arm carries move
    its load)."""
    for role, link in (("base_link", base), ("tip_link", tip)):
        if link is not None and link not in model.links:
            raise RobotError(
                f"{file}: {role} '{link}' is not a link: expected one of {_listing(model.links)}"
            )
    movable = set(model.joint_names)
    above_base = [j for j in model.ancestors(base) if j in movable]
    chain: list[str] = []
    if tip is not None:
        path = model.ancestors(tip)
        if path[: len(model.ancestors(base))] != model.ancestors(base) or tip == base:
            raise RobotError(
                f"{file}: tip_link '{tip}' does not lie below base_link '{base}': expected a "
                "link of the arm that the base carries"
            )
        chain = [j for j in path[len(model.ancestors(base)) :] if j in movable]
    auto: dict[str, float] = {}
    needed: list[tuple[str, str]] = []
    for joint in model.joints:
        name = joint.name
        if name in locked:
            continue
        if name in above_base:
            needed.append((name, f"joint '{name}' places the arm's base link '{base}'"))
        elif not _below(model, joint.child, base):
            auto[name] = _neutral(joint)  # another branch: it moves nothing of the arm's
        elif chain and name not in chain:
            if any(c in model.ancestors(joint.child) for c in chain):
                needed.append((name, f"joint '{name}' is carried by the arm off its chain"))
            else:
                auto[name] = _neutral(joint)  # a sibling branch on the base link
    return auto, needed


def _below(model: UrdfModel, link: str, base: str) -> bool:
    """Whether ``link`` is ``base`` or lies below it in the tree."""
    while True:
        if link == base:
            return True
        if link not in model.parents:
            return False
        link = model.parents[link][1]


def _lock_hint(model: UrdfModel, names: Sequence[str]) -> str:
    units = {model.joint(n).unit for n in names}
    unit = "degrees" if units == {"deg"} else "metres" if units == {"m"} else "deg or m"
    return " ".join(f"--lock {n}=VALUE" for n in names) + f", {unit}"


def _resolve_locks(
    model: UrdfModel,
    file: str,
    locks: Mapping[str, float],
    *,
    base_link: str | None = None,
    tip_link: str | None = None,
    car: Sidecar | None = None,
) -> tuple[dict[str, float], dict[str, float]]:
    """(every lock [SI], the automatic ones among them). Refuses, in one message, everything
    that must be locked: unlocked prismatic, mimic and limitless joints, the base's movable
    ancestors, joints the arm carries off its chain; and a robot whose free joints branch
    (legs, two arms, a head) unless the arm's base link is named."""
    out = _checked_locks(model, file, locks)
    auto: dict[str, float] = {}
    needed: list[tuple[str, str]] = []
    if base_link is not None:
        auto, reasons = _arm_chain(model, file, base_link, tip_link, out)
        needed += reasons
        out = _with_mimics(model, {**out, **auto})
        auto = {k: v for k, v in out.items() if k not in locks}
    given_limits = set(car.velocity_limits) & set(car.effort_limits) if car else set()
    for joint in model.joints:
        if joint.name in out or any(joint.name == n for n, _ in needed):
            continue
        if joint.mimic is not None:
            needed.append((joint.name, f"joint '{joint.name}' mimics '{joint.mimic[0]}'"))
        elif joint.kind == "prismatic":
            needed.append((joint.name, f"joint '{joint.name}' is prismatic (a gripper?)"))
        elif not joint.limited and joint.name not in given_limits:
            needed.append((joint.name, f"joint '{joint.name}' has no <limit>"))
    free = [j.name for j in model.joints if j.name not in out and j.name not in dict(needed)]
    runs = _branches(model, free)
    if len(runs) > 1:  # the base link decides which locks are needed: ask for it first
        bases = sorted({model.joint(run[0]).parent for run in runs})
        advice = (
            f"expected the arm's base link (--base-link LINK or sidecar base_link, e.g. one of "
            f"{_listing(bases)}) and, if the arm branches, its tip link (--tip-link)"
            if base_link is None or tip_link is None
            else "expected locks for the branches off the arm"
        )
        raise RobotError(
            f"{file}: the free joints branch into {len(runs)} chains "
            f"({_shown_runs(runs)}): a legged, mobile or multi-arm robot "
            f"plans one serial arm: {advice}"
        )
    if needed:
        names = [n for n, _ in needed]
        if len(needed) == 1:
            what = f"expected it locked ({_lock_hint(model, names)})"
            if not model.joint(names[0]).limited:
                what += " or a <limit> with lower, upper, velocity and effort"
        else:
            what = f"expected them locked in one go ({_lock_hint(model, names)}; or sidecar locks)"
        raise RobotError(f"{file}: " + "; ".join(r for _, r in needed) + ": " + what)
    return out, auto


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
    pair = _pitch_pair(unique_frame_names(file)[0], locks, free)
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


#: Smallest principal inertia MuJoCo is given, relative to the link's largest [-] (and at least
#: ``_INERTIA_FLOOR`` kg m^2): a zero or round-off-negative one (a thin rod, a placeholder
#: link) stops its compiler with "inertia must have positive eigenvalues".
_INERTIA_RELATIVE = 1e-6
_INERTIA_FLOOR = 1e-12


def _repaired_inertia(link: ET.Element) -> str | None:
    """Raise a link's principal inertias to positive values obeying the triangle inequality
    (A + B >= C), in place; what was changed, or None when MuJoCo accepts it as it is."""
    inertia = link.find("inertial/inertia")
    if inertia is None:
        return None
    keys = ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")
    try:
        v = {k: float(inertia.get(k, "0")) for k in keys}
    except ValueError:
        return None
    tensor = np.array(
        [
            [v["ixx"], v["ixy"], v["ixz"]],
            [v["ixy"], v["iyy"], v["iyz"]],
            [v["ixz"], v["iyz"], v["izz"]],
        ]
    )
    values, axes = np.linalg.eigh(tensor)
    if not np.all(np.isfinite(values)) or not np.any(values > 0):
        return None  # an all-zero inertia (a point mass or a frame): MuJoCo accepts it
    floor = max(_INERTIA_RELATIVE * float(values.max()), _INERTIA_FLOOR)
    fixed = np.maximum(values, floor)
    fixed[0] = max(fixed[0], fixed[2] - fixed[1])  # A + B >= C (sorted ascending)
    if np.all(values >= floor) and values[0] + values[1] >= values[2] * (1 - 1e-9):
        return None
    new = axes @ np.diag(fixed) @ axes.T
    for k, (i, j) in zip(keys, ((0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2)), strict=True):
        inertia.set(k, repr(float(new[i, j])))
    shown = ", ".join(f"{x:.3g}" for x in values)
    return (
        f"{link.get('name')}: principal inertias [{shown}] kg m^2 raised to "
        f"[{', '.join(f'{x:.3g}' for x in fixed)}]"
    )


def mujoco_ready(urdf: Path) -> tuple[Path, tuple[str, ...]]:
    """:func:`mujoco_ready_urdf` and the inertia repairs it made (one line per link)."""

    root = read_xml(urdf, "URDF")
    repairs = []
    for link in root.findall("link"):
        for tag in ("visual", "collision"):
            for element in link.findall(tag):
                link.remove(element)
        if (note := _repaired_inertia(link)) is not None:
            repairs.append(note)
    for element in root.findall("mujoco"):
        root.remove(element)
    extension = ET.SubElement(root, "mujoco")
    compiler = ET.SubElement(extension, "compiler")
    compiler.set("fusestatic", "false")
    compiler.set("discardvisual", "true")
    compiler.set("angle", "radian")
    text = ET.tostring(root, encoding="unicode")
    return write_cached(text, urdf.stem + ".mujoco", ".urdf"), tuple(repairs)


def mujoco_ready_urdf(urdf: Path) -> Path:
    """A copy of ``urdf`` that MuJoCo's URDF compiler accepts: geometry stripped, every link kept.

    The simulation needs no geometry (contacts are off), and MuJoCo can read neither
    ``package://`` mesh paths nor COLLADA files. ``fusestatic="false"`` keeps links behind fixed
    joints as bodies, so a payload body keeps its name. A link inertia MuJoCo refuses (a zero
    or negative principal inertia, or one breaking A + B >= C: a thin rod, a placeholder link)
    is raised to the smallest it accepts (at least 1e-6 of the link's largest, the smallest one
    raised until A + B >= C); the robot's
    parameters list every such repair (Pinocchio keeps the file's values). Written once,
    content-addressed.
    """
    return mujoco_ready(urdf)[0]


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
    urdf: Path,
    model: UrdfModel,
    car: Sidecar | None,
    locks: Mapping[str, float] | None,
    chain: tuple[str | None, str | None] = (None, None),
) -> tuple[dict[str, float], list[str], list[str], dict[str, float]]:
    """(all locks [SI], every movable joint in Pinocchio's order, the free ones, the automatic
    locks of joints off the arm)."""
    from app.planning.dynamics import PinocchioDynamics

    display = dict(car.locks) if car is not None else {}
    merged = {**(locks_from_display(urdf, display) if display else {}), **dict(locks or {})}
    all_locks, auto = _resolve_locks(
        model, urdf.name, merged, base_link=chain[0], tip_link=chain[1], car=car
    )
    order = PinocchioDynamics.joint_order(urdf)
    free = [name for name in order if name not in all_locks]
    if len(free) < 2:
        raise RobotError(
            f"{urdf.name}: {len(free)} free joint(s) {free}: expected at least two "
            "(human shoulder and elbow map onto two joints)"
        )
    return all_locks, order, free, auto


def _sidecar_limits(
    joints: Sequence[UrdfJoint], car: Sidecar | None, field: str
) -> dict[str, float]:
    free = [j.name for j in joints]
    values: dict[str, float] = dict(getattr(car, field)) if car is not None else {}
    for name in values:
        if name not in free:
            raise RobotError(
                f"{car.path.name if car else ''}: {field}.{name} is not a free joint: "
                f"expected one of {_listing(free)}"
            )
    return values


def _speed_limits(
    joints: Sequence[UrdfJoint], car: Sidecar | None, mjcf_only: bool
) -> NDArray[np.float64]:
    """The file's speed limits, the sidecar's overrides; an MJCF's (it has none) unlimited."""
    from app.planning.robots._mjcf_urdf import UNLIMITED_SPEED

    speeds = _sidecar_limits(joints, car, "velocity_limits")
    default = [
        math.inf if mjcf_only and j.velocity == UNLIMITED_SPEED else j.velocity for j in joints
    ]
    return np.array([speeds.get(j.name, d) for j, d in zip(joints, default, strict=True)])


def _effort_limits(
    joints: Sequence[UrdfJoint], car: Sidecar | None, file: str
) -> NDArray[np.float64]:
    """The file's effort limits with the sidecar's overrides; an MJCF joint without a force
    limit (no ``actuatorfrcrange``, no limited motor) needs the sidecar's."""
    from app.planning.robots._mjcf_urdf import UNLIMITED_EFFORT

    efforts = _sidecar_limits(joints, car, "effort_limits")
    out = [efforts.get(j.name, j.effort) for j in joints]
    missing = [j.name for j, v in zip(joints, out, strict=True) if v >= UNLIMITED_EFFORT]
    if missing:
        raise RobotError(
            f"{file}: joint(s) {_listing(missing)} have no force limit: expected "
            "actuatorfrcrange on the joint, a motor with forcerange or ctrlrange, or a sidecar "
            f"with effort_limits ({', '.join(f'{n}: NM' for n in missing)}; docs/robots.md)"
        )
    return np.array(out)


def unique_frame_names(
    urdf: Path, package_dirs: Sequence[Path] = ()
) -> tuple[Path, tuple[str, ...]]:
    """``urdf``, or a copy in which every fixed joint named like a link is renamed
    ``NAME_fixed``, and the renames (``"old -> new"``).

    Pinocchio gives a fixed joint and a link frames of their own names; when the names are the
    same (example-robot-data's b1-z1: ``gripperStator``) locking joints fails with "several
    frames match". A fixed joint's name names nothing a user plans with, so renaming it changes
    nothing else. The copy is cached; its mesh references are made absolute (resolved from the
    original file's folder), so the viewer and the safety check still find the meshes.
    """
    from app.planning.robots._package import resolve_mesh

    root = read_xml(urdf, "URDF")
    links = {link.get("name") for link in root.findall("link")}
    taken = links | {joint.get("name") for joint in root.findall("joint")}
    renamed = []
    for joint in root.findall("joint"):
        name = joint.get("name")
        if joint.get("type") != "fixed" or name not in links:
            continue
        new, k = f"{name}_fixed", 2
        while new in taken:
            new, k = f"{name}_fixed{k}", k + 1
        joint.set("name", new)
        taken.add(new)
        renamed.append(f"{name} -> {new}")
    if not renamed:
        return urdf, ()
    folder = urdf.resolve().parent
    for mesh in root.iter("mesh"):
        reference = mesh.get("filename", "")
        found = resolve_mesh(reference, base_dir=folder, package_dirs=package_dirs)
        if reference and found is not None:
            mesh.set("filename", str(found))
    text = ET.tostring(root, encoding="unicode")
    return write_cached(text, urdf.stem + ".frames", ".urdf"), tuple(renamed)


def _rename_rows(renamed: Sequence[str]) -> tuple[dict[str, object], ...]:
    source = "Pinocchio needs unique frame names (a fixed joint named as its link)"
    return tuple(
        {"name": "renamed fixed joint", "value": note, "unit": "", "source": source}
        for note in renamed
    )


def _controller_limits(
    joints: Sequence[UrdfJoint], car: Sidecar | None, qd_max: NDArray[np.float64]
) -> dict[str, Any]:
    """``qdd_max``, ``jerk_max`` and ``stated_limits`` of :class:`Robot`: the sidecar's
    ``acceleration_limits``/``jerk_limits`` where given (stated), the defaults elsewhere."""
    if car is None or not (car.acceleration_limits or car.jerk_limits):
        return {}
    accelerations = _sidecar_limits(joints, car, "acceleration_limits")
    jerks = _sidecar_limits(joints, car, "jerk_limits")
    qdd = [
        accelerations.get(j.name, v / DEFAULT_RAMP_TIME)
        for j, v in zip(joints, qd_max, strict=True)
    ]
    jerk = [jerks.get(j.name, a / DEFAULT_JERK_TIME) for j, a in zip(joints, qdd, strict=True)]
    return {
        "qdd_max": np.array(qdd, dtype=np.float64),
        "jerk_max": np.array(jerk, dtype=np.float64),
        "stated_limits": {
            "acceleration": tuple(j.name for j in joints if j.name in accelerations),
            "jerk": tuple(j.name for j in joints if j.name in jerks),
        },
    }


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
    base_link: str | None = None,
    tip_link: str | None = None,
) -> Robot:
    """A robot from a user URDF; see :func:`app.planning.robots.load_robot` for the arguments."""
    model = parse_urdf(urdf)
    car = _sidecar_of(urdf, model, sidecar)
    base_link, tip_link = _chain_ends(urdf, car, base_link, tip_link)
    all_locks, order, free, auto = _free_joints(urdf, model, car, locks, (base_link, tip_link))
    joints = [model.joint(name) for name in free]
    shoulder_joint = shoulder_joint or (car.shoulder_joint if car else None)
    elbow_joint = elbow_joint or (car.elbow_joint if car else None)
    shoulder, elbow, how = _roles(urdf, free, all_locks, shoulder_joint, elbow_joint)
    q_min = np.array([j.lower for j in joints])
    q_max = np.array([j.upper for j in joints])
    motors, motor_source = _motors(urdf.name, free, car)
    motors = with_friction(motors, free, car)
    model_urdf, renamed = _model_urdf(urdf, car, mjcf, mjcf_only, package_dirs)
    # The user's MJCF is simulated only when it describes the URDF as given.
    own_mjcf = mjcf if mjcf is not None and model_urdf == urdf else None
    body_payload, body, payload_kind = _payload(
        car, payload, joints[-1].child, model.links, urdf.name
    )
    start, goal = _default_task(q_min, q_max, shoulder, elbow)
    qd_max = _speed_limits(joints, car, mjcf_only)
    robot = Robot(
        name=model.name,
        joint_names=tuple(free),
        urdf_path=model_urdf.resolve(),
        mjcf_path=own_mjcf.resolve() if own_mjcf else mujoco_ready(model_urdf)[0],
        q_min=q_min,
        q_max=q_max,
        qd_max=qd_max,
        tau_max=_effort_limits(joints, car, (mjcf.name if mjcf_only and mjcf else urdf.name)),
        **_controller_limits(joints, car, qd_max),
        motors=motors,
        payload=body_payload,
        payload_body=body,
        default_start=start,
        default_goal=goal,
        shoulder_joint=shoulder,
        elbow_joint=elbow,
        parameters=_parameters(
            urdf, mjcf, mjcf_only, motor_source, body, payload_kind, how, all_locks, auto
        )
        + _repair_rows(None if own_mjcf else model_urdf)
        + _rename_rows(renamed),
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
            **_optional_spec(mjcf_only=mjcf_only, base_link=base_link, tip_link=tip_link),
        },
    )
    if mjcf is not None:
        from app.planning.robots._consistency import check_same_robot

        check_same_robot(robot)
    return robot


def _model_urdf(
    urdf: Path,
    car: Sidecar | None,
    mjcf: Path | None,
    mjcf_only: bool,
    package_dirs: Sequence[Path],
) -> tuple[Path, tuple[str, ...]]:
    """The URDF the models are built from: the sidecar's identified link inertias applied and
    frame names made unique (a cached copy when either changes anything, else ``urdf``), with
    the renames. A user MJCF beside an identified URDF is refused."""
    model_urdf = identified_urdf(urdf, car)
    model_urdf, renamed = unique_frame_names(model_urdf, package_dirs)
    if model_urdf != urdf and mjcf is not None and not mjcf_only:
        raise RobotError(
            f"{car.path.name if car else urdf.name}: identified links with MJCF {mjcf.name}: "
            "expected the URDF alone (MuJoCo then compiles the identified URDF)"
        )
    return model_urdf, renamed


def _chain_ends(
    urdf: Path, car: Sidecar | None, base_link: str | None, tip_link: str | None
) -> tuple[str | None, str | None]:
    """(base link, tip link) of the arm on a branching robot: the arguments, else the
    sidecar's; a tip without a base is refused."""
    base_link = base_link or (car.base_link if car else None)
    tip_link = tip_link or (car.tip_link if car else None)
    if tip_link is not None and base_link is None:
        raise RobotError(
            f"{urdf.name}: tip_link '{tip_link}' without base_link: expected both "
            "(--base-link and --tip-link)"
        )
    return base_link, tip_link


def _optional_spec(
    *, mjcf_only: bool, base_link: str | None, tip_link: str | None
) -> dict[str, object]:
    """The entries of ``Robot.spec`` written only when they differ from their defaults (so
    that specs saved before these options existed read back unchanged)."""
    return {
        **({"mjcf_only": True} if mjcf_only else {}),
        **({"base_link": base_link} if base_link is not None else {}),
        **({"tip_link": tip_link} if tip_link is not None else {}),
    }


def _repair_rows(urdf: Path | None) -> tuple[dict[str, object], ...]:
    """The inertia repairs of the MuJoCo copy of ``urdf`` (none with the user's own MJCF)."""
    if urdf is None:
        return ()
    return tuple(
        {
            "name": "mujoco inertia repair",
            "value": note,
            "unit": "",
            "source": "MuJoCo needs positive principal inertias with A + B >= C",
        }
        for note in mujoco_ready(urdf)[1]
    )


def _parameters(
    urdf: Path,
    mjcf: Path | None,
    mjcf_only: bool,
    motor_source: str,
    body: str,
    payload_kind: str,
    how: str,
    locks: Mapping[str, float],
    auto: Mapping[str, float] | None = None,
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
        source = "off the arm (no effect on it)" if auto and name in auto else "locked"
        rows.append({"name": f"lock.{name}", "value": value, "unit": "rad or m", "source": source})
    return tuple(rows)
