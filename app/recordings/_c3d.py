"""C3D reader (header, parameter section and data parsed with numpy).

ezc3d 1.x crashes (segmentation fault) or hangs on some single-byte corruptions of the
parameter section, which would take a server process down with an upload. This parser
bounds-checks every read and raises RecordingError instead; the tests compare it with ezc3d
on the real files (same analogs and points to float precision).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from app.recordings._common import (
    F64,
    Options,
    Source,
    classify,
    position_channel,
    scalar_channel,
    unique_name,
)
from app.recordings.types import Channel, ChannelKind, Recording

_PROCESSORS = {84: "Intel", 85: "DEC", 86: "MIPS"}


@dataclass
class _Params:
    values: dict[str, Any]

    def get(self, key: str, default: Any = None) -> Any:
        return self.values.get(key, default)

    def number(self, key: str, default: float) -> float:
        v = self.values.get(key)
        if isinstance(v, np.ndarray) and v.size >= 1:
            return float(v.ravel()[0])
        return default

    def _continued(self, group: str, name: str) -> list[object]:
        """The values of ``GROUP:NAME`` followed by ``NAME2``, ``NAME3``... (C3D splits long
        lists), up to the first missing continuation."""
        first = self.values.get(f"{group}:{name}")
        found: list[object] = [] if first is None else [first]
        for i in range(2, 100):
            v = self.values.get(f"{group}:{name}{i}")
            if v is None:
                break
            found.append(v)
        return found

    def strings(self, group: str, name: str) -> list[str]:
        """``GROUP:NAME`` and its continuations as one list of strings."""
        out: list[str] = []
        for v in self._continued(group, name):
            out.extend(v if isinstance(v, list) else [str(v)])
        return out

    def numbers(self, group: str, name: str) -> F64:
        """``GROUP:NAME`` and its continuations as one flat float array."""
        parts = [
            v.ravel().astype(np.float64)
            for v in self._continued(group, name)
            if isinstance(v, np.ndarray)
        ]
        return np.concatenate(parts) if parts else np.zeros(0)


def dec_to_ieee(raw: bytes | np.ndarray, count: int) -> F64:
    """DEC (VAX F) floats to IEEE: swap the 16-bit words, read as IEEE, divide by 4.

    VAX F has the sign/exponent/high-mantissa word first and an exponent bias of 128 with a
    0.1f mantissa, which is the IEEE bit pattern of 4 times the value.
    """
    words = np.frombuffer(raw, dtype="<u2", count=2 * count).reshape(-1, 2).astype(np.uint32)
    bits = (words[:, 0] << 16) | words[:, 1]
    return bits.view(np.float32).astype(np.float64) / 4.0


class _Reader:
    def __init__(self, src: Source, data: bytes, endian: str, dec: bool) -> None:
        self.src = src
        self.data = data
        self.endian = endian
        self.dec = dec

    def need(self, pos: int, size: int, what: str) -> bytes:
        if pos < 0 or size < 0 or pos + size > len(self.data):
            raise self.src.error(
                f"truncated in the {what} (needs bytes {pos}..{pos + size}, file has "
                f"{len(self.data)})",
                expected="a complete C3D file",
            )
        return self.data[pos : pos + size]

    def i8(self, pos: int, what: str) -> int:
        return int(np.frombuffer(self.need(pos, 1, what), dtype=np.int8)[0])

    def u8(self, pos: int, what: str) -> int:
        return self.need(pos, 1, what)[0]

    def i16(self, pos: int, what: str) -> int:
        return int(np.frombuffer(self.need(pos, 2, what), dtype=self.endian + "i2")[0])

    def u16(self, pos: int, what: str) -> int:
        return int(np.frombuffer(self.need(pos, 2, what), dtype=self.endian + "u2")[0])

    def floats(self, raw: bytes, count: int) -> F64:
        if self.dec:
            return dec_to_ieee(raw, count)
        return np.frombuffer(raw, dtype=self.endian + "f4", count=count).astype(np.float64)


def _parse_parameters(r: _Reader, start: int, n_blocks: int) -> _Params:
    end = min(len(r.data), start + max(n_blocks, 1) * 512)
    pos = start + 4
    groups: dict[int, str] = {}
    raw_params: list[tuple[int, str, Any]] = []
    for _ in range(100_000):  # a parameter section holds at most a few thousand entries
        if pos + 2 > end:
            break
        nchars = r.i8(pos, "parameter section")
        gid = r.i8(pos + 1, "parameter section")
        if nchars == 0:
            break
        nlen = abs(nchars)
        raw_name = r.need(pos + 2, nlen, "parameter name").decode("latin-1").strip().upper()
        # A corrupt length makes the "name" the bytes of the next parameters: shown in short.
        name = raw_name if raw_name.isprintable() else repr(raw_name[:24])
        p = pos + 2 + nlen
        offset = r.i16(p, "parameter section")
        nxt = p + offset
        p += 2
        if gid < 0:
            groups[-gid] = name
        elif gid > 0:
            dtype = r.i8(p, f"parameter {name}")
            ndim = r.u8(p + 1, f"parameter {name}")
            dims = list(r.need(p + 2, ndim, f"parameter {name}"))
            p += 2 + ndim
            if dtype not in (-1, 1, 2, 4):
                raise r.src.error(
                    f"parameter {name} has data type {dtype}",
                    expected="-1 (char), 1 (byte), 2 (int16) or 4 (float)",
                )
            count = math.prod(dims) if dims else 1
            raw = r.need(p, abs(dtype) * count, f"parameter {name}")
            value: Any
            if dtype == -1:
                text = raw.decode("latin-1")
                if len(dims) <= 1:
                    value = [text.strip()] if len(dims) == 1 else text
                else:
                    width = dims[0]
                    value = (
                        [text[i : i + width].strip() for i in range(0, len(text), width)]
                        if width
                        else []
                    )
            elif dtype == 1:
                value = np.frombuffer(raw, dtype=np.int8).astype(np.float64)
            elif dtype == 2:
                value = np.frombuffer(raw, dtype=r.endian + "i2").astype(np.float64)
            else:
                value = r.floats(raw, count)
            raw_params.append((gid, name, value))
        if offset == 0 or nxt <= pos:
            break
        pos = nxt
    values: dict[str, Any] = {}
    for gid, name, value in raw_params:
        values[f"{groups.get(gid, str(gid))}:{name}"] = value
    return _Params(values)


def _unsigned(value: float) -> int:
    # Counts stored in signed 16-bit parameters wrap above 32767.
    if not math.isfinite(value):
        return 0
    v = int(value)
    return v + 65536 if v < 0 else v


def read_c3d(src: Source, opts: Options) -> Recording:
    """Analog channels (EMG converted to V) and marker trajectories (m, NaN where residual < 0).

    Analog values are ``(raw - OFFSET) * SCALE * GEN_SCALE``; integer point data is scaled
    by ``|POINT:SCALE|``. Labels longer than one parameter (``LABELS2``...) are joined.
    """
    r, params, proc = _open(src)
    lay = _layout(src, r, params)
    block = _data_block(r, lay)
    channels: dict[str, Channel] = {}
    _analog_channels(
        src,
        params,
        block[:, lay.n_points * 4 :],
        lay.n_analog,
        lay.spf,
        lay.analog_rate,
        lay.is_float,
        lay.start,
        channels,
    )
    _point_channels(
        src,
        params,
        block[:, : lay.n_points * 4],
        lay.n_points,
        abs(lay.scale),
        lay.is_float,
        lay.point_rate,
        lay.start,
        channels,
    )
    metadata = _metadata(params, lay, proc)
    return Recording(channels=channels, source=src.name, format="c3d", metadata=metadata)


def _open(src: Source) -> tuple[_Reader, _Params, int]:
    """A reader over the file, its parameters and its processor type, after header checks."""
    data = src.data()
    if len(data) < 512:
        raise src.error(f"is {len(data)} bytes long", expected="at least the 512-byte C3D header")
    if data[1] != 0x50 or data[0] < 2:
        raise src.error(
            "is not a C3D file (header bytes 1-2)",
            expected="a parameter block number >= 2 and the key 0x50",
        )
    pstart = (data[0] - 1) * 512
    if pstart + 4 > len(data):
        raise src.error("truncated before the parameter section", expected="a complete C3D file")
    proc = data[pstart + 3]
    if proc not in _PROCESSORS:
        raise src.error(
            f"unknown processor type {proc}", expected="84 (Intel), 85 (DEC) or 86 (MIPS)"
        )
    r = _Reader(src, data, ">" if proc == 86 else "<", proc == 85)
    return r, _parse_parameters(r, pstart, data[pstart + 2]), proc


@dataclass(frozen=True)
class _Layout:
    """Where and how the samples are stored."""

    n_points: int
    n_analog: int
    spf: int  # analog samples per channel and frame
    scale: float  # POINT:SCALE (< 0: float storage)
    point_rate: float
    analog_rate: float
    first: int
    n_frames: int
    data_start: int

    @property
    def is_float(self) -> bool:
        return self.scale < 0

    @property
    def start(self) -> float:
        """Time of the first frame [s]."""
        return (self.first - 1) / self.point_rate if self.first >= 1 else 0.0


def _frames(r: _Reader, params: _Params) -> tuple[int, int]:
    """(first, last) frame numbers; TRIAL holds 32-bit ones for trials over 65535 frames."""
    first, last = r.u16(6, "header"), r.u16(8, "header")
    trial_start = params.numbers("TRIAL", "ACTUAL_START_FIELD")
    trial_end = params.numbers("TRIAL", "ACTUAL_END_FIELD")
    if trial_start.size >= 2 and trial_end.size >= 2:
        first = _unsigned(trial_start[0]) + _unsigned(trial_start[1]) * 65536
        last = _unsigned(trial_end[0]) + _unsigned(trial_end[1]) * 65536
    return first, last


def _layout(src: Source, r: _Reader, params: _Params) -> _Layout:
    h_analog_per_frame = r.u16(4, "header")
    h_scale = float(r.floats(r.need(12, 4, "header"), 1)[0])
    h_rate = float(r.floats(r.need(20, 4, "header"), 1)[0])
    n_points = _unsigned(params.number("POINT:USED", r.u16(2, "header")))
    scale = params.number("POINT:SCALE", h_scale)
    point_rate = params.number("POINT:RATE", h_rate)
    data_start = _unsigned(params.number("POINT:DATA_START", r.u16(16, "header")))
    n_analog = _unsigned(params.number("ANALOG:USED", 0.0))
    analog_rate = params.number("ANALOG:RATE", 0.0)
    if not (math.isfinite(scale) and math.isfinite(point_rate) and math.isfinite(analog_rate)):
        raise src.error("point scale or rate is not finite", expected="finite header values")
    first, last = _frames(r, params)
    if last - first + 1 < 1:
        raise src.error(f"frames {first}..{last}", expected="at least one frame")
    if n_analog == 0 or h_analog_per_frame == 0 or analog_rate <= 0:
        raise src.error("has no analog data", expected="analog EMG channels")
    spf = h_analog_per_frame // n_analog
    if spf * n_analog != h_analog_per_frame or spf < 1:
        raise src.error(
            f"{h_analog_per_frame} analog values per frame for {n_analog} channels",
            expected="a whole number of samples per channel and frame",
        )
    if point_rate <= 0:
        point_rate = analog_rate / spf
    if abs(analog_rate / point_rate - spf) > 1e-3 * spf:
        src.warn(
            f"ANALOG:RATE {analog_rate:g} Hz is not {spf} x POINT:RATE {point_rate:g} Hz;"
            f" using {spf * point_rate:g} Hz"
        )
        analog_rate = spf * point_rate
    if data_start < 2:
        raise src.error(f"data start block {data_start}", expected="a block number >= 2")
    return _Layout(
        n_points=n_points,
        n_analog=n_analog,
        spf=spf,
        scale=scale,
        point_rate=point_rate,
        analog_rate=analog_rate,
        first=first,
        n_frames=last - first + 1,
        data_start=data_start,
    )


def _data_block(r: _Reader, lay: _Layout) -> Any:
    """(frames, words per frame) samples: points (x, y, z, residual) then analog values."""
    word = 4 if lay.is_float else 2
    frame_words = lay.n_points * 4 + lay.n_analog * lay.spf
    offset = (lay.data_start - 1) * 512
    raw = r.need(offset, lay.n_frames * frame_words * word, f"data section ({lay.n_frames} frames)")
    if lay.is_float:
        return r.floats(raw, lay.n_frames * frame_words).reshape(lay.n_frames, frame_words)
    return np.frombuffer(raw, dtype=r.endian + "i2").reshape(lay.n_frames, frame_words)


def _metadata(params: _Params, lay: _Layout, proc: int) -> dict[str, Any]:
    metadata: dict[str, Any] = {
        "point_rate": lay.point_rate,
        "analog_rate": lay.analog_rate,
        "stored_rate": lay.analog_rate,
        "frames": lay.n_frames,
        "first_frame": lay.first,
        "processor": _PROCESSORS[proc],
        "points": lay.n_points,
        "analog_channels": lay.n_analog,
    }
    company = params.strings("MANUFACTURER", "COMPANY") + params.strings("MANUFACTURER", "SOFTWARE")
    words: list[str] = []
    for part in company:
        for w in part.split():
            if w not in words:
                words.append(w)
    if words:
        metadata["device"] = " ".join(words)
    subjects = params.strings("SUBJECTS", "NAMES")
    if subjects:
        metadata["subject"] = ", ".join(s for s in subjects if s)
    return metadata


def _analog_channels(
    src: Source,
    params: _Params,
    block: Any,
    n: int,
    spf: int,
    rate: float,
    is_float: bool,
    start: float,
    channels: dict[str, Channel],
) -> None:
    labels = params.strings("ANALOG", "LABELS")
    units = params.strings("ANALOG", "UNITS")
    scale = params.numbers("ANALOG", "SCALE")
    offset = params.numbers("ANALOG", "OFFSET")
    gen = params.number("ANALOG:GEN_SCALE", 1.0)
    unsigned = any("UNSIGNED" in f.upper() for f in params.strings("ANALOG", "FORMAT"))
    samples = np.asarray(block).reshape(-1, n)
    if not is_float and unsigned:
        samples = samples.view(np.uint16)
    if not is_float and unsigned and offset.size:
        offset = np.where(offset < 0, offset + 65536, offset)
    for c in range(n):
        label = labels[c] if c < len(labels) and labels[c] else f"analog{c + 1}"
        unit = units[c] if c < len(units) else None
        s = float(scale[c]) if c < scale.size else 1.0
        o = float(offset[c]) if c < offset.size else 0.0
        values = (samples[:, c].astype(np.float64) - o) * (s * gen)
        name = unique_name(label, channels)
        kind = classify(label, unit)
        channels[name] = scalar_channel(
            name, values, rate=rate, unit=unit, kind=kind, src=src, start=start
        )


def _point_channels(
    src: Source,
    params: _Params,
    block: Any,
    n: int,
    scale: float,
    is_float: bool,
    rate: float,
    start: float,
    channels: dict[str, Channel],
) -> None:
    if n == 0:
        return
    labels = params.strings("POINT", "LABELS")
    unit = (params.strings("POINT", "UNITS") or ["mm"])[0] or "mm"
    pts = np.asarray(block, dtype=np.float64).reshape(-1, n, 4)
    xyz = pts[..., :3] if is_float else pts[..., :3] * scale
    invalid = pts[..., 3] < 0  # residual < 0 marks a missing sample in both storage types
    # Vicon writes model outputs (angles, forces...) as points; they are not positions.
    special: dict[str, tuple[str, str | None]] = {}
    for group, kind_unit in (
        ("ANGLES", "ANGLE_UNITS"),
        ("FORCES", "FORCE_UNITS"),
        ("MOMENTS", "MOMENT_UNITS"),
        ("POWERS", "POWER_UNITS"),
        ("SCALARS", "SCALAR_UNITS"),
    ):
        unit_list = params.strings("POINT", kind_unit)
        for label in params.strings("POINT", group):
            if label:
                special[label] = (group, unit_list[0] if unit_list else None)
    for i in range(n):
        label = labels[i] if i < len(labels) and labels[i] else f"point{i + 1}"
        p = xyz[:, i, :].copy()
        p[invalid[:, i]] = np.nan
        if label in special:
            group, u = special[label]
            kind: ChannelKind = "angle" if group == "ANGLES" else "other"
            for j, axis in enumerate("XYZ"):
                name = unique_name(f"{label}.{axis}", channels)
                channels[name] = scalar_channel(
                    name,
                    p[:, j],
                    rate=rate,
                    unit=u or ("deg" if kind == "angle" else None),
                    kind=kind,
                    src=src,
                    start=start,
                )
            continue
        name = unique_name(label, channels)
        channels[name] = position_channel(
            name, p, rate=rate, unit=unit, kind="marker", src=src, start=start
        )
