"""Generic CSV/TSV, Noraxon MR3 CSV and Vicon Nexus CSV readers."""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from typing import Any

import numpy as np

from app.recordings._common import (
    F64,
    Options,
    Source,
    check_rate,
    classify,
    position_channel,
    rate_from_times,
    scalar_channel,
    split_unit,
    unique_name,
)
from app.recordings._table import (
    Layout,
    Table,
    comment_values,
    detect_layout,
    head_lines,
    read_table,
    split_fields,
    to_float,
)
from app.recordings.types import Channel, Recording

_TIME_NAMES = {
    "time",
    "t",
    "times",
    "timestamp",
    "timestamps",
    "seconds",
    "sec",
    "time_s",
    "elapsed",
    "elapsed_time",
}
_TIME_MS_NAMES = {"time_ms", "timestamp_ms", "ms", "millis", "milliseconds", "t_ms"}
_TIME_UNITS = {"s": 1.0, "sec": 1.0, "seconds": 1.0, "ms": 1e-3, "us": 1e-6, "min": 60.0}
_INDEX_NAMES = {
    "frame",
    "frame#",
    "frames",
    "frame_number",
    "frame_idx",
    "frame_index",
    "sub_frame",
    "subframe",
    "sample",
    "samples",
    "sample_number",
    "index",
    "idx",
}


def _base(label: str) -> tuple[str, str | None]:
    base, unit = split_unit(label)
    return re.sub(r"\s+", "_", base.strip().lower()), unit


def time_column(
    names: list[str], units: dict[str, str | None] | None = None
) -> tuple[str, float] | None:
    """(column, factor to seconds) of the first column that holds time, if any."""
    for name in names:
        base, unit = _base(name)
        unit = unit or (units or {}).get(name)
        if base in _TIME_MS_NAMES:
            return name, 1e-3
        if base in _TIME_NAMES:
            return name, _TIME_UNITS.get((unit or "s").strip().lower(), 1.0)
    return None


def is_index_column(name: str) -> bool:
    return _base(name)[0] in _INDEX_NAMES


def header_rate(values: dict[str, str]) -> float | None:
    """A sampling rate stated in header key/values ("Sampling Rate (Hz)", "fs", "frequency")."""
    for key, value in values.items():
        k = key.lower()
        if k in ("fs", "sr", "srate") or "rate" in k or "frequency" in k:
            number = to_float(value.replace(",", ".")) if value else None
            if number is not None:
                return number
    return None


def timing(
    src: Source,
    table: Table,
    time: tuple[str, float] | None,
    *,
    stored_rate: float | None,
    user_rate: float | None,
) -> tuple[float, float, F64 | None]:
    """(rate, start, explicit times) from the user's rate, a time column or a stated rate."""
    if user_rate is not None:
        start = 0.0
        if time is not None:
            t = table.finite(time[0]) * time[1]
            start = float(t[0])
            if t.size >= 2:
                file_rate = 1.0 / float(np.median(np.diff(t)))
                if abs(file_rate - user_rate) > 0.01 * user_rate:
                    src.warn(
                        f"rate option {user_rate:g} Hz overrides the time column's"
                        f" {file_rate:.6g} Hz"
                    )
        elif stored_rate is not None and abs(stored_rate - user_rate) > 0.01 * user_rate:
            src.warn(f"rate option {user_rate:g} Hz overrides the stated {stored_rate:g} Hz")
        return user_rate, start, None
    if time is not None:
        t = table.finite(time[0]) * time[1]
        rate, start, times = rate_from_times(
            t, src=src, channel=time[0], first_line=table.layout.first_data_line
        )
        rate = check_rate(rate, src=src, what="rate from the time column", channel=time[0])
        if stored_rate is not None and abs(stored_rate - rate) > 0.01 * rate:
            src.warn(
                f"stated rate {stored_rate:g} Hz disagrees with the time column ({rate:.6g} Hz);"
                " the time column is used"
            )
        return rate, start, times
    if stored_rate is not None:
        return check_rate(stored_rate, src=src, what="stated sampling rate"), 0.0, None
    raise src.error(
        "has no time column and no sampling rate",
        expected="a time column, a rate in the header, or the rate option",
    )


def _check_rows(src: Source, table: Table) -> None:
    if table.n_rows < 2:
        raise src.error(
            f"has {table.n_rows} data row(s)",
            line=table.layout.first_data_line,
            expected="at least 2 samples",
        )


def _scalar_channels(
    src: Source,
    table: Table,
    *,
    rate: float,
    start: float,
    times: F64 | None,
    skip: set[str],
    units: dict[str, str | None] | None = None,
    context: str = "",
) -> dict[str, Channel]:
    channels: dict[str, Channel] = {}
    for column in table.numeric:
        if column in skip or is_index_column(column):
            continue
        name, unit = split_unit(column)
        if unit is None and units is not None:
            unit = units.get(column)
        kind = classify(name, unit, context=context)
        values = table.finite(column, channel=name)
        name = unique_name(name, channels)
        channels[name] = scalar_channel(
            name, values, rate=rate, unit=unit, kind=kind, src=src, start=start, time=times
        )
    if not channels:
        raise src.error(
            "has no numeric signal columns",
            line=table.layout.names_line,
            expected="at least one column of numbers besides time",
        )
    return channels


# ---------------------------------------------------------------------------------------------
# generic CSV/TSV


def read_csv(src: Source, opts: Options) -> Recording:
    """Generic delimited text: a header row (or none), a time column or a given rate.

    ``#`` comment lines are read as ``key: value`` metadata; a ``Sampling Rate``/``fs`` key
    gives the rate and ``Labels`` the column names (BioSPPy's text format). When a
    ``Resolution`` (ADC bits) is stated, values are raw counts: the mid-scale offset is
    removed and the unit is ``"counts"``.
    """
    data = src.text()
    layout = detect_layout(data, src)
    header = comment_values(layout)
    names = layout.names
    if names is None:
        labels = next((v for k, v in header.items() if k.lower() in ("labels", "label")), None)
        if labels:
            parts = [p.strip() for p in re.split(r"[,\t;]", labels) if p.strip()]
            if len(parts) == layout.n_fields:
                names = parts
    table = read_table(data, layout, src, names=names)
    _check_rows(src, table)
    units: dict[str, str | None] | None = None
    if layout.units is not None:
        units = {n: (u or None) for n, u in zip(table.names, layout.units, strict=False)}
    tcol = time_column(list(table.numeric), units)
    rate, start, times = timing(
        src, table, tcol, stored_rate=header_rate(header), user_rate=opts.rate
    )
    metadata: dict[str, Any] = {
        "delimiter": layout.delimiter,
        "decimal": layout.decimal,
        "rows": table.n_rows,
    }
    if header:
        metadata["header"] = header
    if layout.preamble:
        # rows above the column names ("Subject,S01"): kept as written
        metadata["preamble"] = [[f for f in row if f] for row in layout.preamble[:50]]
    if table.text or table.empty:
        metadata["ignored_columns"] = list(table.text) + table.empty
    resolution = next((v for k, v in header.items() if k.lower() == "resolution"), None)
    skip = {tcol[0]} if tcol else set()
    if resolution is not None and to_float(resolution) is not None:
        channels = _count_channels(src, table, resolution, rate=rate, start=start, skip=skip)
        metadata["adc_resolution_bits"] = int(float(resolution))
    else:
        channels = _scalar_channels(
            src, table, rate=rate, start=start, times=times, skip=skip, units=units
        )
    return Recording(channels=channels, source=src.name, format="csv", metadata=metadata)


def _count_channels(
    src: Source, table: Table, resolution: str, *, rate: float, start: float, skip: set[str]
) -> dict[str, Channel]:
    bits = float(resolution)
    if not (1 <= bits <= 32):
        raise src.error(f"ADC resolution {resolution!r} bits", expected="1 to 32 bits")
    mid = 2.0 ** (int(bits) - 1)
    channels: dict[str, Channel] = {}
    for column in table.numeric:
        if column in skip or is_index_column(column):
            continue
        kind = classify(column, None)
        values = table.finite(column) - mid
        channels[column] = Channel(
            name=column, data=values, rate=rate, unit="counts", kind=kind, start=start
        )
        if kind == "emg":
            src.warn(
                f"channel {column!r}: EMG in ADC counts ({int(bits)}-bit, mid-scale removed);"
                " no transfer function to volts is stated"
            )
    if not channels:
        raise src.error("has no numeric signal columns", expected="a column of numbers")
    return channels


# ---------------------------------------------------------------------------------------------
# Noraxon MR3


def read_noraxon(src: Source, opts: Options) -> Recording:
    """Noraxon MR3 CSV export: BOM, ``;``, decimal comma, metadata rows, ``"NAME (uV)"``."""
    data = src.text()
    layout = detect_layout(data, src)
    header: dict[str, str] = {}
    if len(layout.preamble) >= 2 and len(layout.preamble[0]) == len(layout.preamble[1]):
        header = {k: v for k, v in zip(layout.preamble[0], layout.preamble[1], strict=True) if k}
    table = read_table(data, layout, src)
    _check_rows(src, table)
    stored = to_float(header.get("frequency", ""), ",") if header.get("frequency") else None
    tcol = time_column(list(table.numeric))
    rate, start, times = timing(src, table, tcol, stored_rate=stored, user_rate=opts.rate)
    skip = {tcol[0]} if tcol else set()
    channels = _scalar_channels(src, table, rate=rate, start=start, times=times, skip=skip)
    metadata: dict[str, Any] = {"device": "Noraxon", "rows": table.n_rows, "header": header}
    version = header.get("exported with version") or header.get("created with version")
    if version:
        metadata["device"] = f"Noraxon MR3 {version}"
    if stored is not None:
        metadata["stored_rate"] = stored
    declared = to_float(header.get("count", ""), ",") if header.get("count") else None
    if declared is not None:
        metadata["declared_rows"] = int(declared)
        metadata["actual_rows"] = table.n_rows
        if int(declared) != table.n_rows:
            src.warn(f"header says {int(declared)} rows, the file holds {table.n_rows}")
    subject = " ".join(
        header.get(k, "").strip() for k in ("first_name", "last_name") if header.get(k, "").strip()
    )
    if subject:
        metadata["subject"] = subject
    for key in ("measurement_date", "record_name"):
        if header.get(key):
            metadata[key] = header[key]
    if table.text or table.empty:
        metadata["annotation_columns"] = list(table.text) + table.empty
    return Recording(channels=channels, source=src.name, format="noraxon_csv", metadata=metadata)


# ---------------------------------------------------------------------------------------------
# Vicon Nexus CSV

VICON_SECTIONS = ("Devices", "Trajectories", "Model Outputs", "Joints", "Segments", "Events")
_SECTION_RE = re.compile(
    rb"^(Devices|Trajectories|Model Outputs|Joints|Segments|Events)[,;\t ]*\r?$", re.MULTILINE
)


def _line_starts(data: bytes, start: int, count: int) -> list[int]:
    """Byte offsets of ``count`` lines starting at ``start`` (plus the offset after them)."""
    out = [start]
    pos = start
    for _ in range(count):
        nl = data.find(b"\n", pos)
        pos = len(data) if nl < 0 else nl + 1
        out.append(pos)
    return out


def read_vicon(src: Source, opts: Options) -> Recording:
    """Vicon Nexus CSV: sections (Devices, Trajectories, Model Outputs...) of 5 header rows.

    Rows: section name, rate, device/marker names, column names, units; then data until a
    blank line. Device columns become scalar channels (EMG converted to V); X/Y/Z triples of
    a trajectory become (N, 3) markers in metres with NaN where the cell is empty.
    """
    data = src.text()
    starts = [m.start() for m in _SECTION_RE.finditer(data)]
    if not starts:
        raise src.error(
            "has no Vicon section header", line=1, expected="'Devices' or 'Trajectories'"
        )
    channels: dict[str, Channel] = {}
    metadata: dict[str, Any] = {"device": "Vicon Nexus", "sections": {}}
    if opts.rate is not None:
        src.warn("rate option ignored: every Vicon section states its own rate")
    for i, start in enumerate(starts):
        end = starts[i + 1] if i + 1 < len(starts) else len(data)
        _vicon_section(src, data, start, end, channels, metadata)
    if not channels:
        raise src.error("has no data in any section", expected="rows of numbers")
    return Recording(channels=channels, source=src.name, format="vicon_csv", metadata=metadata)


@dataclass
class _ViconHeader:
    """The 5 header rows of one Vicon section, split into fields."""

    section: str
    rate: float
    delim: str
    groups: list[str]
    cols: list[str]
    units: list[str]
    offsets: list[int]
    first_line: int


def _vicon_section(
    src: Source,
    data: bytes,
    start: int,
    end: int,
    channels: dict[str, Channel],
    metadata: dict[str, Any],
) -> None:
    head = _vicon_header(src, data, start)
    if head is None:
        return
    table, n = _vicon_table(src, data, end, head)
    t0 = _vicon_start(src, table, head, metadata)
    _vicon_channels(src, table, n, head, t0, channels)


def _vicon_header(src: Source, data: bytes, start: int) -> _ViconHeader | None:
    """The section's header rows (None for the Events section, which holds no signal)."""
    offsets = _line_starts(data, start, 5)
    first_line = data.count(b"\n", 0, start) + 1
    rows = [
        data[offsets[k] : offsets[k + 1]].decode("utf-8", "replace").rstrip("\r\n")
        for k in range(5)
    ]
    section = rows[0].strip(",;\t ")
    if section == "Events":
        return None
    delim = next((d for d in (",", ";", "\t") if d in rows[3]), ",")
    rate_text = split_fields(rows[1], delim)[0] if rows[1] else ""
    stored = to_float(rate_text)
    if stored is None:
        raise src.error(
            f"{section} rate {rate_text!r} is not a number",
            line=first_line + 1,
            expected="the sampling rate in Hz on the row after the section name",
        )
    cols = split_fields(rows[3], delim)
    while cols and not cols[-1]:
        cols.pop()
    if len(cols) < 3 or cols[0].lower() != "frame":
        raise src.error(
            f"{section} column row starts with {cols[:2]!r}",
            line=first_line + 3,
            expected="'Frame,Sub Frame,...' as the 4th row of a section",
        )
    return _ViconHeader(
        section=section,
        rate=check_rate(stored, src=src, what=f"{section} rate"),
        delim=delim,
        groups=split_fields(rows[2], delim),
        cols=cols,
        units=split_fields(rows[4], delim),
        offsets=offsets,
        first_line=first_line,
    )


def _vicon_table(src: Source, data: bytes, end: int, head: _ViconHeader) -> tuple[Table, int]:
    """The section's numbers (columns named by index) and its number of columns."""
    offsets, first_line, section = head.offsets, head.first_line, head.section
    # data rows may carry trailing empty fields the column row does not
    nl = data.find(b"\n", offsets[5])
    first_row = data[offsets[5] : nl if nl >= 0 else len(data)].decode("utf-8", "replace")
    n = max(len(head.cols), len(split_fields(first_row.rstrip("\r"), head.delim)))
    head.cols = (head.cols + [""] * n)[:n]
    head.groups = (head.groups + [""] * n)[:n]
    head.units = (head.units + [""] * n)[:n]
    # Data ends at the first blank line (sections are separated by one).
    blank = re.compile(rb"\n[,;\t ]*\r?\n")
    m = blank.search(data, offsets[5] - 1 if offsets[5] > 0 else 0, end)
    stop = m.start() + 1 if m else end
    if stop <= offsets[5]:
        raise src.error(f"{section} has no data rows", line=first_line + 5, expected="numbers")
    layout = Layout(
        delimiter=head.delim,
        decimal=".",
        comments=[],
        preamble=[],
        preamble_lines=[],
        names=None,
        names_line=first_line + 3,
        units=None,
        data_offset=offsets[5],
        first_data_line=first_line + 5,
        n_fields=n,
    )
    table = read_table(data, layout, src, names=[f"{k}" for k in range(n)], end=stop)
    if table.n_rows < 2:
        raise src.error(
            f"{section} has {table.n_rows} data row(s)",
            line=first_line + 5,
            expected="at least 2 samples",
        )
    return table, n


def _vicon_start(src: Source, table: Table, head: _ViconHeader, metadata: dict[str, Any]) -> float:
    """Time of the section's first row [s] from its frame and sub-frame numbers."""
    rate, section = head.rate, head.section
    frames = table.finite("0", channel="Frame")
    subs = table.numeric.get("1")
    n_sub = int(np.nanmax(subs)) + 1 if subs is not None and np.isfinite(subs).any() else 1
    frame_rate = rate / max(n_sub, 1)
    first_sub = float(subs[0]) if subs is not None and np.isfinite(subs[0]) else 0.0
    t0 = (float(frames[0]) - 1.0) / frame_rate + first_sub / rate
    expected_rows = round((float(frames[-1]) - float(frames[0]) + 1) * n_sub)
    if expected_rows != table.n_rows:
        src.warn(
            f"{section}: frames {frames[0]:g}..{frames[-1]:g} with {n_sub} sub-frames should be"
            f" {expected_rows} rows, the file holds {table.n_rows}"
        )
    metadata["sections"][section] = {
        "rate": rate,
        "rows": table.n_rows,
        "first_frame": int(frames[0]),
    }
    return t0


def _vicon_channels(
    src: Source,
    table: Table,
    n: int,
    head: _ViconHeader,
    t0: float,
    channels: dict[str, Channel],
) -> None:
    """Device columns as scalar channels, X/Y/Z triples as markers, into ``channels``."""
    current = ""
    group_of: list[str] = []
    for g in head.groups:
        current = g or current
        group_of.append(current)
    k = 2
    while k < n:
        triple = [c.upper() for c in head.cols[k : k + 3]]
        if triple == ["X", "Y", "Z"] and head.section != "Devices":
            _vicon_triple(src, table, k, group_of[k], head, t0, channels)
            k += 3
            continue
        if str(k) in table.numeric:
            col, group = head.cols[k], group_of[k]
            short = group.rsplit(" - ", 1)[-1].strip() if group else ""
            label = col or f"column{k + 1}"
            if re.fullmatch(r"\d+", label) or (label in channels and short):
                label = f"{short}.{label}" if short else label
            name = unique_name(label, channels)
            unit = head.units[k] or None
            values = table.finite(str(k), channel=name)
            channels[name] = scalar_channel(
                name, values, rate=head.rate, unit=unit, kind=classify(col, unit), src=src,
                start=t0,
            )  # fmt: skip
        k += 1


def _vicon_triple(
    src: Source,
    table: Table,
    k: int,
    group: str,
    head: _ViconHeader,
    t0: float,
    channels: dict[str, Channel],
) -> None:
    """Columns k..k+2 (X, Y, Z): a marker when the unit is a length, else three scalars."""
    unit = head.units[k] or None
    name = unique_name(group or f"column{k + 1}", channels)
    if norm_is_length(unit):
        xyz = np.column_stack([table.numeric.get(str(k + j), _nan(table.n_rows)) for j in range(3)])
        channels[name] = position_channel(
            name, xyz, rate=head.rate, unit=unit, kind="marker", src=src, start=t0
        )
        return
    for j, axis in enumerate("XYZ"):
        sub = unique_name(f"{name}.{axis}", channels)
        values = table.finite(str(k + j), channel=sub)
        channels[sub] = scalar_channel(
            sub, values, rate=head.rate, unit=unit, kind=classify(group, unit), src=src, start=t0
        )


def _nan(n: int) -> F64:
    return np.full(n, np.nan)


def norm_is_length(unit: str | None) -> bool:
    return (unit or "").strip().lower() in ("mm", "cm", "m")


def sniff_vicon(data: bytes) -> bool:
    lines = [ln.text for ln in head_lines(data, limit=4096)[:2]]
    if len(lines) < 2:
        return False
    first = lines[0].strip().strip(",;\t ")
    rate = lines[1].strip().strip(",;\t ")
    return first in VICON_SECTIONS and to_float(rate) is not None and math.isfinite(float(rate))
