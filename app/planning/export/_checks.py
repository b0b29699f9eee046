"""What an export checks before it writes a controller file, and what the file then records.

Two gates, both on the samples actually written (the export rate, the approach included):

- **Limits**: every limit the robot states, on every free joint: position, speed and torque
  (``q_min``/``q_max`` [rad], ``qd_max`` [rad/s], ``tau_max`` [Nm]: what a URDF's ``<limit>``
  states and the planner enforces), and acceleration [rad/s^2] and jerk [rad/s^3] where the
  robot states them (``Robot.stated_limits``: a sidecar's ``acceleration_limits`` and
  ``jerk_limits``, or limits given explicitly). A URDF states no acceleration or jerk limit,
  and the ``<joint>.acceleration``/``.jerk`` rows of the built-in robots are the jerk-limited
  baseline's assumed controller settings (the optimal methods exceed them by design): those
  are not gated, and the file says so. The jerk is the samples' finite difference of the
  acceleration (by the mean value theorem never above the true peak, so a refusal is never
  spurious). An excess above ``LIMIT_TOL * max(1, |limit|)`` (round-off) refuses the export
  unless it is forced, and a forced file records what was exceeded.
- **Safety**: the plan's ``safety`` block (collision and workspace check, when the plan has
  one). A method with a contact (``ok`` false and a finding of that method) is refused unless
  the user allows it (``allow_unsafe``), which the file records; a plan without the check (no
  block, or ``checked`` false) is exported and the file says ``safety: not checked``.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from dataclasses import asdict, dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from app.planning.export._motion import ExportError, Samples

if TYPE_CHECKING:
    from app.planning.robots import Robot

__all__ = [
    "LIMIT_TOL",
    "Exceedance",
    "ExportNotes",
    "ExportRefused",
    "limit_exceedances",
    "safety_status",
    "stated_controller_limits",
    "unstated_limits",
]

#: Relative excess over a limit that is round-off, not an exceedance [-] (as ``check_limits``).
LIMIT_TOL = 1e-6


class ExportRefused(ExportError):
    """The export would send a controller beyond the robot's limits or into a contact (the
    service answers 409: the request is well formed, the plan is not fit to run)."""


@dataclass(frozen=True)
class Exceedance:
    """The worst sample of one joint beyond one limit.

    Attributes:
        joint: joint name.
        limit: ``position``, ``velocity``, ``acceleration``, ``jerk`` or ``effort``.
        bound: the limit [rad, rad/s, rad/s^2, rad/s^3 or Nm] (signed for position: the bound
            crossed).
        value: the exported value there (signed for position, magnitude otherwise).
        time: its time in the exported file [s].
        unit: the unit of ``bound`` and ``value``.
    """

    joint: str
    limit: str
    bound: float
    value: float
    time: float
    unit: str

    @property
    def ratio(self) -> float:
        """How far beyond: value / bound for magnitudes, 1 + overshoot for positions."""
        if self.limit == "position":
            return 1.0 + abs(self.value - self.bound) / max(1.0, abs(self.bound))
        return abs(self.value) / abs(self.bound)

    def text(self) -> str:
        """One line, e.g. ``joint 'elbow_joint' velocity 3.15114 rad/s exceeds its limit
        3.15 rad/s at t=0.53 s``."""
        verb = "is beyond" if self.limit == "position" else "exceeds"
        return (
            f"joint '{self.joint}' {self.limit} {_num(self.value)} {self.unit} {verb} its limit "
            f"{_num(self.bound)} {self.unit} at t={self.time:.4g} s"
        )

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


def _num(x: float) -> str:
    """Enough digits that a value just past its limit reads as past it (3.1511, not 3.15)."""
    return f"{x:.6g}"


def stated_controller_limits(robot: Robot, kind: str) -> np.ndarray:
    """(n,) the robot's ``acceleration`` [rad/s^2] or ``jerk`` [rad/s^3] limits where it states
    them (``Robot.stated_limits``), inf elsewhere (not checked)."""
    values = np.asarray(robot.qdd_max if kind == "acceleration" else robot.jerk_max, float)
    stated = set(robot.stated_limits.get(kind, ()))
    return np.array(
        [
            v if name in stated else math.inf
            for name, v in zip(robot.joint_names, values, strict=True)
        ]
    )


def unstated_limits(robot: Robot) -> tuple[str, ...]:
    """The controller limits (``acceleration``, ``jerk``) the robot does not state for every
    joint, each with the joints it does state it for, e.g. ``jerk (stated for: j1)``."""
    out = []
    for kind in ("acceleration", "jerk"):
        stated = [n for n in robot.joint_names if n in set(robot.stated_limits.get(kind, ()))]
        if len(stated) < robot.n_joints:
            out.append(kind + (f" (stated for {' '.join(stated)} only)" if stated else ""))
    return tuple(out)


def limit_exceedances(
    samples: Samples,
    robot: Robot,
    *,
    qdd_max: np.ndarray | None = None,
    jerk_max: np.ndarray | None = None,
) -> list[Exceedance]:
    """Every (joint, limit) whose exported samples leave the robot's limits, worst first.

    Args:
        samples: the samples to be written (T rows of ``robot.joint_names``).
        robot: the robot (its position, speed, torque and stated acceleration and jerk limits).
        qdd_max, jerk_max: (n,) acceleration [rad/s^2] and jerk [rad/s^3] limits to check
            instead of the robot's stated ones (inf: not checked; see the module docstring).

    Returns:
        One :class:`Exceedance` per joint and limit exceeded (its worst sample), sorted by how
        far beyond (largest first); empty when the file keeps every limit.
    """
    names = robot.joint_names
    out: list[Exceedance] = []

    def worst(values: np.ndarray, bound: np.ndarray, kind: str, unit: str, sign: float) -> None:
        excess = sign * (values - bound[None, :])
        for j in range(len(names)):
            if not math.isfinite(float(bound[j])):
                continue
            k = int(np.argmax(excess[:, j]))
            if excess[k, j] > LIMIT_TOL * max(1.0, abs(float(bound[j]))):
                out.append(
                    Exceedance(
                        names[j],
                        kind,
                        float(bound[j]),
                        float(values[k, j]),
                        float(samples.t[k]),
                        unit,
                    )
                )

    worst(samples.q, np.asarray(robot.q_max), "position", "rad", 1.0)
    worst(samples.q, np.asarray(robot.q_min), "position", "rad", -1.0)
    worst(np.abs(samples.qd), np.asarray(robot.qd_max), "velocity", "rad/s", 1.0)
    if qdd_max is None:
        qdd_max = stated_controller_limits(robot, "acceleration")
    worst(np.abs(samples.qdd), np.asarray(qdd_max, float), "acceleration", "rad/s^2", 1.0)
    if jerk_max is None:
        jerk_max = stated_controller_limits(robot, "jerk")
    if samples.t.size > 1 and np.any(np.isfinite(np.asarray(jerk_max, float))):
        jerk = np.abs(np.gradient(samples.qdd, samples.t, axis=0))
        worst(jerk, np.asarray(jerk_max, float), "jerk", "rad/s^3", 1.0)
    worst(np.abs(samples.tau), np.asarray(robot.tau_max), "effort", "Nm", 1.0)
    return sorted(out, key=lambda e: -e.ratio)


@dataclass(frozen=True)
class SafetyStatus:
    """The plan's collision/workspace check as it bears on one method.

    Attributes:
        state: ``ok`` (checked, no contact of this method), ``unsafe`` (a contact of this
            method) or ``not checked`` (no check, or the check could not run).
        first: the method's earliest finding (``unsafe`` only), as the plan reported it.
        min_clearance: the plan's smallest clearance [m] when it reported one.
        reason: why not checked, when the plan said.
    """

    state: str
    first: Mapping[str, Any] | None = None
    min_clearance: float | None = None
    reason: str | None = None

    def contact_text(self) -> str:
        """One line, e.g. ``at t=0.31 s: links forearm_link and base_link (self), 12.3 mm
        deep`` or ``at t=0.31 s: link wrist_1_link and obstacle mount plane (plane), ...``."""
        f = self.first or {}
        links = f.get("links")
        names = [str(x) for x in links] if isinstance(links, list | tuple) else []
        parts = []
        if names:
            parts.append(("links " if len(names) > 1 else "link ") + " and ".join(names))
        if f.get("obstacle") is not None:
            parts.append(f"obstacle {f['obstacle']}")
        place = " and ".join(parts) or "an unnamed pair"
        kind = f" ({f['kind']})" if f.get("kind") else ""
        depth = f.get("depth")
        deep = f", {1000 * float(depth):.1f} mm deep" if isinstance(depth, int | float) else ""
        time = f.get("time")
        at = f"at t={float(time):.4g} s: " if isinstance(time, int | float) else ""
        return f"{at}{place}{kind}{deep}"


def safety_status(safety: Any, method: str) -> SafetyStatus:
    """How the plan's ``safety`` block (or None) judges ``method``.

    A block counts as a check only when ``checked`` is true and ``ok`` is a boolean; then the
    method is unsafe when ``ok`` is false and a finding names it (another method's contact does
    not stop this one). Anything else is ``not checked``, never ``ok``.
    """
    if not isinstance(safety, Mapping):
        return SafetyStatus("not checked")
    reason = safety.get("reason")
    reason = str(reason).removeprefix("not checked: ") if reason else None
    if safety.get("checked") is not True:
        return SafetyStatus("not checked", reason=reason)
    ok = safety.get("ok")
    clearance = safety.get("min_clearance")
    clearance = float(clearance) if isinstance(clearance, int | float) else None
    if ok is True:
        return SafetyStatus("ok", min_clearance=clearance)
    if ok is not False:
        return SafetyStatus("not checked", reason=reason)
    findings = [
        f
        for f in safety.get("findings") or []
        if isinstance(f, Mapping) and f.get("method") == method
    ]
    if not findings:
        return SafetyStatus("ok", min_clearance=clearance)
    first = min(
        findings,
        key=lambda f: f["time"] if isinstance(f.get("time"), int | float) else math.inf,
    )
    return SafetyStatus("unsafe", first=dict(first), min_clearance=clearance)


@dataclass(frozen=True)
class ExportNotes:
    """What an export file records about its own fitness to run.

    Attributes:
        exceeded: the limits exceeded (non-empty only when the export was forced).
        forced: the user forced the export (``--force``).
        safety: the method's :class:`SafetyStatus`.
        allow_unsafe: the user allowed an unsafe method (``--allow-unsafe``).
        extra: further lines (e.g. a URScript for a robot not recognised as a UR).
        unstated: the controller limits not checked because the robot does not state them
            (:func:`unstated_limits`).
    """

    exceeded: tuple[Exceedance, ...] = ()
    forced: bool = False
    safety: SafetyStatus = field(default_factory=lambda: SafetyStatus("not checked"))
    allow_unsafe: bool = False
    extra: tuple[str, ...] = ()
    unstated: tuple[str, ...] = ()

    def safety_line(self) -> str:
        s = self.safety
        if s.state == "unsafe":
            return f"safety: UNSAFE, exported with allow_unsafe: first contact {s.contact_text()}"
        if s.state == "ok":
            clearance = (
                "" if s.min_clearance is None else f" (min clearance {s.min_clearance:.4g} m)"
            )
            return f"safety: checked, no contact{clearance}"
        return "safety: not checked" + (f" ({s.reason})" if s.reason else "")

    def limits_line(self) -> str:
        if not self.exceeded:
            return "limits: within the robot's limits"
        worst = "; ".join(e.text() for e in self.exceeded)
        return f"limits: FORCED past the robot's limits: {worst}"

    def unstated_line(self) -> str | None:
        """What was not checked because the robot states no such limit (None: all checked)."""
        if not self.unstated:
            return None
        return f"limits not stated by the robot (not checked): {'; '.join(self.unstated)}"

    def lines(self) -> list[str]:
        """One-line statements for a comment header (no newline inside any)."""
        unstated = self.unstated_line()
        return [
            self.limits_line(),
            *([unstated] if unstated else []),
            self.safety_line(),
            *self.extra,
        ]

    def to_dict(self) -> dict[str, Any]:
        s = self.safety
        return {
            "forced": self.forced,
            "exceeded": [e.to_dict() for e in self.exceeded],
            "safety": {
                "state": s.state,
                "allow_unsafe": self.allow_unsafe,
                "first_contact": None if s.first is None else json.loads(json.dumps(s.first)),
                "min_clearance": s.min_clearance,
                "reason": s.reason,
            },
            "notes": list(self.extra),
            "unstated_limits": list(self.unstated),
        }


def check_export(
    method: str,
    samples: Samples,
    robot: Robot,
    *,
    safety: Any = None,
    force: bool = False,
    allow_unsafe: bool = False,
) -> ExportNotes:
    """Refuse an export past the limits or into a contact unless told; else what to record.

    Raises:
        ExportRefused: a limit exceeded without ``force`` (the worst: method, joint, limit,
            value, time) or a contact of ``method`` without ``allow_unsafe`` (the first).
    """
    status = safety_status(safety, method)
    if status.state == "unsafe" and not allow_unsafe:
        raise ExportRefused(
            f"method {method} is not safe to run: first contact {status.contact_text()}: "
            "expected a collision-free plan (--allow-unsafe / allow_unsafe=true exports it anyway, "
            "and the file records it)"
        )
    exceeded = limit_exceedances(samples, robot)
    if exceeded and not force:
        more = f" (and {len(exceeded) - 1} more)" if len(exceeded) > 1 else ""
        raise ExportRefused(
            f"method {method}: {exceeded[0].text()}{more}: expected every exported sample within "
            "the robot's limits (--force / force=true exports it anyway, and the file records it)"
        )
    return ExportNotes(
        exceeded=tuple(exceeded),
        forced=force,
        safety=status,
        allow_unsafe=allow_unsafe and status.state == "unsafe",
        unstated=unstated_limits(robot),
    )
