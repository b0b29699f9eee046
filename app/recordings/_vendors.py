"""Delsys (EMGworks and Trigno CSV exports) and Qualisys (QTM TSV exports) readers.

Delsys exports give every signal its own time column: a header row ``X[s],<signal>,X[s],
<signal>,...`` (EMGworks: ``R BICEPS BRACHII: EMG 1``; Trigno Discover: ``EMG 1 (mV)`` under a
row of sensor labels such as ``Biceps R (81728)``; Trigno Discover 2.x: ``EMG 1 Time Series
(s),EMG 1 (mV),ACC X Time Series (s),ACC X (G)`` with a ``sensor mode:`` row above and a rate row
``, 1259.2593 Hz, ...`` and a period row below), preceded by ``Application:``/``Date`` lines and
``Key: value`` rows (``Stop Trigger Method: None``) that are metadata, never labels; slower
signals (accelerometers) end earlier, so their columns have empty tails. The user's muscle
labels are kept in the channel names (``Biceps R: EMG 1``) and mapped to sites.

Qualisys Track Manager TSV exports start with ``KEY<TAB>value`` header lines
(``NO_OF_FRAMES``, ``FREQUENCY``, ``MARKER_NAMES``... for 3D data; ``NO_OF_CHANNELS``,
``CHANNEL_NAMES`` for analog data), optionally a ``Frame<TAB>Time<TAB>LSHO X...`` or
``SAMPLE<TAB>TIME<TAB>...`` column row, then numbers. Markers are in mm; a marker at exactly
(0, 0, 0) is missing (older QTM versions write zeros for gaps).
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
    rate_from_times,
    scalar_channel,
    split_unit,
    unique_name,
)
from app.recordings._table import decode
from app.recordings.types import Channel, Recording

#: A Delsys time column: ``X[s]`` (EMGworks, Trigno Discover 1.x) or ``EMG 1 Time Series (s)``
#: (Trigno Discover 2.x, one per signal).
_DELSYS_TIME = re.compile(r"^\s*\"?(x\s*\[s\]|[^,;\t]*\btime series\s*\(s\))\"?\s*$", re.IGNORECASE)
#: Metadata cells above the column names: ``Stop Trigger Method: None``, ``sensor mode: 65``,
#: ``1259.2593 Hz``, ``0.000794 s``; never sensor labels.
_DELSYS_META_CELL = re.compile(r"^[^:]+:\s*\S|:$|^[-+\d.,eE]+\s*(hz|s)?$", re.IGNORECASE)
_SERIAL = re.compile(r"\s*\(\d+\)\s*$")


def _fields(line: str, delimiter: str) -> list[str]:
    return [f.strip().strip('"').strip() for f in line.split(delimiter)]


def _numbers(data: bytes, skip: int, n_cols: int, delimiter: str, decimal: str) -> F64:
    """(rows, n_cols) floats of the data block after ``skip`` lines; empty cells are NaN."""
    import pyarrow as pa
    from pyarrow import csv as pacsv

    text = data
    if decimal == ",":
        text = data.replace(b",", b".")
    names = [f"c{i}" for i in range(n_cols)]
    table = pacsv.read_csv(
        io.BytesIO(text),
        read_options=pacsv.ReadOptions(skip_rows=skip, column_names=names),
        parse_options=pacsv.ParseOptions(delimiter=delimiter, invalid_row_handler=lambda r: "skip"),
        convert_options=pacsv.ConvertOptions(
            column_types=dict.fromkeys(names, pa.float64()),
            include_columns=names,
            include_missing_columns=True,
            # Trigno Discover 2.x writes ", " between cells: a blank cell is empty
            null_values=["", " ", "  ", "NaN", "nan", "NA", "N/A"],
        ),
    )
    return np.column_stack(
        [table.column(n).to_numpy(zero_copy_only=False).astype(np.float64) for n in names]
    )


# ---------------------------------------------------------------------------------------------
# Delsys


def sniff_delsys(texts: list[str]) -> bool:
    """True when a line starts with a Delsys time column (``X[s]``, ``... Time Series (s)``)."""
    for t in texts[:40]:
        for delim in (",", ";", "\t"):
            first = t.split(delim, 1)[0]
            if delim in t and _DELSYS_TIME.match(first):
                return True
    return False


def _delsys_layout(src: Source, lines: list[str]) -> tuple[int, str, list[str], list[str]]:
    """(header line index, delimiter, header fields, sensor label of each column)."""
    for i, line in enumerate(lines):
        for delim in (",", ";", "\t"):
            if delim in line and _DELSYS_TIME.match(line.split(delim, 1)[0]):
                header = _fields(line, delim)
                return i, delim, header, _sensor_labels(lines[max(0, i - 4) : i], delim, header)
    raise src.error("has no Delsys 'X[s]' header row", expected="a Delsys EMGworks/Trigno CSV")


def _sensor_labels(above: list[str], delim: str, header: list[str]) -> list[str]:
    """Trigno Discover puts each sensor's label over its first column (``Biceps R (81728)``)
    and leaves the sensor's other columns empty: fill forward. ``Key:`` rows are metadata."""
    for line in above[::-1]:
        row = _fields(line, delim)
        cells = [c for c in row if c]
        if not cells or any(_is_num(c) or _DELSYS_META_CELL.search(c) for c in cells):
            continue
        if any(c.lower().startswith(("sensor mode", "application", "date")) for c in cells):
            continue
        out, current = [], ""
        for k in range(len(header)):
            current = (row[k] if k < len(row) else "") or current
            out.append(current)
        return out
    return [""] * len(header)


def _is_num(text: str) -> bool:
    try:
        float(text.replace(",", "."))
    except ValueError:
        return False
    return True


def _delsys_name(label: str, signal: str) -> tuple[str, str | None]:
    name, unit = split_unit(signal)
    label = _SERIAL.sub("", label).strip()
    if label and label.lower() not in name.lower():
        name = f"{label}: {name}"
    return name, unit


def _stated_rates(rows: list[str], delim: str, n: int) -> list[float | None]:
    """Per column, the rate of a Trigno Discover 2.x rate row (``, 1259.2593 Hz, , ...``)."""
    for line in rows:
        cells = _fields(line, delim)
        if any(re.fullmatch(r"[-+\d.eE]+\s*hz", c, re.IGNORECASE) for c in cells):
            out: list[float | None] = []
            for k in range(n):
                m = re.fullmatch(r"([-+\d.eE]+)\s*hz", cells[k] if k < len(cells) else "", re.I)
                out.append(float(m.group(1)) if m and _is_num(m.group(1)) else None)
            return out
    return [None] * n


def _stated_rate(src: Source, name: str, stated: float, from_times: float) -> float:
    """The header's rate (more digits than the rounded time column) when the times agree."""
    if abs(stated - from_times) <= 0.01 * from_times:
        return check_rate(stated, src=src, what="stated rate", channel=name)
    src.warn(
        f"channel {name!r}: stated rate {stated:g} Hz disagrees with its time column"
        f" ({from_times:.6g} Hz); the time column is used"
    )
    return from_times


def read_delsys(src: Source, opts: Options) -> Recording:
    """Delsys EMGworks / Trigno Discover CSV export (one time column per signal)."""
    del opts
    data = src.text()
    lines = decode(data[: 1 << 16]).splitlines()
    h, delim, header, labels = _delsys_layout(src, lines)
    first = next(
        (k for k in range(h + 1, len(lines)) if _is_num(_fields(lines[k], delim)[0] or "x")),
        None,
    )
    if first is None:
        raise src.error("has no data rows", line=h + 2, expected="numbers under the header")
    decimal = "," if delim == ";" and "," in lines[first] else "."
    block = _numbers(data, first, len(header), delim, decimal)
    stated = _stated_rates(lines[h + 1 : first], delim, len(header))
    channels: dict[str, Channel] = {}
    for k in range(0, len(header) - 1, 2):
        if not _DELSYS_TIME.match(header[k]) or not header[k + 1]:
            continue
        name, unit = _delsys_name(labels[k + 1], header[k + 1])
        keep = np.isfinite(block[:, k]) & np.isfinite(block[:, k + 1])
        t, v = block[keep, k], block[keep, k + 1]
        if t.size < 2:
            continue
        rate, start, times = rate_from_times(t, src=src, channel=name, first_line=first + 1)
        said = stated[k + 1]
        if times is None and said is not None:
            rate = _stated_rate(src, name, said, rate)
        # The signal part says what the sensor measures ("EMG 1", "ACC X 1"); the muscle
        # label in front would make an accelerometer on the biceps look like EMG.
        kind = classify(split_unit(header[k + 1])[0].split(":")[-1], unit)
        if kind == "other":
            kind = classify(name, unit)
        if kind == "emg" and unit is None:
            unit = "V"  # EMGworks exports volts without saying so
        name = unique_name(name, channels)
        channels[name] = scalar_channel(
            name, v, rate=rate, unit=unit, kind=kind, src=src, start=start, time=times
        )
    if not channels:
        raise src.error("has no signal columns", line=h + 1, expected="X[s],<signal> pairs")
    meta: dict[str, Any] = {"preamble": [ln for ln in lines[:h] if ln.strip(" ,;\t")][:20]}
    return Recording(channels=channels, source=src.name, format="delsys_csv", metadata=meta)


# ---------------------------------------------------------------------------------------------
# Qualisys


_QTM_FIRST_KEYS = (
    "NO_OF_FRAMES",
    "NO_OF_CHANNELS",
    "NO_OF_CAMERAS",
    "NO_OF_MARKERS",
    "NO_OF_SAMPLES",
    "TOT_NO_OF_CHAN",
    "FILE_VERSION",
)
_QTM_KEY = re.compile(r"^[A-Z][A-Z0-9_]*$")


def sniff_qualisys(texts: list[str]) -> bool:
    """A QTM TSV export: ``KEY<TAB>value`` lines first (3D: ``NO_OF_FRAMES``...; analog:
    ``TOT_NO_OF_CHAN``/``NO_OF_SAMPLES``, ``FREQUENCY``, ``NO_OF_CHANNELS``, ``CHANNEL_NAMES``)."""
    lines = [t for t in texts[:40] if t.strip()]
    if not lines or "\t" not in lines[0]:
        return False
    keys = []
    for t in lines:
        key = t.split("\t", 1)[0].strip()
        if not _QTM_KEY.match(key):
            break
        keys.append(key)
    if not keys or keys[0] not in _QTM_FIRST_KEYS:
        return False
    if keys[0] in _QTM_FIRST_KEYS[:4]:
        return True
    return "FREQUENCY" in keys and any(
        k in keys for k in ("NO_OF_CHANNELS", "CHANNEL_NAMES", "MARKER_NAMES")
    )


def _qualisys_header(src: Source, lines: list[str]) -> tuple[dict[str, list[str]], int, bool]:
    """(KEY -> values, index of the first data line, whether a column-name row precedes it)."""
    header: dict[str, list[str]] = {}
    for i, line in enumerate(lines):
        fields = line.rstrip("\r\n").split("\t")
        key = fields[0].strip()
        if key.upper() in ("FRAME", "SAMPLE"):
            return header, i + 1, True
        if _is_num(key):
            return header, i, False
        if key:
            header[key.upper()] = [f.strip() for f in fields[1:]]
    raise src.error("has no data rows", expected="a Qualisys TSV export with data")


def _qualisys_rate(src: Source, header: dict[str, list[str]], key: str) -> float:
    value = (header.get(key) or [""])[0]
    try:
        return check_rate(float(value), src=src, what=key)
    except ValueError:
        raise src.error(f"has no valid {key}", expected=f"{key}<TAB>rate in Hz") from None


def read_qualisys(src: Source, opts: Options) -> Recording:
    """Qualisys Track Manager TSV export: 3D markers (mm) or analog channels (EMG in V)."""
    del opts
    data = src.text()
    lines = decode(data[: 1 << 16]).splitlines()
    header, first, named = _qualisys_header(src, lines)
    n_cols = len(lines[first].rstrip("\r\n").split("\t")) if first < len(lines) else 0
    block = _numbers(data, first, n_cols, "\t", ".")
    block = block[np.isfinite(block).any(axis=1)]
    if len(block) < 2:
        raise src.error(f"has {len(block)} data row(s)", line=first + 1, expected="2 or more")
    if "MARKER_NAMES" in header:
        channels = _qualisys_markers(src, header, block, named)
    else:
        channels = _qualisys_analog(src, header, block, named)
    rate = next(iter(channels.values())).rate
    steps = np.diff(block[:, 1]) if named and block.shape[1] > 1 else np.zeros(0)
    if steps.size and np.median(steps) > 0:
        file_rate = 1.0 / float(np.median(steps))
        if abs(file_rate - rate) > 0.01 * rate:
            src.warn(
                f"FREQUENCY {rate:g} Hz disagrees with the TIME column ({file_rate:.6g} Hz);"
                " FREQUENCY is used"
            )
    for key in ("NO_OF_FRAMES", "NO_OF_SAMPLES"):
        declared = (header.get(key) or [""])[0]
        if _is_num(declared) and int(float(declared)) != len(block):
            src.warn(f"header says {key} {declared}, the file holds {len(block)} rows")
    meta = {k.lower(): v[0] if len(v) == 1 else v for k, v in header.items() if k != "MARKER_NAMES"}
    return Recording(channels=channels, source=src.name, format="qualisys_tsv", metadata=meta)


def _qualisys_markers(
    src: Source, header: dict[str, list[str]], block: F64, named: bool
) -> dict[str, Channel]:
    rate = _qualisys_rate(src, header, "FREQUENCY")
    names = [n for n in header["MARKER_NAMES"] if n]
    offset = 2 if named else 0  # Frame, Time
    if block.shape[1] < offset + 3 * len(names):
        raise src.error(
            f"has {block.shape[1]} columns for {len(names)} markers",
            expected=f"{offset + 3 * len(names)} columns (X, Y, Z per marker)",
        )
    start = float(block[0, 1]) if named else 0.0
    channels: dict[str, Channel] = {}
    for j, name in enumerate(names):
        xyz = block[:, offset + 3 * j : offset + 3 * j + 3].copy()
        xyz[np.all(xyz == 0.0, axis=1)] = np.nan  # QTM writes 0 0 0 for a gap
        channels[unique_name(name, channels)] = position_channel(
            name, xyz, rate=rate, unit="mm", kind="marker", src=src, start=start
        )
    return channels


def _qualisys_analog(
    src: Source, header: dict[str, list[str]], block: F64, named: bool
) -> dict[str, Channel]:
    rate = _qualisys_rate(src, header, "FREQUENCY")
    names = [n for n in header.get("CHANNEL_NAMES", []) if n]
    offset = 2 if named else 0  # SAMPLE, TIME
    if not names:
        names = [f"Analog {k + 1}" for k in range(block.shape[1] - offset)]
    start = float(block[0, 1]) if named else 0.0
    channels: dict[str, Channel] = {}
    for j, label in enumerate(names[: block.shape[1] - offset]):
        name, unit = split_unit(label)
        kind = classify(name, unit)
        channels[unique_name(name, channels)] = scalar_channel(
            name,
            block[:, offset + j],
            rate=rate,
            unit=unit or ("V" if kind == "emg" else None),
            kind=kind,
            src=src,
            start=start,
        )
    if not channels:
        raise src.error("has no analog channels", expected="CHANNEL_NAMES and data columns")
    return channels
