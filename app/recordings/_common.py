"""Shared pieces of the readers: the input source, units, rate checks and channel building."""

from __future__ import annotations

import contextlib
import math
import os
import re
import tempfile
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from app.recordings.muscles import is_muscle_label, map_muscle
from app.recordings.types import Channel, ChannelKind, DatalogSensor, RecordingError

F64 = NDArray[np.float64]

# Rates outside this band are not a plausible stored value for any signal we read.
MIN_RATE = 1.0
MAX_RATE = 100_000.0

G0 = 9.80665  # standard gravity [m/s^2], for accelerations stated in g


@dataclass
class Options:
    """The reader options of ``read_recording``, validated once."""

    rate: float | None = None
    emg_rate: float | None = None
    muscle_map: Mapping[str, str] | None = None
    image_size: tuple[int, int] | None = None
    frame_rate: float | None = None
    datalog_sensors: Sequence[DatalogSensor] | None = None


@dataclass
class Source:
    """Where a recording comes from: the user's file name for messages, and the bytes or a path.

    Readers never show ``path`` to the user (uploads are stored by hash), only ``name``.
    """

    name: str
    path: Path | None = None
    content: bytes | None = None
    warnings: list[str] = field(default_factory=list)
    utf8: bytes | None = field(default=None, repr=False)
    sidecars: Mapping[str, bytes] = field(default_factory=dict)

    def data(self) -> bytes:
        if self.content is None:
            if self.path is None:
                raise self.error("no data given")
            try:
                self.content = self.path.read_bytes()
            except OSError as exc:
                raise self.error(f"cannot be read: {exc.strerror or exc}") from exc
        return self.content

    def text(self) -> bytes:
        """The content as UTF-8 (text readers and pyarrow need it).

        UTF-8 and ASCII pass through without a copy; UTF-16 (with BOM) is decoded; anything
        else is taken as Windows-1252 / Latin-1, which is what old Windows exports write.
        """
        if self.utf8 is None:
            self.utf8 = to_utf8(self.data())
        return self.utf8

    def error(
        self,
        message: str,
        *,
        line: int | None = None,
        channel: str | None = None,
        expected: str | None = None,
    ) -> RecordingError:
        return RecordingError(
            message, file=self.name, line=line, channel=channel, expected=expected
        )

    def warn(self, message: str) -> None:
        self.warnings.append(message)

    @contextlib.contextmanager
    def as_path(self, suffix: str) -> Iterator[Path]:
        """A real file path, writing the bytes to a temporary file only when there is none.

        Some libraries (pyedflib) insist on a path; uploads only have bytes.
        """
        if self.path is not None:
            yield self.path
            return
        fd, tmp = tempfile.mkstemp(suffix=suffix, prefix="bioplan-upload-")
        try:
            with os.fdopen(fd, "wb") as fh:
                fh.write(self.data())
            yield Path(tmp)
        finally:
            with contextlib.suppress(OSError):
                os.unlink(tmp)

    def sidecar(self, *names: str) -> tuple[str, bytes] | None:
        """(name, bytes) of the first sidecar among ``names``: given with the upload
        (``sidecars``, matched by file name, case-insensitively), else beside the file."""
        given = {Path(k).name.lower(): (Path(k).name, v) for k, v in self.sidecars.items()}
        for n in names:
            if n.lower() in given:
                return given[n.lower()]
        if self.path is None:
            return None
        for n in names:
            p = self.path.with_name(n)
            if p.is_file():
                try:
                    return p.name, p.read_bytes()
                except OSError:
                    return None
        return None


# ---------------------------------------------------------------------------------------------
# units


def to_utf8(data: bytes) -> bytes:
    """``data`` re-encoded as UTF-8 (see ``Source.text``)."""
    if data.isascii():
        return data
    if data[:2] in (b"\xff\xfe", b"\xfe\xff"):
        try:
            return data.decode("utf-16").encode("utf-8")
        except UnicodeDecodeError:
            pass
    try:
        data.decode("utf-8")
        return data
    except UnicodeDecodeError:
        return data.decode("cp1252", errors="replace").encode("utf-8")


_BLANK = b"\xef\xbb\xbf \t\r\n"


def is_blank(data: bytes) -> bool:
    """Whether ``data`` holds nothing but whitespace (and a BOM), without copying a big file."""
    if data[: 1 << 16].strip(_BLANK):
        return False
    return not data.strip(_BLANK)


def norm_unit(unit: str | None) -> str:
    """A unit string folded for comparison: lower case, no spaces, micro sign as 'u'."""
    if unit is None:
        return ""
    text = unit.strip().strip("\"'").replace("µ", "u").replace("μ", "u").replace(" ", "")
    return text.lower()


_VOLT = {
    "v": 1.0,
    "volt": 1.0,
    "volts": 1.0,
    "mv": 1e-3,
    "millivolt": 1e-3,
    "millivolts": 1e-3,
    "uv": 1e-6,
    "microv": 1e-6,
    "microvolt": 1e-6,
    "microvolts": 1e-6,
    "nv": 1e-9,
}
_ANGLE = {
    "deg": math.pi / 180.0,
    "degree": math.pi / 180.0,
    "degrees": math.pi / 180.0,
    "°": math.pi / 180.0,
    "rad": 1.0,
    "radian": 1.0,
    "radians": 1.0,
}
_LENGTH = {"mm": 1e-3, "cm": 1e-2, "m": 1.0, "meter": 1.0, "meters": 1.0, "metres": 1.0}
_ACCEL = {
    "g": G0,
    "mg": G0 * 1e-3,
    "m/s^2": 1.0,
    "m/s2": 1.0,
    "m/s²": 1.0,
    "ms-2": 1.0,
    "m.s-2": 1.0,
    "mm/s^2": 1e-3,
    "mm/s2": 1e-3,
}

SI_UNIT: dict[ChannelKind, str] = {
    "emg": "V",
    "angle": "rad",
    "marker": "m",
    "accel": "m/s^2",
    "landmark": "norm",
    "other": "",
}


def is_voltage(unit: str | None) -> bool:
    return norm_unit(unit) in _VOLT


def is_angle_unit(unit: str | None) -> bool:
    return norm_unit(unit) in _ANGLE


def is_accel_unit(unit: str | None) -> bool:
    u = norm_unit(unit)
    # "g" alone is gravity here; "mg" (milli-g) too: no EMG or angle is stated in grams
    return u in _ACCEL


def si_scale(kind: ChannelKind, unit: str | None) -> tuple[float, str] | None:
    """Factor to SI for a channel of ``kind`` stated in ``unit``; None when the unit is unknown."""
    u = norm_unit(unit)
    table: dict[str, float] | None = {
        "emg": _VOLT,
        "angle": _ANGLE,
        "marker": _LENGTH,
        "accel": _ACCEL,
    }.get(kind)
    if table is None:
        return None
    if u in table:
        return table[u], SI_UNIT[kind]
    return None


def guess_emg_scale(values: F64) -> tuple[float, str]:
    """Scale to volts and the unit assumed, for EMG stated without a unit, from its amplitude.

    Raw sEMG peaks at a few mV: in V the 99th percentile of |x| is well under 0.1, in mV
    between ~0.01 and ~10, in uV above ~30. A warning always says which unit was assumed.
    """
    x = values[:: max(1, values.size // 200_000)]
    x = x[np.isfinite(x)]
    if x.size == 0:
        return 1.0, "V"
    p99 = float(np.percentile(np.abs(x - np.median(x)), 99))
    if p99 < 0.1:
        return 1.0, "V"
    if p99 < 30.0:
        return 1e-3, "mV"
    return 1e-6, "uV"


_UNIT_IN_LABEL = re.compile(r"^(?P<name>.*?)\s*[\(\[]\s*(?P<unit>[^\)\]]*?)\s*[\)\]]\s*$")
_UNIT_SUFFIX = re.compile(
    r"^(?P<name>.+?)[_ ](?P<unit>uV|mV|V|deg|rad|mm|m|g|ms2|m_s2)$", re.IGNORECASE
)


def split_unit(label: str) -> tuple[str, str | None]:
    """``"BICEPS (uV)"`` -> ``("BICEPS", "uV")``; ``"elbow_deg"`` -> ``("elbow_deg", "deg")``.

    A unit in brackets is removed from the name; a ``_unit`` suffix stays in the name (it is
    part of the label the user knows) but still gives the unit.
    """
    m = _UNIT_IN_LABEL.match(label)
    if m and m.group("name"):
        return m.group("name").strip(), m.group("unit").strip()
    m = _UNIT_SUFFIX.match(label)
    if m:
        unit = m.group("unit")
        unit = {"ms2": "m/s^2", "m_s2": "m/s^2"}.get(unit.lower(), unit)
        return label, unit
    return label, None


_ANGLE_WORDS = ("angle", "flexion", "extension", "gonio", "abduction", "adduction", "rotation")
_ACCEL_WORDS = ("acc", "accel", "acceleration")


def classify(label: str, unit: str | None, *, context: str = "") -> ChannelKind:
    """The kind of a scalar channel from its label, its unit and a context (device name...).

    EMG: the label or context says EMG, or names a muscle, or the unit is mV/uV (no other
    analog signal we read is stated in mV or uV). Angles: degrees/radians or an angle word.
    Accelerations: g or m/s^2, or an "acc" word.
    """
    words = re.sub(r"[^a-z]+", " ", (label + " " + context).lower()).split()
    u = norm_unit(unit)
    if "emg" in words or any(w.startswith("emg") for w in words) or is_muscle_label(label):
        return "emg"
    if u in ("mv", "uv", "microv", "microvolt", "microvolts", "millivolt", "millivolts"):
        return "emg"
    if u in _ANGLE or any(w.startswith(a) for w in words for a in _ANGLE_WORDS):
        return "angle"
    if u in _ACCEL or any(w in _ACCEL_WORDS or w.startswith("accel") for w in words):
        return "accel"
    return "other"


# ---------------------------------------------------------------------------------------------
# rates


def check_rate(value: Any, *, src: Source, what: str, channel: str | None = None) -> float:
    """A sampling rate [Hz] as float, or a RecordingError when missing, zero or absurd."""
    try:
        rate = float(value)
    except (TypeError, ValueError):
        raise src.error(
            f"{what} {value!r} is not a number", channel=channel, expected="a rate in Hz"
        ) from None
    if not math.isfinite(rate) or rate <= 0:
        raise src.error(
            f"{what} is {rate:g}", channel=channel, expected="a positive, finite rate in Hz"
        )
    if rate < MIN_RATE or rate > MAX_RATE:
        raise src.error(
            f"{what} {rate:g} Hz is absurd",
            channel=channel,
            expected=f"between {MIN_RATE:g} Hz and {MAX_RATE:g} Hz",
        )
    return rate


def rate_from_times(
    times: F64, *, src: Source, channel: str, first_line: int | None = None
) -> tuple[float, float, F64 | None]:
    """(rate, start, explicit times or None when uniform) from a time column [s].

    Uniform means every step is within 1 % of the median step (CSV exports round times).
    """
    if times.size < 2:
        raise src.error("has a single sample", channel=channel, expected="at least 2 samples")
    if not np.all(np.isfinite(times)):
        idx = int(np.flatnonzero(~np.isfinite(times))[0])
        line = None if first_line is None else first_line + idx
        raise src.error(
            "time is missing or not finite", line=line, channel=channel, expected="a number"
        )
    dt = np.diff(times)
    bad = np.flatnonzero(dt <= 0)
    if bad.size:
        i = int(bad[0]) + 1
        line = None if first_line is None else first_line + i
        raise src.error(
            f"time goes from {times[i - 1]:g} to {times[i]:g} s",
            line=line,
            channel=channel,
            expected="strictly increasing time",
        )
    rate, uniform = grid_rate(times)
    return rate, float(times[0]), None if uniform else times.astype(np.float64)


def grid_rate(times: F64) -> tuple[float, bool]:
    """(rate, uniform) of increasing sample times [s].

    Exports round their time column (1/1500 s printed as 0.00067, 0.00133...), so single
    steps are unreliable: the rate comes from the whole span, and the sampling counts as
    uniform when no sample sits more than a quarter period off that grid (a dropped sample
    or real jitter moves samples by a whole period).
    """
    n = times.size
    # least-squares slope of time against sample index: rounding errors average out
    idx = np.arange(n, dtype=np.float64) - 0.5 * (n - 1)
    centred = times - float(np.mean(times))
    step = float(np.dot(idx, centred) / np.dot(idx, idx))
    grid = float(np.mean(times)) + step * idx
    uniform = bool(np.max(np.abs(times - grid)) <= 0.25 * step)
    if not uniform:
        step = float(np.median(np.diff(times)))
    return nice_rate(1.0 / step), uniform


def nice_rate(rate: float) -> float:
    """``rate`` snapped to 6 significant digits when it is that close (2000, not 1999.9999)."""
    snapped = float(f"{rate:.6g}")
    return snapped if abs(snapped - rate) <= 1e-6 * rate else rate


def emg_median_frequency(x: F64, rate: float) -> float | None:
    """Median frequency [Hz] of a raw EMG signal (Welch-style mean of Hann-windowed segments).

    Uses at most 256 segments spread over the recording so long files stay cheap. Returns None
    when the signal is too short or flat.
    """
    nseg = 256
    if x.size < 4 * nseg:
        return None
    n_segments = min(256, x.size // nseg)
    starts = np.linspace(0, x.size - nseg, n_segments).astype(np.int64)
    seg = x[starts[:, None] + np.arange(nseg)[None, :]]
    seg = seg - seg.mean(axis=1, keepdims=True)
    power = (np.abs(np.fft.rfft(seg * np.hanning(nseg), axis=1)) ** 2).mean(axis=0)
    power[0] = 0.0
    if not np.all(np.isfinite(power)):
        return None
    total = float(power.sum())
    if not math.isfinite(total) or total <= 0:
        return None
    cum = np.cumsum(power)
    k = int(np.searchsorted(cum, 0.5 * total))
    return float(k * rate / nseg)


# A median outside this band at the stored rate means the rate is probably wrong. Typical sEMG
# medians are 50-150 Hz; the band is wider because real low-noise recordings sit near 45 Hz
# (NT-01 at its true 2 kHz) and fine-wire EMG higher.
EMG_MEDIAN_BAND = (20.0, 250.0)
_EMG_MEDIAN_TARGET = 90.0
_COMMON_EMG_RATES = (
    500.0,
    1000.0,
    1024.0,
    1200.0,
    1500.0,
    2000.0,
    2048.0,
    2148.1481,
    2500.0,
    4000.0,
    4096.0,
    5000.0,
    10000.0,
)


def suggest_emg_rate(median: float, rate: float) -> float:
    """A sampling rate that would put an EMG median frequency inside the plausible band.

    Decimal slips (x10, x1000) are the usual metadata error, so they are tried first, then
    common EMG amplifier rates, then the rate that gives a 90 Hz median.
    """
    lo, hi = EMG_MEDIAN_BAND

    def ok(r: float) -> bool:
        return lo <= median * r / rate <= hi

    def closeness(r: float) -> float:
        return abs(math.log(median * r / rate / _EMG_MEDIAN_TARGET))

    slips = [rate * 10.0**k for k in (-3, -2, -1, 1, 2, 3)]
    for group in (slips, list(_COMMON_EMG_RATES)):
        good = [r for r in group if ok(r) and MIN_RATE <= r <= MAX_RATE]
        if good:
            return min(good, key=closeness)
    exact = rate * _EMG_MEDIAN_TARGET / median
    return float(f"{exact:.3g}")


# ---------------------------------------------------------------------------------------------
# channels


def emg_to_volts(values: F64, unit: str | None, *, src: Source, channel: str) -> tuple[F64, str]:
    """EMG values in volts; an unknown or missing unit is guessed from the amplitude."""
    scaled = si_scale("emg", unit)
    if scaled is not None:
        factor = scaled[0]
        return (values * factor if factor != 1.0 else values), "V"
    factor, assumed = guess_emg_scale(values)
    what = f"unit {unit!r} is not a voltage" if unit else "no unit stated"
    src.warn(f"channel {channel!r}: {what}; assumed {assumed} from the amplitude")
    return (values * factor if factor != 1.0 else values), "V"


def scalar_channel(
    name: str,
    values: F64,
    *,
    rate: float,
    unit: str | None,
    kind: ChannelKind,
    src: Source,
    start: float = 0.0,
    time: F64 | None = None,
) -> Channel:
    """A scalar channel converted to SI units for its kind, with the site mapped from its name.

    Angles without a unit are taken as degrees when they exceed 2π somewhere (radians never
    do for joint angles), otherwise radians; a warning says so.
    """
    data = np.asarray(values, dtype=np.float64)
    out_unit = unit or ""
    if kind == "emg":
        data, out_unit = emg_to_volts(data, unit, src=src, channel=name)
    elif kind in ("angle", "accel"):
        scaled = si_scale(kind, unit)
        if scaled is None and kind == "angle":
            finite = data[np.isfinite(data)]
            in_deg = finite.size > 0 and float(np.max(np.abs(finite))) > 2 * math.pi
            scaled = (math.pi / 180.0, "rad") if in_deg else (1.0, "rad")
            src.warn(
                f"channel {name!r}: angle without a unit; assumed "
                f"{'degrees' if in_deg else 'radians'} from its range"
            )
        if scaled is not None:
            factor, out_unit = scaled
            if factor != 1.0:
                data = data * factor
    site = map_muscle(name) if kind == "emg" else None
    return Channel(
        name=name,
        data=data,
        rate=rate,
        unit=out_unit,
        kind=kind,
        start=start,
        site=site,
        time=time,
    )


def position_channel(
    name: str,
    xyz: F64,
    *,
    rate: float,
    unit: str | None,
    kind: ChannelKind,
    src: Source,
    confidence: F64 | None = None,
    start: float = 0.0,
    time: F64 | None = None,
) -> Channel:
    """An (N, 3) marker or landmark channel; NaN rows are missing and get confidence 0."""
    data = np.asarray(xyz, dtype=np.float64)
    out_unit = unit or ""
    if kind == "marker":
        scaled = si_scale("marker", unit)
        if scaled is None:
            src.warn(f"channel {name!r}: marker unit {unit!r} unknown; assumed mm")
            scaled = (1e-3, "m")
        factor, out_unit = scaled
        if factor != 1.0:
            data = data * factor
    missing = ~np.all(np.isfinite(data), axis=1)
    if missing.any():
        data = data.copy()
        data[missing] = np.nan
    conf = np.where(missing, 0.0, 1.0) if confidence is None else confidence.astype(np.float64)
    if confidence is not None:
        conf = np.where(missing | ~np.isfinite(conf), 0.0, np.clip(conf, 0.0, 1.0))
    return Channel(
        name=name,
        data=data,
        rate=rate,
        unit=out_unit,
        kind=kind,
        start=start,
        confidence=conf,
        time=time,
    )


def unique_name(name: str, taken: Mapping[str, object] | set[str]) -> str:
    """``name`` or ``name#2``, ``name#3``... so no channel hides another."""
    if name not in taken:
        return name
    i = 2
    while f"{name}#{i}" in taken:
        i += 1
    return f"{name}#{i}"
