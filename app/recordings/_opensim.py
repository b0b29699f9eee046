"""OpenSim TRC (marker trajectories) and MOT/STO (coordinates, forces) readers.

Headers state row counts (``NumFrames``, ``nRows``) that exports often get wrong; the data
rows are counted instead, and both numbers go into the metadata with a warning when they
differ. Tab- and comma-separated files are read alike.
"""

from __future__ import annotations

import re
from typing import Any

import numpy as np

from app.recordings._common import (
    F64,
    Options,
    Source,
    check_rate,
    position_channel,
    rate_from_times,
    scalar_channel,
    unique_name,
)
from app.recordings._table import Layout, Table, head_lines, read_table, split_fields, to_float
from app.recordings.types import Channel, ChannelKind, Recording


def _delimiter(text: str) -> str:
    return "\t" if "\t" in text else ","


def _data_layout(
    src: Source,
    data: bytes,
    *,
    start_line_index: int,
    delimiter: str,
    n_fields: int,
    names_line: int,
) -> Layout:
    lines = head_lines(data)
    for ln in lines[start_line_index:]:
        if ln.text.strip(" ,\t"):
            return Layout(
                delimiter=delimiter,
                decimal=".",
                comments=[],
                preamble=[],
                preamble_lines=[],
                names=None,
                names_line=names_line,
                units=None,
                data_offset=ln.start,
                first_data_line=ln.number,
                n_fields=n_fields,
            )
    raise src.error("has no data rows", line=names_line, expected="rows of numbers")


def _field_count(src: Source, data: bytes, delimiter: str, first: int) -> int:
    lines = head_lines(data)
    for ln in lines[first:]:
        if ln.text.strip(" ,\t"):
            return len(split_fields(ln.text, delimiter))
    raise src.error("has no data rows", expected="rows of numbers")


def read_trc(src: Source, opts: Options) -> Recording:
    """TRC: 5 header lines (file type, keys, values, marker names, X1/Y1/Z1), then data."""
    data = src.text()
    lines = head_lines(data)
    if len(lines) < 5 or not lines[0].text.startswith("PathFileType"):
        raise src.error("is not a TRC file", line=1, expected="'PathFileType' on line 1")
    delim = _delimiter(lines[0].text)
    keys = split_fields(lines[1].text, delim)
    values = split_fields(lines[2].text, delim)
    header = {k: v for k, v in zip(keys, values, strict=False) if k}
    names_row = split_fields(lines[3].text, delim)
    n_fields = _field_count(src, data, delim, 5)
    stored = to_float(header.get("DataRate", "")) if header.get("DataRate") else None
    if stored is None and opts.rate is None:
        raise src.error(
            "states no DataRate", line=3, expected="a DataRate value or the rate option"
        )
    rate = check_rate(opts.rate if opts.rate is not None else stored, src=src, what="DataRate")
    unit = header.get("Units", "mm") or "mm"
    layout = _data_layout(
        src, data, start_line_index=5, delimiter=delim, n_fields=n_fields, names_line=4
    )
    table = read_table(data, layout, src, names=[str(i) for i in range(n_fields)])
    if table.n_rows < 2:
        raise src.error(
            f"has {table.n_rows} data row(s)",
            line=layout.first_data_line,
            expected="at least 2 frames",
        )
    start = 0.0
    times: F64 | None = None
    if "1" in table.numeric and opts.rate is None:
        t = table.finite("1", channel="Time")
        file_rate, start, times = rate_from_times(
            t, src=src, channel="Time", first_line=layout.first_data_line
        )
        if abs(file_rate - rate) > 0.01 * rate:
            src.warn(f"DataRate {rate:g} Hz disagrees with the Time column ({file_rate:.6g} Hz)")
    channels: dict[str, Channel] = {}
    for k in range(2, n_fields - 2, 3):
        label = names_row[k] if k < len(names_row) and names_row[k] else f"marker{(k - 2) // 3 + 1}"
        cols = [table.numeric.get(str(k + j)) for j in range(3)]
        if any(c is None for c in cols):
            if all(str(k + j) in table.empty for j in range(3)):
                cols = [np.full(table.n_rows, np.nan)] * 3
            else:
                raise src.error("marker columns are not numeric", channel=label, expected="numbers")
        xyz = np.column_stack([c for c in cols if c is not None])
        name = unique_name(label, channels)
        channels[name] = position_channel(
            name, xyz, rate=rate, unit=unit, kind="marker", src=src, start=start, time=times
        )
    if not channels:
        raise src.error("has no marker columns", line=4, expected="X/Y/Z columns per marker")
    metadata: dict[str, Any] = {
        "header": header,
        "stored_rate": stored,
        "actual_rows": table.n_rows,
    }
    declared = to_float(header.get("NumFrames", "")) if header.get("NumFrames") else None
    if declared is not None:
        metadata["declared_rows"] = int(declared)
        if int(declared) != table.n_rows:
            src.warn(f"header says NumFrames={int(declared)}, the file holds {table.n_rows} rows")
    n_markers = to_float(header.get("NumMarkers", "")) if header.get("NumMarkers") else None
    if n_markers is not None and int(n_markers) != len(channels):
        src.warn(f"header says NumMarkers={int(n_markers)}, the file has {len(channels)}")
    return Recording(channels=channels, source=src.name, format="trc", metadata=metadata)


_ROTATION_EXCLUDE = re.compile(r"(_t[xyz]|_trans[xyz]?|trans[xyz])$", re.IGNORECASE)
#: Words of OpenSim coordinate names (arm26, Rajagopal, MoBL, gait models): an STO column in
#: radians is an angle only when it names a coordinate, not a muscle's activation or force.
_COORDINATE_WORDS = re.compile(
    r"(flex|elev|elv|_ele|rot|add|abd|angle|tilt|list|pro_sup|dev|bend|extension|supination"
    r"|pronation|shoulder|elbow|wrist|knee|hip|ankle|lumbar|pelvis|subtalar|mtp|thorax|neck)",
    re.IGNORECASE,
)
#: OpenSim 4 state paths: ``/jointset/<joint>/<coordinate>/value`` (and ``/speed``).
_STATE_PATH = re.compile(r"^/jointset/[^/]+/(?P<coord>[^/]+)/(?P<what>value|speed)$")


def read_mot(src: Source, opts: Options, *, fmt: str = "mot") -> Recording:
    """MOT/STO: ``key=value`` header up to ``endheader``, column names, data.

    MOT columns are coordinates: rotations become angles (degrees converted to radians when
    ``inDegrees=yes``), translations (``*_tx``...) stay metres. STO columns named
    ``*_moment``/``*_force`` are N·m/N; other STO columns are coordinates when
    ``inDegrees=yes``; with ``inDegrees=no`` (OpenSim's IK and states files in radians) the
    columns that name a coordinate (``r_elbow_flex``, ``/jointset/r_elbow/r_elbow_flex/value``)
    are angles in radians (``.../speed`` in rad/s), the rest (activations...) unitless.
    """
    data = src.text()
    lines = head_lines(data)
    end = next(
        (i for i, ln in enumerate(lines) if ln.text.strip(" ,\t").lower() == "endheader"), None
    )
    if end is None:
        raise src.error("has no 'endheader' line", expected="an OpenSim header ending in endheader")
    header: dict[str, str] = {}
    for ln in lines[:end]:
        text = ln.text.strip(" ,\t")
        if "=" in text:
            k, _, v = text.partition("=")
            header[k.strip()] = v.strip()
    table, names_line = _mot_table(src, data, lines, end)
    stated = {k.lower(): v.strip().lower() for k, v in header.items()}
    in_degrees = stated.get("indegrees", "no") == "yes"
    radians = stated.get("indegrees") == "no"
    tcol = next((c for c in table.numeric if c.strip().lower() == "time"), None)
    rate, start, times = _mot_timing(src, opts, table, tcol, names_line)
    channels: dict[str, Channel] = {}
    for column in table.numeric:
        if column == tcol:
            continue
        kind, unit = _mot_kind(column, fmt, in_degrees, radians=radians)
        name = unique_name(column, channels)
        values = table.finite(column)
        if unit == "deg/s":
            values, unit = np.deg2rad(values), "rad/s"
        channels[name] = scalar_channel(
            name, values, rate=rate, unit=unit, kind=kind, src=src, start=start, time=times
        )
    if not channels:
        raise src.error("has no data columns", line=names_line, expected="coordinates")
    metadata: dict[str, Any] = {
        "header": header,
        "in_degrees": in_degrees,
        "actual_rows": table.n_rows,
        "title": lines[0].text.strip(" ,\t"),
    }
    declared = to_float(header.get("nRows", "")) if header.get("nRows") else None
    if declared is not None:
        metadata["declared_rows"] = int(declared)
        if int(declared) != table.n_rows:
            src.warn(f"header says nRows={int(declared)}, the file holds {table.n_rows} rows")
    return Recording(channels=channels, source=src.name, format=fmt, metadata=metadata)


def _mot_table(src: Source, data: bytes, lines: list[Any], end: int) -> tuple[Table, int]:
    """(the data table, line number of the column names) after ``endheader``."""
    names_idx = next((i for i in range(end + 1, len(lines)) if lines[i].text.strip(" ,\t")), None)
    if names_idx is None:
        raise src.error(
            "has no column names after endheader",
            line=lines[end].number + 1,
            expected="a column name row",
        )
    names_line = lines[names_idx]
    delim = _delimiter(names_line.text)
    names = split_fields(names_line.text, delim)
    n_fields = _field_count(src, data, delim, names_idx + 1)
    names = (names + [f"column{i + 1}" for i in range(len(names), n_fields)])[:n_fields]
    layout = _data_layout(
        src,
        data,
        start_line_index=names_idx + 1,
        delimiter=delim,
        n_fields=n_fields,
        names_line=names_line.number,
    )
    table = read_table(data, layout, src, names=names)
    if table.n_rows < 2:
        raise src.error(
            f"has {table.n_rows} data row(s)",
            line=layout.first_data_line,
            expected="at least 2 rows",
        )
    return table, names_line.number


def _mot_timing(
    src: Source, opts: Options, table: Table, tcol: str | None, names_line: int
) -> tuple[float, float, F64 | None]:
    """(rate, start, explicit times) from the rate option or the time column."""
    if opts.rate is not None:
        return check_rate(opts.rate, src=src, what="rate option"), 0.0, None
    if tcol is None:
        raise src.error(
            "has no time column", line=names_line, expected="a 'time' column or the rate option"
        )
    rate, start, times = rate_from_times(
        table.finite(tcol), src=src, channel=tcol, first_line=table.layout.first_data_line
    )
    return check_rate(rate, src=src, what="rate from the time column"), start, times


def _mot_kind(
    column: str, fmt: str, in_degrees: bool, *, radians: bool = False
) -> tuple[ChannelKind, str]:
    """(kind, unit as stored) of a MOT/STO column; ``radians``: the header says inDegrees=no."""
    lower = column.lower()
    if lower.endswith(("_moment", "_torque")):
        return "other", "N*m"
    if lower.endswith("_force"):
        return "other", "N"
    state = _STATE_PATH.match(column.strip())
    if state is not None:
        translation = _ROTATION_EXCLUDE.search(state["coord"]) is not None
        if state["what"] == "speed":
            return "other", "m/s" if translation else ("deg/s" if in_degrees else "rad/s")
        return ("other", "m") if translation else ("angle", "deg" if in_degrees else "rad")
    coordinate = radians and _COORDINATE_WORDS.search(column) and "/" not in column
    if fmt == "sto" and not in_degrees and not coordinate:
        return "other", ""
    if _ROTATION_EXCLUDE.search(column):
        return "other", "m"
    return "angle", "deg" if in_degrees else "rad"


def read_sto(src: Source, opts: Options) -> Recording:
    return read_mot(src, opts, fmt="sto")
