"""The HumanTemplate: what the planner takes from recorded human lifts.

The analysis package builds it from recordings (``app.analysis.template``); the planner only
reads it. Defaults are the paper's: the elbow's velocity peaks at 62 deg, in the middle of phase B
(40-90 deg).

Where the peak goes on a robot stroke: a template built from lifts knows where, within each
lift's own range (start angle -> top angle), the elbow was fastest, as a fraction of that range;
the robot's elbow stroke q0 -> q1 gets its peak at the same fraction. Absolute angles would move
the peak of a 40 -> 127 deg lift to the wrong place on a 0 -> 150 deg task. The paper's default
has no lifts, so it keeps the paper's absolute 62 deg (see :func:`joint_on_stroke`).
"""

from __future__ import annotations

import json
import math
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from app.errors import BioPlanError
from app.names import HUMAN_CURL_SPAN_DEG

#: ``HumanTemplate.source`` when no recorded lift had usable elbow kinematics.
PAPER_DEFAULT_SOURCE = "paper default"


@dataclass(frozen=True)
class HumanTemplate:
    """Kinematic and muscular features of human lifts that shape a robot trajectory.

    Attributes:
        peak_velocity_angle_deg: elbow flexion at which the elbow's angular velocity peaks [deg],
            mean over lifts.
        peak_velocity_angle_sd_deg: its standard deviation over lifts [deg] (0 for defaults).
        phase_bounds_deg: (A/B, B/C) elbow-flexion thresholds [deg].
        peak_velocity_time_fraction: time of the velocity peak as a fraction of the lift's
            duration (None when unknown).
        normalized_time: (K,) grid in [0, 1] for the profiles below (empty when unknown).
        velocity_mean, velocity_sd: (K,) elbow velocity normalised by its peak.
        acceleration_mean, acceleration_sd: (K,) elbow acceleration normalised by its peak |value|.
        activation_order: EMG sites in order of onset (e.g. deltoid first).
        emg_peak_time_fraction: site -> time of the EMG envelope peak as a fraction of the lift.
        n_lifts: how many lifts the kinematic fields rest on (0 = paper defaults).
        source: where the kinematic numbers come from: ``"N lifts with kinematics"`` or
            :data:`PAPER_DEFAULT_SOURCE` (and why).
        peak_velocity_range_fraction: where the velocity peaks within each lift's own range,
            (angle at the peak - start angle) / (top angle - start angle), mean over lifts
            (None for the paper's default); what the planner places on the robot's stroke.
        peak_velocity_range_fraction_sd: its standard deviation over lifts.
        lift_range_deg: mean (start, top) elbow flexion of the lifts [deg] (None without).
        files: the recordings the template was built from.
        emg_lifts: how many lifts the EMG timing fields (``activation_order``,
            ``emg_peak_time_fraction``) rest on.
        assumptions: what the analysis had to assume (e.g. an unknown video size).
    """

    peak_velocity_angle_deg: float = 62.0
    peak_velocity_angle_sd_deg: float = 0.0
    phase_bounds_deg: tuple[float, float] = (40.0, 90.0)
    peak_velocity_time_fraction: float | None = None
    normalized_time: tuple[float, ...] = ()
    velocity_mean: tuple[float, ...] = ()
    velocity_sd: tuple[float, ...] = ()
    acceleration_mean: tuple[float, ...] = ()
    acceleration_sd: tuple[float, ...] = ()
    activation_order: tuple[str, ...] = ()
    emg_peak_time_fraction: dict[str, float] = field(default_factory=dict)
    n_lifts: int = 0
    source: str = PAPER_DEFAULT_SOURCE
    peak_velocity_range_fraction: float | None = None
    peak_velocity_range_fraction_sd: float = 0.0
    lift_range_deg: tuple[float, float] | None = None
    files: tuple[str, ...] = ()
    emg_lifts: int = 0
    assumptions: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        lo, hi = self.phase_bounds_deg
        if not 0.0 < lo < hi:
            raise BioPlanError(
                f"phase bounds must satisfy 0 < A/B < B/C, got {self.phase_bounds_deg}"
            )
        if not 0.0 < self.peak_velocity_angle_deg < 180.0:
            raise BioPlanError(
                f"peak velocity angle must lie in (0, 180) deg, got {self.peak_velocity_angle_deg}"
            )
        frac = self.peak_velocity_range_fraction
        if frac is not None and not 0.0 < frac < 1.0:
            raise BioPlanError(
                f"peak_velocity_range_fraction must lie in (0, 1), got {frac}"
                " (the peak lies strictly inside each lift's range)"
            )

    @property
    def is_paper_default(self) -> bool:
        """True when no recorded lift shaped the kinematic fields (the paper's values are used)."""
        return self.n_lifts == 0

    def peak_joint_angle(self, q0: float, q1: float) -> float:
        """Where on a robot elbow stroke q0 -> q1 [rad] the elbow should be fastest [rad].

        With lifts, at the same fraction of the stroke as within the lifts' own ranges:
        ``q0 + peak_velocity_range_fraction * (q1 - q0)``. The paper's default (no lifts) places
        its absolute 62 deg by :func:`joint_on_stroke`.
        """
        if self.peak_velocity_range_fraction is not None:
            return q0 + self.peak_velocity_range_fraction * (q1 - q0)
        return joint_on_stroke(self.peak_velocity_angle_deg, q0, q1)

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)

    @classmethod
    def from_dict(cls, data: Any) -> HumanTemplate:
        """A template from its :meth:`to_dict` form.

        Raises:
            BioPlanError: ``data`` is not an object, has an unknown field, or a field has the
                wrong type or value; the message names the field and what was expected.
        """
        if not isinstance(data, dict):
            raise BioPlanError(f"a HumanTemplate must be a JSON object, got {type(data).__name__}")
        unknown = set(data) - set(cls.__dataclass_fields__)
        if unknown:
            raise BioPlanError(f"unknown HumanTemplate fields: {sorted(unknown)}")
        kwargs = {name: _field_value(name, value) for name, value in data.items()}
        return cls(**kwargs)

    def to_json(self) -> str:
        return json.dumps(self.to_dict(), indent=2)

    @classmethod
    def from_json(cls, text: str) -> HumanTemplate:
        """A template from its :meth:`to_json` text (BioPlanError for malformed JSON or fields)."""
        try:
            data = json.loads(text)
        except json.JSONDecodeError as exc:
            raise BioPlanError(
                f"HumanTemplate JSON: {exc.msg} at line {exc.lineno} column {exc.colno}"
            ) from exc
        return cls.from_dict(data)


#: What each HumanTemplate field holds in JSON: "number", "optional number", "integer",
#: "string", "numbers" (array), "strings" (array), "pair" (two numbers), "optional pair",
#: "site fractions" (object of string -> number).
_FIELD_KINDS: dict[str, str] = {
    "peak_velocity_angle_deg": "number",
    "peak_velocity_angle_sd_deg": "number",
    "phase_bounds_deg": "pair",
    "peak_velocity_time_fraction": "optional number",
    "normalized_time": "numbers",
    "velocity_mean": "numbers",
    "velocity_sd": "numbers",
    "acceleration_mean": "numbers",
    "acceleration_sd": "numbers",
    "activation_order": "strings",
    "emg_peak_time_fraction": "site fractions",
    "n_lifts": "integer",
    "source": "string",
    "peak_velocity_range_fraction": "optional number",
    "peak_velocity_range_fraction_sd": "number",
    "lift_range_deg": "optional pair",
    "files": "strings",
    "emg_lifts": "integer",
    "assumptions": "strings",
}


def _is_number(value: Any) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value)


def _field_value(name: str, value: Any) -> Any:
    """``value`` of field ``name`` as the dataclass holds it, or BioPlanError naming the field."""
    kind = _FIELD_KINDS[name]
    if kind.startswith("optional ") and value is None:
        return None
    kind = kind.removeprefix("optional ")
    ok = {
        "number": lambda: _is_number(value),
        "integer": lambda: isinstance(value, int) and not isinstance(value, bool) and value >= 0,
        "string": lambda: isinstance(value, str),
        "numbers": lambda: isinstance(value, list | tuple) and all(map(_is_number, value)),
        "strings": lambda: (
            isinstance(value, list | tuple) and all(isinstance(v, str) for v in value)
        ),
        "pair": lambda: (
            isinstance(value, list | tuple) and len(value) == 2 and all(map(_is_number, value))
        ),
        "site fractions": lambda: (
            isinstance(value, dict)
            and all(isinstance(k, str) and _is_number(v) for k, v in value.items())
        ),
    }[kind]()
    if not ok:
        expected = {
            "number": "a finite number",
            "integer": "a non-negative integer",
            "string": "a string",
            "numbers": "an array of finite numbers",
            "strings": "an array of strings",
            "pair": "an array of two finite numbers",
            "site fractions": "an object of site name -> finite number",
        }[kind]
        if name in ("peak_velocity_time_fraction", "peak_velocity_range_fraction"):
            expected += " or null"
        if name == "lift_range_deg":
            expected += " or null"
        raise BioPlanError(f"HumanTemplate field {name!r}: expected {expected}, got {value!r:.60}")
    if kind in ("numbers", "strings", "pair"):
        return tuple(value)
    if kind == "site fractions":
        return dict(value)
    return value


def _stroke_is_human_like(q0: float, q1: float) -> bool:
    lo, hi = np.radians(HUMAN_CURL_SPAN_DEG)
    return bool(q1 > q0 and q0 >= lo - 1e-9 and q1 <= hi + np.radians(30.0))


def flexion_on_stroke(q_elbow: ArrayLike, q0: float, q1: float) -> NDArray[np.float64]:
    """Human-equivalent elbow flexion [deg] of robot elbow angles on a stroke q0 -> q1 [rad].

    When the stroke covers the human curl's angles directly (it rises from about 0 and ends
    within 30 deg past 150 deg, as the built-in tasks do), the joint angle is the flexion;
    otherwise the stroke maps linearly onto the human curl span 0-150 deg.

    Args:
        q_elbow: (...,) elbow joint angles [rad].
        q0, q1: the stroke's start and end [rad].
    """
    q = np.asarray(q_elbow, dtype=np.float64)
    if _stroke_is_human_like(q0, q1):
        return np.asarray(np.degrees(q), dtype=np.float64)
    lo, hi = HUMAN_CURL_SPAN_DEG
    return np.asarray(lo + (q - q0) / (q1 - q0) * (hi - lo), dtype=np.float64)


def joint_on_stroke(flexion_deg: float, q0: float, q1: float) -> float:
    """Inverse of :func:`flexion_on_stroke` for one flexion [deg] -> joint angle [rad]."""
    if _stroke_is_human_like(q0, q1):
        return math.radians(flexion_deg)
    lo, hi = HUMAN_CURL_SPAN_DEG
    return q0 + (flexion_deg - lo) / (hi - lo) * (q1 - q0)
