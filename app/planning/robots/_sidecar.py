"""The robot sidecar: motors, gears, payload, locks and the shoulder/elbow choice, in YAML.

The format is documented in ``docs/robots.md``. Values a person types are in display units:
lock values in degrees (metres for prismatic joints), everything else SI. Every error names the
file and the field (``motors.elbow_joint.gear_ratio``) and what was expected.

A sidecar is read with limits (``MAX_SIDECAR_BYTES``, ``MAX_DEPTH``, ``MAX_ALIASES``,
``MAX_NODES``, ``MAX_DIGITS``): a 362-byte file of nested anchors ("billion laughs") held a
parse slot for 23-52 s while an error message spelled it out, a 5,000-digit integer and a
10,000-deep nesting were server errors. Messages quote a value only when it is short, never a
whole parsed structure.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from app.errors import one_line
from app.planning.energy import MotorModel
from app.planning.robots._types import RobotError

#: Sidecar fields of one joint's actuator: name -> (unit, required) (checked further, with the
#: joint's motor, by ``app.planning.actuators.envelope_from_fields``).
ACTUATOR_FIELDS: dict[str, tuple[str, bool]] = {
    "peak_torque": ("Nm", True),
    "rated_speed": ("rad/s", True),
    "max_speed": ("rad/s", False),
    "corner_speed": ("rad/s", False),
    "bus_voltage": ("V", False),
    "rms_torque": ("Nm", True),
    "duty_cycle": ("s", True),
}

__all__ = [
    "MAX_ALIASES",
    "MAX_DEPTH",
    "MAX_DIGITS",
    "MAX_NODES",
    "MAX_SIDECAR_BYTES",
    "MOTOR_FIELDS",
    "Sidecar",
    "SidecarPayload",
    "read_sidecar",
]

#: Largest sidecar file [bytes]: one lists a few dozen joints in a few kilobytes.
MAX_SIDECAR_BYTES = 256 * 1024
#: Deepest nesting of mappings and lists (a sidecar needs four: ``motors.joint.field``).
MAX_DEPTH = 20
#: Most aliases (``*name``) in one sidecar (anchors may share a motor block between joints).
MAX_ALIASES = 200
#: Most values the document holds with every alias spelled out.
MAX_NODES = 20_000
#: Longest number literal [characters] (Python refuses to read integers past 4,300 digits).
MAX_DIGITS = 100

#: Motor fields: name -> (unit, lower bound, bound included, required).
MOTOR_FIELDS: dict[str, tuple[str, float, bool, bool]] = {
    "gear_ratio": ("-", 1.0, True, True),
    "torque_constant": ("Nm/A", 0.0, False, True),
    "winding_resistance": ("ohm", 0.0, True, True),
    "rotor_inertia": ("kg m^2", 0.0, True, False),
    "viscous_friction": ("Nm s/rad", 0.0, True, False),
    "coulomb_friction": ("Nm", 0.0, True, False),
    "regen_efficiency": ("-", 0.0, True, False),
}
_TOP: tuple[str, ...] = ("robot", "shoulder_joint", "elbow_joint", "locks", "payload", "motors")
#: Speed overrides, and identified parameters (``bioplan identify``; see ``_identified.py``).
_TOP += ("velocity_limits", "links", "friction")
#: Effort limits (an MJCF without ``actuatorfrcrange``) and the arm's chain on a robot with
#: several branches (legs, a second arm, a head: docs/robots.md, onboarding rules).
_TOP += ("effort_limits", "base_link", "tip_link")
#: The workspace the safety check uses (``_obstacles.py``, ``app.planning.safety``).
_TOP += ("obstacles", "mount_plane", "srdf")
#: Actuator limits per joint: torque–speed envelope and RMS torque (``app.planning.actuators``).
_TOP += ("actuators",)
#: Controller limits a robot states (the export gates them; a URDF has no such field).
_TOP += ("acceleration_limits", "jerk_limits")
_PAYLOAD = ("mass", "body", "com", "size")


@dataclass(frozen=True)
class SidecarPayload:
    """Payload fields of a sidecar (each None when not given)."""

    mass: float | None = None
    body: str | None = None
    com: tuple[float, float, float] | None = None
    size: tuple[float, float, float] | None = None


@dataclass(frozen=True)
class Sidecar:
    """A parsed sidecar.

    Attributes:
        path: the file.
        robot: the robot name the sidecar was written for (checked against the URDF's).
        shoulder_joint, elbow_joint: joint names, or None.
        locks: joint -> value in display units (deg, or m for prismatic joints).
        payload: payload fields.
        motors: joint -> motor model (empty: motors not modelled).
        velocity_limits: joint -> speed limit [rad/s or m/s] overriding the model file's.
        effort_limits: joint -> torque [Nm] or force [N] limit overriding the model file's.
        acceleration_limits, jerk_limits: joint -> the controller's acceleration [rad/s^2]
            and jerk [rad/s^3] limit (stated limits: exports are refused past them).
        base_link, tip_link: the arm's base and end link on a branched robot, or None.
        links: link -> identified ``LinkInertial`` replacing the URDF's inertial.
        friction: joint -> identified ``JointFriction`` (viscous, Coulomb, torque offset).
        obstacles: fixed obstacles for the safety check (``Obstacle``, base frame).
        mount_plane: the mounting plane's height and whether it is checked.
        srdf: an SRDF whose disabled collision pairs the safety check honours (resolved
            against the sidecar's folder), or None.
    """

    path: Path
    robot: str | None = None
    shoulder_joint: str | None = None
    elbow_joint: str | None = None
    locks: Mapping[str, float] = field(default_factory=dict)
    payload: SidecarPayload = field(default_factory=SidecarPayload)
    motors: Mapping[str, MotorModel] = field(default_factory=dict)
    velocity_limits: Mapping[str, float] = field(default_factory=dict)
    effort_limits: Mapping[str, float] = field(default_factory=dict)
    acceleration_limits: Mapping[str, float] = field(default_factory=dict)
    jerk_limits: Mapping[str, float] = field(default_factory=dict)
    base_link: str | None = None
    tip_link: str | None = None
    links: Mapping[str, Any] = field(default_factory=dict)
    friction: Mapping[str, Any] = field(default_factory=dict)
    obstacles: tuple[Any, ...] = ()
    mount_plane: Any = None
    srdf: Path | None = None
    # Actuator limits: joint -> {field: value} (:data:`ACTUATOR_FIELDS`).
    actuators: Mapping[str, Mapping[str, float]] = field(default_factory=dict)


class _Fields:
    """Typed reads of a YAML mapping, with errors that name the file and the field path."""

    def __init__(self, file: str) -> None:
        self.file = file

    def fail(self, where: str, got: Any, expected: str) -> RobotError:
        return RobotError(
            f"{self.file}: {one_line(where, 120)} is {_shown(got)}: expected {expected}"
        )

    def mapping(self, where: str, value: Any) -> dict[str, Any]:
        if value is None:
            return {}
        if not isinstance(value, dict) or not all(isinstance(k, str) for k in value):
            raise self.fail(where, value, "a mapping of names to values")
        return value

    def number(
        self, where: str, value: Any, *, lower: float | None = None, strict: bool = False
    ) -> float:
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise self.fail(where, value, "a number")
        number = float(value)
        if not math.isfinite(number):
            raise self.fail(where, value, "a finite number")
        if lower is not None and (number < lower or (strict and number == lower)):
            raise self.fail(where, value, f"a number {'>' if strict else '>='} {lower:g}")
        return number

    def text(self, where: str, value: Any) -> str | None:
        if value is None:
            return None
        if not isinstance(value, str) or not value:
            raise self.fail(where, value, "a name")
        return value

    def vector(self, where: str, value: Any) -> tuple[float, float, float] | None:
        if value is None:
            return None
        if not isinstance(value, list) or len(value) != 3:
            raise self.fail(where, value, "a list of three numbers [m]")
        x, y, z = (self.number(f"{where}[{i}]", v) for i, v in enumerate(value))
        return x, y, z

    def unknown(self, where: str, data: Mapping[str, Any], known: tuple[str, ...]) -> None:
        extra = sorted(set(data) - set(known))
        if extra:
            prefix = f"{where}." if where else ""
            raise RobotError(
                f"{self.file}: unknown field {one_line(prefix + extra[0], 40)}: expected one of "
                f"{', '.join(known)}"
            )


def _motor(fields: _Fields, joint: str, data: Any) -> MotorModel:
    where = f"motors.{joint}"
    values = fields.mapping(where, data)
    fields.unknown(where, values, tuple(MOTOR_FIELDS))
    kwargs: dict[str, float] = {}
    for name, (_, lower, inclusive, required) in MOTOR_FIELDS.items():
        if name not in values:
            if required:
                raise RobotError(f"{fields.file}: {one_line(where, 120)} lacks {name}: expected it")
            continue
        kwargs[name] = fields.number(
            f"{where}.{name}", values[name], lower=lower, strict=not inclusive
        )
    if kwargs.get("regen_efficiency", 0.0) > 1.0:
        raise fields.fail(
            f"{where}.regen_efficiency", values["regen_efficiency"], "a value in [0, 1]"
        )
    return MotorModel(
        gear_ratio=kwargs["gear_ratio"],
        torque_constant=kwargs["torque_constant"],
        winding_resistance=kwargs["winding_resistance"],
        rotor_inertia=kwargs.get("rotor_inertia", 0.0),
        viscous_friction=kwargs.get("viscous_friction", 0.0),
        coulomb_friction=kwargs.get("coulomb_friction", 0.0),
        regen_efficiency=kwargs.get("regen_efficiency", 0.0),
    )


def _payload(fields: _Fields, data: Any) -> SidecarPayload:
    values = fields.mapping("payload", data)
    fields.unknown("payload", values, _PAYLOAD)
    mass = values.get("mass")
    size = fields.vector("payload.size", values.get("size"))
    if size is not None and min(size) < 0.0:
        raise fields.fail("payload.size", list(size), "extents >= 0 m")
    return SidecarPayload(
        mass=None if mass is None else fields.number("payload.mass", mass, lower=0.0),
        body=fields.text("payload.body", values.get("body")),
        com=fields.vector("payload.com", values.get("com")),
        size=size,
    )


def read_sidecar(path: str | Path) -> Sidecar:
    """Parse and check a sidecar YAML file (joint names are checked later, against the robot).

    Raises:
        RobotError: unreadable file, not YAML, an unknown field, or a value out of range (e.g.
            a gear ratio below 1), naming the file and the field; a file past the limits
            (size, nesting, aliases, values, digits), naming the limit.
    """
    file_path = Path(path)
    file = file_path.name
    data = _load_yaml(file_path)
    fields = _Fields(file)
    top = fields.mapping("the document", data)
    fields.unknown("", top, _TOP)
    locks = {
        name: fields.number(f"locks.{name}", value)
        for name, value in fields.mapping("locks", top.get("locks")).items()
    }
    speeds = {
        name: fields.number(f"velocity_limits.{name}", value, lower=0.0, strict=True)
        for name, value in fields.mapping("velocity_limits", top.get("velocity_limits")).items()
    }
    efforts = {
        name: fields.number(f"effort_limits.{name}", value, lower=0.0, strict=True)
        for name, value in fields.mapping("effort_limits", top.get("effort_limits")).items()
    }
    controller = {
        key: {
            name: fields.number(f"{key}.{name}", value, lower=0.0, strict=True)
            for name, value in fields.mapping(key, top.get(key)).items()
        }
        for key in ("acceleration_limits", "jerk_limits")
    }
    motors = {
        name: _motor(fields, name, value)
        for name, value in fields.mapping("motors", top.get("motors")).items()
    }
    from app.planning.robots._identified import read_identified

    links, friction = read_identified(fields, top)
    from app.planning.robots._obstacles import read_workspace

    obstacles, mount_plane, srdf = read_workspace(fields, top)
    srdf_path = None if srdf is None else (file_path.resolve().parent / srdf).resolve()
    if srdf_path is not None and not srdf_path.is_file():
        raise fields.fail("srdf", srdf, "an SRDF file (a path from the sidecar's folder)")
    return Sidecar(
        path=file_path.resolve(),
        robot=fields.text("robot", top.get("robot")),
        shoulder_joint=fields.text("shoulder_joint", top.get("shoulder_joint")),
        elbow_joint=fields.text("elbow_joint", top.get("elbow_joint")),
        locks=locks,
        payload=_payload(fields, top.get("payload")),
        motors=motors,
        velocity_limits=speeds,
        effort_limits=efforts,
        acceleration_limits=controller["acceleration_limits"],
        jerk_limits=controller["jerk_limits"],
        base_link=fields.text("base_link", top.get("base_link")),
        tip_link=fields.text("tip_link", top.get("tip_link")),
        links=links,
        friction=friction,
        obstacles=obstacles,
        mount_plane=mount_plane,
        srdf=srdf_path,
        actuators=_actuators(fields, top.get("actuators")),
    )


def _actuators(fields: _Fields, data: Any) -> dict[str, dict[str, float]]:
    """The ``actuators`` block: per joint, numbers > 0 of known fields (checked further, with
    the joint's motor, by ``app.planning.actuators.envelope_from_fields``)."""
    out: dict[str, dict[str, float]] = {}
    for joint, block in fields.mapping("actuators", data).items():
        where = f"actuators.{joint}"
        values = fields.mapping(where, block)
        fields.unknown(where, values, tuple(ACTUATOR_FIELDS))
        out[joint] = {
            name: fields.number(f"{where}.{name}", value, lower=0.0, strict=True)
            for name, value in values.items()
        }
    return out


def _shown(value: Any) -> str:
    """A value for a message: short scalars as written, anything else described, never spelled
    out (an aliased structure can expand to gigabytes; a huge integer cannot be printed)."""
    if isinstance(value, int) and not isinstance(value, bool) and value.bit_length() > 64:
        return f"an integer of about {int(value.bit_length() * 0.30103) + 1} digits"
    if value is None or isinstance(value, bool | int | float):
        return repr(value)
    if isinstance(value, str):
        return one_line(repr(value), 60)
    if isinstance(value, list):
        if len(value) <= 4 and all(isinstance(v, int | float) for v in value):
            return "[" + ", ".join(_shown(v) for v in value) + "]"
        return f"a list of {len(value)} items"
    if isinstance(value, dict):
        return f"a mapping of {len(value)} entries"
    return f"a value of type {type(value).__name__}"


class _TooLarge(Exception):
    """A sidecar past one of the reading limits (the message says which)."""


@functools.cache
def _limited_loader() -> Any:
    """PyYAML's safe loader with the limits: nesting depth and aliases counted as nodes are
    composed, number literals refused past ``MAX_DIGITS`` before Python converts them."""
    import yaml

    class Loader(yaml.SafeLoader):  # type: ignore[misc]
        depth = 0
        aliases = 0

        def compose_node(self, parent: Any, index: Any) -> Any:
            if self.check_event(yaml.AliasEvent):
                self.aliases += 1
                if self.aliases > MAX_ALIASES:
                    raise _TooLarge(f"more than {MAX_ALIASES} aliases (*name): expected fewer")
                return super().compose_node(parent, index)
            self.depth += 1
            try:
                if self.depth > MAX_DEPTH:
                    raise _TooLarge(
                        f"lists or mappings nested more than {MAX_DEPTH} deep: expected the "
                        "shallow mapping of docs/robots.md"
                    )
                return super().compose_node(parent, index)
            finally:
                self.depth -= 1

    def number(loader: Any, node: Any) -> Any:
        if len(node.value) > MAX_DIGITS:
            line = node.start_mark.line + 1
            raise _TooLarge(
                f"a number of {len(node.value)} characters at line {line}: expected at most "
                f"{MAX_DIGITS}"
            )
        if node.tag.endswith(":int"):
            return loader.construct_yaml_int(node)
        return loader.construct_yaml_float(node)

    Loader.add_constructor("tag:yaml.org,2002:int", number)
    Loader.add_constructor("tag:yaml.org,2002:float", number)
    return Loader


def _expanded(node: Any) -> int:
    """Values the composed document holds with every alias spelled out (each shared node
    counted once per use, computed once per node); a node inside itself is refused."""
    import yaml

    sizes: dict[int, int] = {}
    active: set[int] = set()

    def size(item: Any) -> int:
        key = id(item)
        if key in sizes:
            return sizes[key]
        if key in active:
            raise _TooLarge("an alias inside the value it names: expected no recursive structure")
        active.add(key)
        total = 1
        if isinstance(item, yaml.SequenceNode):
            total += sum(size(child) for child in item.value)
        elif isinstance(item, yaml.MappingNode):
            total += sum(size(k) + size(v) for k, v in item.value)
        active.discard(key)
        sizes[key] = min(total, MAX_NODES + 1)
        return sizes[key]

    try:
        return size(node)
    except RecursionError:
        raise _TooLarge("aliases nested inside aliases too deep: expected fewer") from None


def sidecar_yaml(path: str | Path) -> dict[str, Any]:
    """The YAML mapping of a sidecar file as written (checked with :func:`read_sidecar`
    first), e.g. to keep its motors, locks and roles in a sidecar written from it.

    Raises:
        RobotError: the file is not a valid sidecar (names the file and the field).
    """
    read_sidecar(path)
    data = _load_yaml(Path(path)) or {}
    return dict(data)


def _load_yaml(path: Path) -> Any:
    """The YAML document of a sidecar file, read within the limits.

    Raises:
        RobotError: a missing, unreadable, too large or invalid file, naming it (and the limit).
    """
    import yaml

    file = path.name
    try:
        with open(path, "rb") as handle:
            raw = handle.read(MAX_SIDECAR_BYTES + 1)
        text = raw.decode("utf-8")
    except FileNotFoundError:
        raise RobotError(f"{file}: no such file ({path}): expected a sidecar YAML file") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise RobotError(f"{file}: cannot be read ({exc}): expected a UTF-8 YAML file") from None
    if len(raw) > MAX_SIDECAR_BYTES:
        raise RobotError(
            f"{file}: larger than {MAX_SIDECAR_BYTES} bytes: expected a sidecar of a few kilobytes"
        )
    loader = _limited_loader()(text)
    try:
        node = loader.get_single_node()
        if node is not None and _expanded(node) > MAX_NODES:
            raise _TooLarge(
                f"more than {MAX_NODES} values with its aliases spelled out: expected a few "
                "dozen joints' settings"
            )
        return None if node is None else loader.construct_document(node)
    except _TooLarge as exc:
        raise RobotError(f"{file}: {exc}") from None
    except (yaml.YAMLError, RecursionError, ValueError) as exc:
        mark = getattr(exc, "problem_mark", None)
        line = f" at line {mark.line + 1}" if mark is not None else ""
        raise RobotError(f"{file}: not valid YAML{line}: expected a sidecar mapping") from None
    finally:
        loader.dispose()
