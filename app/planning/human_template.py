"""The HumanTemplate: what the planner takes from recorded human lifts.

The analysis package builds it from recordings (``app.analysis.template``); the planner only
reads it. Defaults are the paper's: the elbow's velocity peaks at 62 deg, in the middle of phase B
(40-90 deg).
"""

from __future__ import annotations

import json
from dataclasses import asdict, dataclass, field
from typing import Any


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
        n_lifts: how many lifts the template rests on (0 = paper defaults).
        source: where it came from (file names, or "paper defaults").
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
    source: str = "paper defaults"

    def __post_init__(self) -> None:
        lo, hi = self.phase_bounds_deg
        if not 0.0 < lo < hi:
            raise ValueError(
                f"phase bounds must satisfy 0 < A/B < B/C, got {self.phase_bounds_deg}"
            )
        if not 0.0 < self.peak_velocity_angle_deg < 180.0:
            raise ValueError(
                f"peak velocity angle must lie in (0, 180) deg, got {self.peak_velocity_angle_deg}"
            )

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> HumanTemplate:
        known = set(cls.__dataclass_fields__)
        unknown = set(data) - known
        if unknown:
            raise ValueError(f"unknown HumanTemplate fields: {sorted(unknown)}")
        kwargs = dict(data)
        for name in (
            "phase_bounds_deg",
            "normalized_time",
            "velocity_mean",
            "velocity_sd",
            "acceleration_mean",
            "acceleration_sd",
            "activation_order",
        ):
            if name in kwargs:
                kwargs[name] = tuple(kwargs[name])
        return cls(**kwargs)

    def to_json(self) -> str:
        return json.dumps(self.to_dict(), indent=2)

    @classmethod
    def from_json(cls, text: str) -> HumanTemplate:
        return cls.from_dict(json.loads(text))
