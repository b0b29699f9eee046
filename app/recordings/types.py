"""Recording and Channel types shared by every reader, and the one error type readers raise."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from app.errors import BioPlanError

ChannelKind = Literal["emg", "angle", "landmark", "marker", "accel", "other"]
Site = Literal["deltoid", "triceps", "biceps", "forearm"]
SITES: tuple[Site, ...] = ("deltoid", "triceps", "biceps", "forearm")


class RecordingError(BioPlanError):
    """A recording cannot be read or used as it is.

    The message always names where the problem is (file, line or channel) and what was expected,
    so the CLI can print it as one line and the API can return it as a 4xx.
    """

    def __init__(
        self,
        message: str,
        *,
        file: str | None = None,
        line: int | None = None,
        channel: str | None = None,
        expected: str | None = None,
    ) -> None:
        self.message = message
        self.file = file
        self.line = line
        self.channel = channel
        self.expected = expected
        super().__init__(str(self))

    def __str__(self) -> str:
        where = []
        if self.file:
            where.append(self.file)
        if self.line is not None:
            where.append(f"line {self.line}")
        if self.channel:
            where.append(f"channel {self.channel!r}")
        text = (", ".join(where) + ": " if where else "") + self.message
        if self.expected:
            text += f" (expected {self.expected})"
        return text


@dataclass
class Channel:
    """One signal of a recording, uniformly sampled unless ``time`` is given.

    Attributes:
        name: label as in the file (e.g. ``"Biceps.EMG4"``, ``"RELB"``, ``"left_elbow"``).
        data: (N,) samples for scalar signals, or (N, 3) positions for landmarks and markers;
            NaN marks a missing sample.
        rate: sampling rate [Hz] (nominal when ``time`` is given).
        unit: physical unit after conversion: ``"V"`` for EMG, ``"rad"`` for angles, ``"m"`` for
            markers, ``"norm"`` for normalised image coordinates, ``"m/s^2"`` for accelerations.
        kind: what the signal is.
        start: time of the first sample [s] on the recording's clock.
        site: one of the four EMG sites the method uses, when this channel is mapped to one.
        confidence: (N,) optional per-sample confidence in [0, 1] (MediaPipe visibility,
            1 for a C3D marker with residual >= 0 and 0 when the residual is negative).
        time: (N,) optional explicit sample times [s] for irregular sampling.
    """

    name: str
    data: NDArray[np.float64]
    rate: float
    unit: str
    kind: ChannelKind
    start: float = 0.0
    site: Site | None = None
    confidence: NDArray[np.float64] | None = None
    time: NDArray[np.float64] | None = None

    @property
    def n_samples(self) -> int:
        return int(self.data.shape[0])

    @property
    def times(self) -> NDArray[np.float64]:
        """(N,) sample times [s]."""
        if self.time is not None:
            return self.time
        return self.start + np.arange(self.n_samples, dtype=np.float64) / self.rate

    @property
    def duration(self) -> float:
        """Time span covered [s]."""
        return self.n_samples / self.rate if self.time is None else float(np.ptp(self.time))


@dataclass
class Recording:
    """Channels read from one file (or one logical recording), plus metadata.

    Attributes:
        channels: channels by name, in file order.
        source: the file name the recording came from (never a full path of the server).
        format: the detected format, e.g. ``"noraxon_csv"``, ``"c3d"``, ``"mediapipe_csv"``.
        metadata: anything else the file states (subject, device, image size...).
    """

    channels: dict[str, Channel]
    source: str
    format: str
    metadata: dict[str, Any] = field(default_factory=dict)

    def of_kind(self, kind: ChannelKind) -> list[Channel]:
        return [c for c in self.channels.values() if c.kind == kind]

    def emg_by_site(self) -> dict[Site, Channel]:
        """EMG channels that are mapped to one of the four sites (first one per site)."""
        out: dict[Site, Channel] = {}
        for c in self.of_kind("emg"):
            if c.site is not None and c.site not in out:
                out[c.site] = c
        return out


@dataclass(frozen=True)
class DatalogSensor:
    """One column of a Biometrics DataLOG ASCII export and how to turn its ADC counts into units.

    The export has no header, so the user (or a JSON sidecar) says what each column is.
    ``value = counts / counts_range * physical_range`` in ``unit``, then converted to SI
    (EMG to V, angles to rad, accelerations to m/s^2).

    Attributes:
        column: 0-based column index in the tab-separated export.
        name: channel name to give (e.g. ``"biceps"``); mapped to a site like any label.
        kind: what the sensor measures (``"emg"``, ``"angle"`` for goniometers, ``"accel"``...).
        rate: sampling rate of this sensor [Hz]; DataLOG sensors run at different rates.
        physical_range: the physical value that ``counts_range`` counts stand for, in ``unit``
            (e.g. ``3.0`` with ``"mV"`` for EMG ±4000 counts = ±3 mV; ``180.0`` ``"deg"`` for a
            goniometer).
        unit: unit of ``physical_range``: ``"V"``, ``"mV"``, ``"uV"``, ``"deg"``, ``"rad"``,
            ``"g"``, ``"m/s^2"``...
        counts_range: ADC counts that correspond to ``physical_range`` (keyword-only, 4000).
    """

    column: int
    name: str
    kind: ChannelKind
    rate: float
    physical_range: float
    unit: str
    counts_range: float = field(default=4000.0, kw_only=True)


@dataclass(frozen=True)
class RateCheck:
    """An EMG sampling rate that looks wrong, and the rate that would fit (upload-time data).

    Attributes:
        stored_rate: the rate the file states [Hz].
        suggested_rate: the rate at which the EMG's spectrum looks like surface EMG [Hz].
        median_frequency: the EMG's spectral median at the stored rate [Hz].
        channels: the EMG channels the verdict covers.
        reason: one sentence for the user.
    """

    stored_rate: float
    suggested_rate: float
    median_frequency: float
    channels: tuple[str, ...]
    reason: str

    def to_dict(self) -> dict[str, Any]:
        return {
            "stored_rate_hz": self.stored_rate,
            "suggested_rate_hz": self.suggested_rate,
            "median_frequency_hz": self.median_frequency,
            "channels": list(self.channels),
            "reason": self.reason,
        }


def rate_check(recording: Recording) -> RateCheck | None:
    """The reader's verdict on the recording's EMG rate (None when it looks plausible).

    Readers store it in ``metadata["rate_check"]``; with ``emg_rate`` given when reading, the
    check runs on the corrected rate.
    """
    data = recording.metadata.get("rate_check")
    if not isinstance(data, dict):
        return None
    return RateCheck(
        stored_rate=float(data["stored_rate_hz"]),
        suggested_rate=float(data["suggested_rate_hz"]),
        median_frequency=float(data["median_frequency_hz"]),
        channels=tuple(data["channels"]),
        reason=str(data["reason"]),
    )
