"""Format detection from content; the file extension only breaks ties."""

from __future__ import annotations

import re
from pathlib import Path

from app.recordings._common import to_utf8
from app.recordings._csv import sniff_vicon
from app.recordings._mediapipe import landmark_column
from app.recordings._table import detect_delimiter, head_lines, is_comment, split_fields
from app.recordings._vendors import sniff_delsys, sniff_qualisys
from app.recordings.types import RecordingError

FORMATS: tuple[str, ...] = (
    "csv",
    "noraxon_csv",
    "vicon_csv",
    "datalog_txt",
    "c3d",
    "edf",
    "mat",
    "mediapipe_csv",
    "mediapipe_json",
    "trc",
    "mot",
    "sto",
    "delsys_csv",
    "qualisys_tsv",
    "xdf",
)

SNIFF_BYTES = 1 << 16
_HDF5 = b"\x89HDF\r\n\x1a\n"
_INT = re.compile(r"^[-+]?\d+$")


#: What a user may upload, for messages about files of other formats.
SUPPORTED = (
    "one of: C3D; EDF/BDF (with BIDS _channels.tsv/_emg.json sidecars); MATLAB .mat; CSV/TSV/TXT"
    " exports (generic, Noraxon MR3, Delsys EMGworks/Trigno, Vicon, Qualisys TSV, Biometrics"
    " DataLOG); OpenSim TRC/MOT/STO; MediaPipe landmark CSV/JSON; XDF (Lab Streaming Layer);"
    " video (mp4, mov, avi)"
)
VIDEO_SUFFIXES = (".mp4", ".mov", ".avi", ".m4v", ".mkv", ".webm")


def _is_video(head: bytes) -> bool:
    """ISO media (mp4/mov: an ``ftyp`` or ``moov`` box first) or AVI (RIFF....AVI )."""
    return head[4:8] in (b"ftyp", b"moov", b"mdat", b"wide") or (
        head[:4] == b"RIFF" and head[8:12] == b"AVI "
    )


def _is_c3d(head: bytes) -> bool:
    if len(head) < 512 or head[1] != 0x50 or head[0] < 2:
        return False
    p = (head[0] - 1) * 512
    # The parameter section's 4th byte is the processor type (84 Intel, 85 DEC, 86 MIPS).
    return p + 3 >= len(head) or head[p + 3] in (84, 85, 86)


def sniff_bytes(head: bytes, filename: str) -> str:
    """The format of a file from its first bytes (at least 64 KB when the file is longer)."""
    ext = Path(filename).suffix.lower()
    if not head.strip(b"\xef\xbb\xbf \t\r\n"):
        raise RecordingError("file is empty", file=filename, expected="a recording")
    if head.startswith(b"XDF:"):
        return "xdf"
    if head[:8] == b"0       " or head[:8] == b"\xffBIOSEMI":
        return "edf"
    if head.startswith(b"MATLAB 5.0 MAT-file") or head.startswith(b"MATLAB 7.3 MAT-file"):
        return "mat"
    if head.startswith(_HDF5) or head[512:520] == _HDF5:
        return "mat"
    if _is_c3d(head):
        return "c3d"
    if head[:2] in (b"\xff\xfe", b"\xfe\xff"):  # UTF-16 text (Windows "Unicode" export)
        head = to_utf8(head[: len(head) // 2 * 2])
    if _is_video(head) or ext in VIDEO_SUFFIXES:
        raise RecordingError(
            "is a video, not a recording: its pose is extracted first (bioplan analyze VIDEO,"
            " or app.recordings.extract_pose)",
            file=filename,
            expected=SUPPORTED,
        )
    if b"\x00" in head[:4096]:
        raise RecordingError(
            "is a binary file of unknown format", file=filename, expected=SUPPORTED
        )
    lines = head_lines(head, limit=len(head))
    texts = [ln.text for ln in lines]
    first = next((t.strip() for t in texts if t.strip()), "")
    if first[:1] in "{[":
        return "mediapipe_json"
    if sniff_qualisys(texts):
        return "qualisys_tsv"
    if sniff_delsys(texts):
        return "delsys_csv"
    if first.startswith("PathFileType"):
        return "trc"
    if any(t.strip(" ,\t").lower() == "endheader" for t in texts[:80]):
        if ext in (".mot", ".sto"):
            return ext[1:]
        return "mot" if first.strip(" ,\t").lower() == "coordinates" else "sto"
    if sniff_vicon(head):
        return "vicon_csv"
    top = "\n".join(texts[:4])
    if "Noraxon" in top or (texts and '"type"' in texts[0] and '"frequency"' in texts[0]):
        return "noraxon_csv"
    content = [t for t in texts if t.strip() and not is_comment(t)]
    if not content:
        return "csv"
    delim, _ = detect_delimiter(content[-30:])
    for t in content[:20]:
        fields = split_fields(t, delim)
        if sum(landmark_column(f) is not None for f in fields) >= 6:
            return "mediapipe_csv"
        if (
            delim == ";"
            and fields
            and fields[0].lower() == "time"
            and any(re.search(r"\((u|µ|m)?V\)$", f) for f in fields)
        ):
            return "noraxon_csv"
    has_comments = any(is_comment(t) for t in texts[:10])
    if delim == "\t" and not has_comments:
        rows = [split_fields(t, "\t") for t in content[:50]]
        values = [f for row in rows for f in row if f]
        if values and all(_INT.match(v) for v in values):
            return "datalog_txt"
    return "csv"


def sniff_format(path: str | Path) -> str:
    """The format of a recording file, from its content (first bytes and lines).

    The extension is only a hint (``.mot`` vs ``.sto``); a Noraxon CSV named ``.txt`` or a
    C3D named ``.dat`` is still recognised.

    Args:
        path: file to inspect.

    Returns:
        One of ``FORMATS``.

    Raises:
        RecordingError: the file is missing, empty or of no known format.
    """
    p = Path(path)
    try:
        with p.open("rb") as fh:
            head = fh.read(SNIFF_BYTES)
    except OSError as exc:
        raise RecordingError(f"cannot be read: {exc.strerror or exc}", file=p.name) from None
    return sniff_bytes(head, p.name)
