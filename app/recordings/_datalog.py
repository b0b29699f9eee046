"""Biometrics DataLOG ASCII export: tab-separated ADC counts, one column per sensor."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any, get_args

import numpy as np

from app.errors import BioPlanError
from app.recordings._common import (
    F64,
    Options,
    Source,
    check_rate,
    emg_to_volts,
    si_scale,
    unique_name,
)
from app.recordings._table import Table, detect_layout, read_table
from app.recordings.muscles import map_muscle
from app.recordings.types import Channel, ChannelKind, DatalogSensor, Recording

_KINDS: tuple[str, ...] = get_args(ChannelKind)


def _pad_short_rows(data: bytes) -> bytes:
    """Rows padded with trailing tabs to the widest row, when an export dropped empty fields.

    Counting tabs per line is vectorised; the Python rewrite only runs when rows differ.
    """
    arr = np.frombuffer(data, dtype=np.uint8)
    newlines = np.flatnonzero(arr == 10)
    ends = np.append(newlines, arr.size)
    tabs = np.concatenate(([0], np.cumsum(arr == 9)))
    starts = np.concatenate(([0], newlines + 1))
    per_line = tabs[ends] - tabs[starts]
    length = ends - starts
    filled = per_line[length > 1]
    if filled.size == 0 or filled.min() == filled.max():
        return data
    width = int(filled.max())
    out = []
    for raw in data.split(b"\n"):
        line = raw.rstrip(b"\r")
        if line.strip():
            line = line + b"\t" * (width - line.count(b"\t"))
        out.append(line)
    return b"\n".join(out)


def sensors_from_json(obj: Any) -> list[DatalogSensor]:
    """Sensors from a sidecar: ``{"sensors": [{column, name, kind, rate, ...}]}`` or a list."""
    items = obj.get("sensors") if isinstance(obj, dict) else obj
    if not isinstance(items, list):
        raise BioPlanError("expected a list of sensors or {'sensors': [...]}")
    out = []
    for i, it in enumerate(items):
        if not isinstance(it, dict):
            raise BioPlanError(f"sensor {i} is not an object")
        try:
            out.append(
                DatalogSensor(
                    column=int(it["column"]),
                    name=str(it["name"]),
                    kind=it.get("kind", "other"),
                    rate=float(it["rate"]),
                    physical_range=float(it["physical_range"]),
                    unit=str(it.get("unit", "counts")),
                    counts_range=float(it.get("counts_range", 4000.0)),
                )
            )
        except (KeyError, TypeError, ValueError) as exc:
            raise BioPlanError(f"sensor {i}: {exc}") from None
    return out


def _sidecar_sensors(src: Source) -> list[DatalogSensor] | None:
    name = Path(src.name)
    side = src.sidecar(name.name + ".json", name.stem + ".json")
    if side is None and src.path is not None:
        side = src.sidecar(src.path.name + ".json", src.path.stem + ".json")
    if side is None:
        return None
    try:
        return sensors_from_json(json.loads(side[1].decode("utf-8")))
    except (UnicodeDecodeError, ValueError) as exc:
        raise src.error(
            f"sidecar {side[0]} cannot be used: {exc}",
            expected='{"sensors": [{"column", "name", "kind", "rate", "physical_range", "unit"}]}',
        ) from None


def _check_sensor(src: Source, s: DatalogSensor, n_columns: int) -> float:
    label = s.name or f"column {s.column}"
    if not isinstance(s.column, int) or not 0 <= s.column < n_columns:
        raise src.error(
            f"sensor column {s.column!r} does not exist",
            channel=label,
            expected=f"a 0-based column index below {n_columns}",
        )
    if s.kind not in _KINDS:
        raise src.error(f"sensor kind {s.kind!r}", channel=label, expected=f"one of {_KINDS}")
    for what, v in (("counts_range", s.counts_range), ("physical_range", s.physical_range)):
        if not (isinstance(v, int | float) and math.isfinite(v) and v > 0):
            raise src.error(f"{what} is {v!r}", channel=label, expected="a positive number")
    return check_rate(s.rate, src=src, what="sensor rate", channel=label)


def _sensor_counts(src: Source, table: Table, col: str, name: str) -> F64:
    """The column's counts without the empty tail of a slower sensor."""
    values = table.numeric.get(col)
    if values is None:
        raise src.error(
            "column holds no numbers",
            line=table.layout.first_data_line,
            channel=name,
            expected="ADC counts",
        )
    finite = np.isfinite(values)
    n = int(np.flatnonzero(finite)[-1]) + 1 if finite.any() else 0
    if n and not finite[:n].all():
        row = int(np.flatnonzero(~finite[:n])[0])
        raise src.error(
            "empty field inside the column",
            line=table.line_of_row(row),
            channel=name,
            expected="empty fields only at the end of a slower sensor's column",
        )
    if n < 2:
        raise src.error(f"column has {n} sample(s)", channel=name, expected="at least 2")
    return values[:n]


def _to_si(src: Source, s: DatalogSensor, physical: F64, name: str) -> tuple[F64, str]:
    """Physical values in the sensor's unit -> SI (EMG in V; angles, accelerations...)."""
    unit = s.unit
    if s.kind == "emg":
        if si_scale("emg", unit) is None:
            raise src.error(f"EMG unit {unit!r}", channel=name, expected="V, mV or uV")
        return emg_to_volts(physical, unit, src=src, channel=name)
    if s.kind in ("angle", "accel", "marker"):
        scaled = si_scale(s.kind, unit)
        if scaled is None:
            raise src.error(
                f"{s.kind} unit {unit!r} is not known",
                channel=name,
                expected="an SI-convertible unit",
            )
        return physical * scaled[0], scaled[1]
    return physical, unit


def read_datalog(src: Source, opts: Options) -> Recording:
    """DataLOG export: no header, no time column, ragged columns (one rate per sensor).

    Each column is trimmed of its trailing empty fields (a slower sensor's column ends
    early), then ``counts / counts_range * physical_range`` is converted to SI. Sensors come
    from ``datalog_sensors``, else a sidecar ``<file>.json``/``<stem>.json``; with neither,
    the ``rate`` option reads every column as raw counts at that rate.
    """
    data = _pad_short_rows(src.text())
    layout = detect_layout(data, src, delimiter="\t")
    table = read_table(data, layout, src)
    sensors = list(opts.datalog_sensors) if opts.datalog_sensors else _sidecar_sensors(src)
    metadata: dict[str, Any] = {"device": "Biometrics DataLOG", "columns": layout.n_fields}
    if not sensors:
        if opts.rate is None:
            raise src.error(
                "DataLOG export states no sensor rates",
                expected="datalog_sensors=[DatalogSensor(...)], a <file>.json sidecar or rate=",
            )
        src.warn("no sensor definitions: every column read as raw counts at the rate option")
        sensors = [
            DatalogSensor(i, f"column{i + 1}", "other", opts.rate, 4000.0, "counts")
            for i in range(layout.n_fields)
        ]
    columns = table.names
    channels: dict[str, Channel] = {}
    used: set[int] = set()
    for s in sensors:
        rate = _check_sensor(src, s, layout.n_fields)
        name = unique_name(s.name or f"column{s.column + 1}", channels)
        counts = _sensor_counts(src, table, columns[s.column], name)
        physical, unit = _to_si(src, s, counts * (s.physical_range / s.counts_range), name)
        channels[name] = Channel(
            name=name,
            data=np.ascontiguousarray(physical),
            rate=rate,
            unit=unit,
            kind=s.kind,
            site=map_muscle(name) if s.kind == "emg" else None,
        )
        used.add(s.column)
    metadata["sensors"] = [
        {
            "column": s.column,
            "name": s.name,
            "kind": s.kind,
            "rate": s.rate,
            "counts_range": s.counts_range,
            "physical_range": s.physical_range,
            "unit": s.unit,
        }
        for s in sensors
    ]
    unused = [i for i in range(layout.n_fields) if i not in used and columns[i] in table.numeric]
    if unused:
        metadata["ignored_columns"] = unused
    return Recording(channels=channels, source=src.name, format="datalog_txt", metadata=metadata)
