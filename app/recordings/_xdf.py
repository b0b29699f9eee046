"""XDF (Lab Streaming Layer recordings) via pyxdf: EMG and motion-capture streams on one clock.

An XDF file holds several streams, each with its own header (name, type, channel count,
nominal rate, channel format, ``desc/channels/channel`` with label, unit, type, marker), its
samples with time stamps of the sending computer's LSL clock, and ClockOffset chunks that relate
that clock to the recording computer's. pyxdf (``load_xdf(..., synchronize_clocks=True)``)
applies the offsets, so every stream's time stamps are on the recorder's LSL clock: that is
the recording's clock, with time 0 at the first sample of any stream (stated in
``metadata["clock"]``).

Numeric streams of type ``EMG`` give EMG channels (converted to V) at their nominal rate;
streams of type ``MoCap`` give one (N, 3) marker channel per marker from the channels' X/Y/Z
components (LSL's MoCap meta-data: ``marker`` + ``type`` PositionX/Y/Z, or labels ending in
X/Y/Z) in metres. Other numeric streams become scalar channels classified by their labels;
string (event marker) streams are listed in the metadata and skipped.
"""

from __future__ import annotations

import io
import re
from typing import Any

import numpy as np

from app.recordings._common import (
    F64,
    Options,
    Source,
    check_rate,
    classify,
    position_channel,
    scalar_channel,
    unique_name,
)
from app.recordings.types import Channel, Recording

MAGIC = b"XDF:"
_UNITS = {
    "microvolts": "uV",
    "microvolt": "uV",
    "millivolts": "mV",
    "volts": "V",
    "millimeters": "mm",
    "millimetres": "mm",
    "centimeters": "cm",
    "meters": "m",
    "metres": "m",
}
_AXIS = re.compile(r"^(?P<marker>.*?)[\s_.:-]*(?:pos(?:ition)?)?[\s_.:-]*(?P<axis>[xyz])$", re.I)
_MOCAP_TYPES = {"mocap", "motioncapture", "motion capture", "markers3d", "position"}


def _text(info: dict[str, Any], key: str) -> str:
    value = info.get(key)
    while isinstance(value, list):
        value = value[0] if value else ""
    return str(value or "").strip()


def _channel_meta(info: dict[str, Any], n: int) -> list[dict[str, str]]:
    """label, unit, type, marker of each channel (from ``desc/channels/channel``)."""
    out: list[dict[str, str]] = []
    desc = info.get("desc")
    try:
        channels = desc[0]["channels"][0]["channel"]  # type: ignore[index]
    except (TypeError, KeyError, IndexError):
        channels = []
    for k in range(n):
        ch = channels[k] if k < len(channels) and isinstance(channels[k], dict) else {}
        meta = {key: _text(ch, key) for key in ("label", "unit", "type", "marker")}
        meta["label"] = meta["label"] or f"{_text(info, 'name') or 'channel'} {k + 1}"
        out.append(meta)
    return out


def _unit(text: str) -> str | None:
    return _UNITS.get(text.strip().lower(), text.strip() or None)


def _is_mocap(stream_type: str) -> bool:
    return stream_type.strip().lower() in _MOCAP_TYPES


def read_xdf(src: Source, opts: Options) -> Recording:
    """Every numeric stream of an XDF file, on the recorder's clock (offsets applied)."""
    import pyxdf

    streams, header = pyxdf.load_xdf(
        io.BytesIO(src.data()), synchronize_clocks=True, dejitter_timestamps=True
    )
    series = [s for s in streams if len(s.get("time_stamps", ())) >= 2]
    if not series:
        raise src.error("has no stream with samples", expected="an XDF file with data streams")
    if opts.rate is not None:
        src.warn("rate option ignored: every XDF stream states its own rate (use emg_rate)")
    t0 = min(float(s["time_stamps"][0]) for s in series)
    channels: dict[str, Channel] = {}
    described: list[dict[str, Any]] = []
    for stream in series:
        described.append(_stream(src, stream, t0, channels, opts))
    if not channels:
        raise src.error("has no numeric stream", expected="EMG or motion-capture streams")
    version = _text(header.get("info", {}), "version")
    metadata: dict[str, Any] = {
        "device": "Lab Streaming Layer (XDF" + (f" {version}" if version else "") + ")",
        "streams": described,
        "clock": "the recording computer's LSL clock (ClockOffset chunks applied by pyxdf),"
        f" time 0 = first sample of any stream, at LSL time {t0:.6f} s",
        "lsl_time_zero": t0,
    }
    return Recording(channels=channels, source=src.name, format="xdf", metadata=metadata)


def _stream(
    src: Source, stream: dict[str, Any], t0: float, channels: dict[str, Channel], opts: Options
) -> dict[str, Any]:
    """Add one stream's channels; a description of the stream for the metadata."""
    del opts  # the streams state their own rates; emg_rate and the muscle map apply later
    info = stream["info"]
    name, stype = _text(info, "name"), _text(info, "type")
    fmt = _text(info, "channel_format")
    stamps = np.asarray(stream["time_stamps"], dtype=np.float64)
    nominal = float(_text(info, "nominal_srate") or 0.0)
    about: dict[str, Any] = {
        "name": name,
        "type": stype,
        "channel_format": fmt,
        "nominal_rate_hz": nominal,
        "samples": int(stamps.size),
        "start_s": float(stamps[0] - t0),
    }
    effective = float(info.get("effective_srate") or 0.0)
    if effective:
        about["effective_rate_hz"] = effective
    if fmt == "string":
        about["skipped"] = "string (event marker) stream"
        return about
    data = np.asarray(stream["time_series"], dtype=np.float64)
    if data.ndim == 1:
        data = data[:, None]
    what = f"nominal_srate of stream {name!r}"
    if nominal > 0:
        rate, times = check_rate(nominal, src=src, what=what), None
        if effective and abs(effective - nominal) > 0.01 * nominal:
            src.warn(
                f"stream {name!r}: {effective:.6g} Hz measured from its time stamps, nominal"
                f" {nominal:g} Hz; the nominal rate is used"
            )
    else:  # irregular stream: keep its time stamps
        rate = check_rate(
            (stamps.size - 1) / float(stamps[-1] - stamps[0]), src=src, what=f"rate of {name!r}"
        )
        times = stamps - t0
    start = float(stamps[0] - t0)
    meta = _channel_meta(info, data.shape[1])
    if _is_mocap(stype):
        _mocap(src, name, data, meta, rate=rate, start=start, times=times, channels=channels)
        return about
    context = "emg" if stype.lower() == "emg" else ""
    for k, m in enumerate(meta):
        unit = _unit(m["unit"])
        kind = classify(m["label"], unit, context=context or m["type"])
        label = unique_name(m["label"], channels)
        channels[label] = scalar_channel(
            label, data[:, k], rate=rate, unit=unit, kind=kind, src=src, start=start, time=times
        )
    return about


def _mocap(
    src: Source,
    stream: str,
    data: F64,
    meta: list[dict[str, str]],
    *,
    rate: float,
    start: float,
    times: F64 | None,
    channels: dict[str, Channel],
) -> None:
    """One (N, 3) marker channel per marker of a MoCap stream."""
    axes: dict[str, dict[str, int]] = {}
    units: dict[str, str | None] = {}
    for k, m in enumerate(meta):
        ctype = m["type"].lower()
        if ctype.startswith("position") and ctype[-1:] in "xyz" and m["marker"]:
            marker, axis = m["marker"], ctype[-1]
        else:
            match = _AXIS.match(m["label"])
            if match is None or not match["marker"]:
                continue
            marker, axis = match["marker"], match["axis"].lower()
        axes.setdefault(marker, {})[axis] = k
        units.setdefault(marker, _unit(m["unit"]))
    for marker, cols in axes.items():
        if set(cols) != {"x", "y", "z"}:
            src.warn(f"stream {stream!r}: marker {marker!r} lacks an X, Y or Z channel; skipped")
            continue
        xyz = data[:, [cols["x"], cols["y"], cols["z"]]]
        name = unique_name(marker, channels)
        channels[name] = position_channel(
            name, xyz, rate=rate, unit=units[marker], kind="marker", src=src, start=start,
            time=times,
        )  # fmt: skip
