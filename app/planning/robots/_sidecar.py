"""The robot sidecar: motors, gears, payload, locks and the shoulder/elbow choice, in YAML.

The format is documented in ``docs/robots.md``. Values a person types are in display units:
lock values in degrees (metres for prismatic joints), everything else SI. Every error names the
file and the field (``motors.elbow_joint.gear_ratio``) and what was expected.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from app.planning.energy import MotorModel
from app.planning.robots._types import RobotError

__all__ = ["MOTOR_FIELDS", "Sidecar", "SidecarPayload", "read_sidecar"]

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
_TOP = ("robot", "shoulder_joint", "elbow_joint", "locks", "payload", "motors", "velocity_limits")
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
    """

    path: Path
    robot: str | None = None
    shoulder_joint: str | None = None
    elbow_joint: str | None = None
    locks: Mapping[str, float] = field(default_factory=dict)
    payload: SidecarPayload = field(default_factory=SidecarPayload)
    motors: Mapping[str, MotorModel] = field(default_factory=dict)
    velocity_limits: Mapping[str, float] = field(default_factory=dict)


class _Fields:
    """Typed reads of a YAML mapping, with errors that name the file and the field path."""

    def __init__(self, file: str) -> None:
        self.file = file

    def fail(self, where: str, got: Any, expected: str) -> RobotError:
        return RobotError(f"{self.file}: {where} is {got!r}: expected {expected}")

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
                f"{self.file}: unknown field {prefix}{extra[0]}: expected one of {', '.join(known)}"
            )


def _motor(fields: _Fields, joint: str, data: Any) -> MotorModel:
    where = f"motors.{joint}"
    values = fields.mapping(where, data)
    fields.unknown(where, values, tuple(MOTOR_FIELDS))
    kwargs: dict[str, float] = {}
    for name, (_, lower, inclusive, required) in MOTOR_FIELDS.items():
        if name not in values:
            if required:
                raise RobotError(f"{fields.file}: {where} lacks {name}: expected it")
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
            a gear ratio below 1), naming the file and the field.
    """
    import yaml

    file_path = Path(path)
    file = file_path.name
    try:
        text = file_path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise RobotError(
            f"{file}: no such file ({file_path}): expected a sidecar YAML file"
        ) from None
    except (OSError, UnicodeDecodeError) as exc:
        raise RobotError(f"{file}: cannot be read ({exc}): expected a UTF-8 YAML file") from None
    try:
        data = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        line = f" at line {mark.line + 1}" if mark is not None else ""
        raise RobotError(f"{file}: not valid YAML{line}: expected a sidecar mapping") from None
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
    motors = {
        name: _motor(fields, name, value)
        for name, value in fields.mapping("motors", top.get("motors")).items()
    }
    return Sidecar(
        path=file_path.resolve(),
        robot=fields.text("robot", top.get("robot")),
        shoulder_joint=fields.text("shoulder_joint", top.get("shoulder_joint")),
        elbow_joint=fields.text("elbow_joint", top.get("elbow_joint")),
        locks=locks,
        payload=_payload(fields, top.get("payload")),
        motors=motors,
        velocity_limits=speeds,
    )
