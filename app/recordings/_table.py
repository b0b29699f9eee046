"""Delimited text tables: layout detection on the first lines, then one pyarrow parse.

Layout detection looks at the first 64 KB only (delimiter, decimal mark, header and metadata
rows); the data block is handed to ``pyarrow.csv`` in one call, so a 60 MB file parses in a
fraction of a second and no Python loop ever runs over rows. Errors name the file line.
"""

from __future__ import annotations

import csv
import re
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from app.recordings._common import F64, Source, is_blank

HEAD_BYTES = 1 << 16
BOM = b"\xef\xbb\xbf"
_NUMBER = re.compile(r"^[-+]?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?$")
_MISSING = {"nan", "na", "n/a", "null", "none", "-nan", "inf", "-inf", "+inf", "infinity"}
COMMENT_PREFIXES = ("#", "%", "//")


@dataclass
class Line:
    number: int  # 1-based line number in the file
    start: int  # byte offset of the line
    text: str  # decoded, without the line terminator


def decode(raw: bytes) -> str:
    try:
        return raw.decode("utf-8")
    except UnicodeDecodeError:
        # Windows exports (Noraxon, DataLOG) are often cp1252; latin-1 never fails.
        return raw.decode("latin-1")


def head_lines(data: bytes, *, limit: int = HEAD_BYTES) -> list[Line]:
    """Complete lines among the first ``limit`` bytes (a partial last line is dropped)."""
    head = data[:limit]
    complete = len(data) <= limit
    lines: list[Line] = []
    pos = 0
    number = 1
    while pos < len(head):
        end = head.find(b"\n", pos)
        if end < 0:
            if not complete:
                break
            end = len(head)
        raw = head[pos:end]
        if raw.endswith(b"\r"):
            raw = raw[:-1]
        start = pos
        if pos == 0 and raw.startswith(BOM):
            raw = raw[len(BOM) :]
        lines.append(Line(number, start, decode(raw)))
        pos = end + 1
        number += 1
    return lines


def split_fields(text: str, delimiter: str) -> list[str]:
    """Fields of one line, quote-aware, stripped of spaces and quotes."""
    try:
        row = next(csv.reader([text], delimiter=delimiter, quotechar='"'))
    except (csv.Error, StopIteration):
        row = text.split(delimiter)
    return [f.strip().strip('"').strip() for f in row]


def is_number(text: str, decimal: str = ".") -> bool:
    t = text.strip()
    if decimal == ",":
        t = t.replace(",", ".")
    return bool(_NUMBER.match(t)) or t.lower() in _MISSING


def to_float(text: str, decimal: str = ".") -> float | None:
    t = text.strip().strip('"')
    if decimal == ",":
        t = t.replace(",", ".")
    if not _NUMBER.match(t):
        return None
    return float(t)


def is_comment(text: str) -> bool:
    return text.lstrip().startswith(COMMENT_PREFIXES)


def _numeric_share(fields: list[str], decimal: str) -> tuple[int, int]:
    filled = [f for f in fields if f]
    return sum(is_number(f, decimal) for f in filled), len(filled)


def _is_data(fields: list[str], decimal: str) -> bool:
    num, filled = _numeric_share(fields, decimal)
    return num >= 1 and 2 * num >= filled


def detect_delimiter(texts: list[str]) -> tuple[str, str]:
    """(delimiter, decimal mark) that split ``texts`` (data-like lines) most consistently.

    A candidate must give the same field count on every line; among those, the one whose
    fields are most often numbers wins, then the one with more fields. A decimal comma is
    considered only when the delimiter is not a comma ("0,5;1,5" is two numbers).
    """
    best: tuple[float, int, str, str] | None = None
    for delim in ("\t", ";", ",", "|"):
        counts = {len(split_fields(t, delim)) for t in texts}
        if len(counts) != 1:
            continue
        n = counts.pop()
        if n < 2:
            continue
        for decimal in (".", ",") if delim != "," else (".",):
            num = filled = 0
            for t in texts:
                a, b = _numeric_share(split_fields(t, delim), decimal)
                num += a
                filled += b
            share = num / filled if filled else 0.0
            key = (share, n, delim, decimal)
            if best is None or key[:2] > best[:2]:
                best = key
    if best is not None:
        return best[2], best[3]
    # One column: a comma inside numbers is a decimal mark only if no line has a dot.
    joined = "\n".join(texts)
    if re.search(r"\d,\d", joined) and "." not in joined:
        return "\t", ","
    return ",", "."


@dataclass
class Layout:
    delimiter: str
    decimal: str
    comments: list[Line]
    preamble: list[list[str]]  # rows before the column names, split
    preamble_lines: list[Line]
    names: list[str] | None  # column names (None: no header row)
    names_line: int | None
    units: list[str] | None  # a units row under the names, when there is one
    data_offset: int  # byte offset of the first data line
    first_data_line: int  # its 1-based line number
    n_fields: int
    # columns whose values in the first 64 KB are all numbers: parsed as float64 directly
    numeric_hint: list[bool] = field(default_factory=list)


def detect_layout(data: bytes, src: Source, *, delimiter: str | None = None) -> Layout:
    """Find delimiter, decimal mark, comment/metadata rows, column names and the data start."""
    if is_blank(data):
        raise src.error("file is empty", expected="a header and rows of numbers")
    lines = head_lines(data)
    content = [ln for ln in lines if ln.text.strip() and not is_comment(ln.text)]
    if not content:
        raise src.error("has no data rows", expected="rows of numbers")
    if delimiter is None:
        # The last lines of the head are data in any file with more than a few rows.
        delimiter, decimal = detect_delimiter([ln.text for ln in content[-30:]])
    else:
        _, decimal = detect_delimiter([ln.text for ln in content[-30:]])
        if decimal == "," and delimiter == ",":
            decimal = "."
    fields = [split_fields(ln.text, delimiter) for ln in content]
    first = None
    for i, f in enumerate(fields):
        if not _is_data(f, decimal):
            continue
        follow = fields[i + 1 : i + 6]
        if all(len(g) == len(f) and _is_data(g, decimal) for g in follow):
            first = i
            break
    if first is None:
        raise src.error(
            "has no rows of numbers",
            line=content[0].number,
            expected=f"rows of numbers separated by {delimiter!r}",
        )
    n_fields = len(fields[first])
    names: list[str] | None = None
    names_line: int | None = None
    units: list[str] | None = None
    pre_end = first
    if first > 0:
        cand = fields[first - 1]
        cand_line = content[first - 1]
        trimmed = list(cand)
        while len(trimmed) > n_fields and not trimmed[-1]:
            trimmed.pop()
        if len(trimmed) == n_fields:
            names, names_line, pre_end = trimmed, cand_line.number, first - 1
            # a units row under the names row ("s, uV, deg"): names come from the row above
            above = _trimmed(fields[first - 2], n_fields) if first >= 2 else None
            if _is_units_row(trimmed) and above is not None and len(above) == n_fields:
                units = trimmed
                names, names_line, pre_end = above, content[first - 2].number, first - 2
        elif first == 1 or len(cand) < n_fields:
            # A single line right above the data that does not split like the data is a header
            # written with another delimiter.
            raise src.error(
                f"header has {len(cand)} field(s) but the data rows have {n_fields}",
                line=cand_line.number,
                expected=f"the same delimiter ({delimiter!r}) in the header and the data",
            )
    comments = [ln for ln in lines if is_comment(ln.text) and ln.number < content[first].number]
    return Layout(
        delimiter=delimiter,
        decimal=decimal,
        comments=comments,
        preamble=fields[:pre_end],
        preamble_lines=content[:pre_end],
        names=names,
        names_line=names_line,
        units=units,
        data_offset=content[first].start
        + (len(BOM) if content[first].start == 0 and data.startswith(BOM) else 0),
        first_data_line=content[first].number,
        n_fields=n_fields,
        numeric_hint=_numeric_hint(fields[first:], n_fields, decimal),
    )


_UNIT_WORDS = {
    "s",
    "sec",
    "ms",
    "v",
    "mv",
    "uv",
    "µv",
    "μv",
    "deg",
    "rad",
    "mm",
    "cm",
    "m",
    "g",
    "mg",
    "m/s^2",
    "m/s2",
    "m/s²",
    "n",
    "nm",
    "nmm",
    "n.m",
    "n*m",
    "hz",
    "%",
    "counts",
    "norm",
    "a.u.",
}


def _trimmed(row: list[str], n: int) -> list[str]:
    out = list(row)
    while len(out) > n and not out[-1]:
        out.pop()
    return out


def _is_units_row(row: list[str]) -> bool:
    filled = [f.strip().strip("()[]").lower() for f in row if f.strip()]
    return bool(filled) and all(f in _UNIT_WORDS for f in filled)


def _numeric_hint(rows: list[list[str]], n: int, decimal: str) -> list[bool]:
    hint = []
    for j in range(n):
        values = [r[j] for r in rows if len(r) == n and r[j]]
        hint.append(bool(values) and all(is_number(v, decimal) for v in values))
    return hint


def comment_values(layout: Layout) -> dict[str, str]:
    """``# Key:= value`` / ``# Key: value`` / ``# Key = value`` comment lines as a dict."""
    out: dict[str, str] = {}
    for ln in layout.comments:
        text = ln.text.lstrip().lstrip("#%/").strip()
        m = re.match(r"^(?P<k>[^:=]+?)\s*(:=|:|=)\s*(?P<v>.*)$", text)
        if m:
            out[m.group("k").strip()] = m.group("v").strip()
    return out


@dataclass
class Table:
    """Parsed data block: numeric columns as float64 (NaN where empty) and text columns."""

    src: Source
    data: bytes
    layout: Layout
    names: list[str]
    numeric: dict[str, F64] = field(default_factory=dict)
    text: dict[str, Any] = field(default_factory=dict)  # pyarrow string arrays, read lazily
    empty: list[str] = field(default_factory=list)
    n_rows: int = 0

    def line_of_row(self, row: int) -> int:
        """1-based file line of data row ``row`` (empty lines are skipped, as the parser does)."""
        pos = self.layout.data_offset
        line = self.layout.first_data_line
        seen = -1
        data = self.data
        while pos <= len(data):
            end = data.find(b"\n", pos)
            if end < 0:
                end = len(data)
            if data[pos:end].strip(b"\r"):
                seen += 1
                if seen == row:
                    return line
            pos = end + 1
            line += 1
        return line

    def finite(self, name: str, *, channel: str | None = None) -> F64:
        """A numeric column, or a RecordingError naming the first line with a missing value."""
        values = self.numeric[name]
        bad = ~np.isfinite(values)
        if bad.any():
            row = int(np.flatnonzero(bad)[0])
            raise self.src.error(
                "value is missing or not a number",
                line=self.line_of_row(row),
                channel=channel or name,
                expected="a finite number in every row",
            )
        return values


def unique_names(names: list[str]) -> list[str]:
    out: list[str] = []
    for i, n in enumerate(names):
        base = n or f"column{i + 1}"
        name = base
        k = 2
        while name in out:
            name = f"{base}#{k}"
            k += 1
        out.append(name)
    return out


def read_table(
    data: bytes,
    layout: Layout,
    src: Source,
    *,
    names: list[str] | None = None,
    end: int | None = None,
) -> Table:
    """Parse the data block of ``data`` (from ``layout.data_offset`` to ``end``) with pyarrow."""
    n = layout.n_fields
    cols = unique_names(names or layout.names or [f"column{i + 1}" for i in range(n)])
    if len(cols) != n:
        raise src.error(
            f"{len(cols)} column names for {n} data fields",
            line=layout.names_line,
            expected="one name per column",
        )
    keys = [f"c{i}" for i in range(n)]
    table, bad_rows = _parse_block(data, layout, src, keys, end)
    out = Table(src=src, data=data, layout=layout, names=cols, n_rows=table.num_rows)
    if bad_rows:
        _raise_bad_row(data, layout, src, bad_rows[0])
    for key, name in zip(keys, cols, strict=True):
        _add_column(out, name, table.column(key))
    return out


def _parse_block(
    data: bytes, layout: Layout, src: Source, keys: list[str], end: int | None
) -> tuple[Any, list[tuple[int, int, str | None]]]:
    """(pyarrow table, rows with the wrong number of fields) of the data block."""
    import pyarrow as pa
    import pyarrow.csv as pcsv

    n = len(keys)
    block = pa.py_buffer(data).slice(
        layout.data_offset, (end if end is not None else len(data)) - layout.data_offset
    )
    bad_rows: list[tuple[int, int, str | None]] = []

    def on_invalid(row: Any) -> str:
        if not bad_rows:
            bad_rows.append((row.expected_columns, row.actual_columns, row.text))
        return "skip"

    # Typing the columns that look numeric skips pyarrow's inference; a column that turns out
    # to hold text further down fails conversion and is re-read as text below.
    forced: dict[str, Any] = {
        k: pa.float64() for k, num in zip(keys, layout.numeric_hint, strict=False) if num
    }
    for _ in range(n + 1):
        bad_rows.clear()
        try:
            table = pcsv.read_csv(
                block,
                read_options=pcsv.ReadOptions(column_names=keys, block_size=1 << 22),
                parse_options=pcsv.ParseOptions(
                    delimiter=layout.delimiter,
                    quote_char='"',
                    ignore_empty_lines=True,
                    invalid_row_handler=on_invalid,
                ),
                convert_options=pcsv.ConvertOptions(
                    decimal_point=layout.decimal,
                    strings_can_be_null=True,
                    quoted_strings_can_be_null=True,
                    column_types=forced,
                ),
            )
            return table, bad_rows
        except pa.ArrowInvalid as exc:
            # A column typed from the first block meets text further down: read it as text to
            # find the exact line below.
            m = re.search(r"column #(\d+)", str(exc))
            if not m or int(m.group(1)) >= n or forced.get(keys[int(m.group(1))]) == pa.string():
                raise src.error(f"cannot be parsed: {exc}", expected="delimited numbers") from None
            forced[keys[int(m.group(1))]] = pa.string()
    raise src.error("cannot be parsed", expected="delimited numbers")  # pragma: no cover


def _raise_bad_row(
    data: bytes, layout: Layout, src: Source, bad: tuple[int, int, str | None]
) -> None:
    expected, actual, text = bad
    line = None
    if text is not None:
        at = data.find(text.encode("utf-8", "replace"), layout.data_offset)
        if at >= 0:
            line = data.count(b"\n", 0, at) + 1
    raise src.error(
        f"row has {actual} field(s), not {expected}",
        line=line,
        expected=f"{expected} fields separated by {layout.delimiter!r} in every row",
    )


_NUMBER_CELL = re.compile(r"^\s*[-+]?(\d+([.,]\d*)?|[.,]\d+)([eE][-+]?\d+)?\s*$")


def _add_column(out: Table, name: str, col: Any) -> None:
    """A parsed column into ``out``: numbers, empty, or text (mostly-numeric text is an error
    naming the first cell that is not a number)."""
    import pyarrow as pa
    import pyarrow.compute as pc

    typ = col.type
    if pa.types.is_integer(typ) or pa.types.is_floating(typ):
        arr = pc.cast(col, pa.float64()).to_numpy()
        if col.null_count:
            arr = np.where(pc.is_null(col).to_numpy(zero_copy_only=False), np.nan, arr)
        out.numeric[name] = np.ascontiguousarray(arr, dtype=np.float64)
        return
    if pa.types.is_null(typ) or col.null_count == len(col):
        out.empty.append(name)
        return
    strings = pc.cast(col, pa.string())
    looks = pc.match_substring_regex(strings, _NUMBER_CELL.pattern)
    n_num = pc.sum(looks).as_py() or 0
    n_filled = len(strings) - strings.null_count
    if n_num and 2 * n_num > n_filled:
        bad = pc.and_(pc.invert(pc.fill_null(looks, True)), pc.is_valid(strings))
        row = int(np.flatnonzero(bad.to_numpy(zero_copy_only=False))[0])
        raise out.src.error(
            f"text {strings[row].as_py()!r} in a numeric column",
            line=out.line_of_row(row),
            channel=name,
            expected="a number",
        )
    out.text[name] = strings
