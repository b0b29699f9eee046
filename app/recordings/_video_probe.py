"""What a video file's container says about it, read from its header in pure Python.

An upload must be refused at once (a 4xx, nothing stored) when it is not a video container
BioPlan can turn into pose, or when it is longer than the server accepts; decoding it takes the
pose environment and seconds to minutes. The container header says both in a few kilobytes:

- MP4 and QuickTime MOV (ISO base media): the ``moov`` box's ``mvhd`` (duration, time scale),
  and per track ``tkhd`` (width, height), ``mdia/hdlr`` (a ``vide`` track), ``mdia/mdhd`` and
  ``minf/stbl/stsz`` (the video track's duration and sample count, hence its frame rate);
- AVI (RIFF): the ``hdrl`` list's ``avih`` header (microseconds per frame, frames, size) and a
  ``strh`` stream header of type ``vids``.

What the header states is checked, not trusted: frames that do not decode, or a stream longer
than stated, are found by the pose worker, which enforces the same limit while it decodes.
"""

from __future__ import annotations

import struct
from collections.abc import Iterator
from dataclasses import dataclass

from app.recordings.types import RecordingError

#: How deep boxes/chunks are searched (moov/trak/mdia/minf/stbl is 5 levels).
_MAX_DEPTH = 8
_ISO_FIRST = (b"ftyp", b"moov", b"mdat", b"wide", b"free", b"skip", b"pnot")
_EXPECTED = "an mp4, mov or avi video"


@dataclass(frozen=True)
class VideoProbe:
    """A video container's own description of its video stream.

    Attributes:
        container: ``"mp4"`` (ISO base media: mp4, m4v, mov) or ``"avi"``.
        duration: stated duration [s], or None when the header does not state one
            (fragmented MP4 without a total duration).
        width, height: frame size [px], or None when not stated.
        frames: stated number of frames, or None.
        fps: frame rate [Hz] (frames / duration), or None.
    """

    container: str
    duration: float | None
    width: int | None
    height: int | None
    frames: int | None
    fps: float | None

    def to_dict(self) -> dict[str, object]:
        """JSON-ready form (``duration_s``, ``fps_hz``...)."""
        return {
            "container": self.container,
            "duration_s": self.duration,
            "width": self.width,
            "height": self.height,
            "frames": self.frames,
            "fps_hz": self.fps,
        }


def looks_like_video(head: bytes) -> bool:
    """True when the first bytes are an ISO media box or an AVI RIFF header."""
    return (len(head) >= 8 and head[4:8] in _ISO_FIRST) or (
        head[:4] == b"RIFF" and head[8:12] == b"AVI "
    )


def probe_video(data: bytes, name: str) -> VideoProbe:
    """The container's description of a video held in memory.

    Args:
        data: the whole file.
        name: the user's file name (for messages).

    Returns:
        What the header states (see :class:`VideoProbe`).

    Raises:
        RecordingError: not an MP4/MOV/AVI container, truncated, or without a video stream.
    """
    if data[:4] == b"RIFF" and data[8:12] == b"AVI ":
        return _probe_avi(data, name)
    if len(data) >= 8 and data[4:8] in _ISO_FIRST:
        return _probe_iso(data, name)
    raise RecordingError(
        "is not a video container BioPlan can read (no MP4/MOV box or AVI header)",
        file=name,
        expected=_EXPECTED,
    )


# ------------------------------------------------------------------------------- ISO media


def _boxes(data: bytes, start: int, end: int, name: str) -> Iterator[tuple[bytes, int, int]]:
    """(type, payload start, payload end) of the boxes in data[start:end]."""
    i = start
    while i + 8 <= end:
        size, kind = struct.unpack_from(">I4s", data, i)
        header = 8
        if size == 1:
            if i + 16 > end:
                break
            size = struct.unpack_from(">Q", data, i + 8)[0]
            header = 16
        elif size == 0:
            size = end - i
        if size < header or i + size > end:
            raise RecordingError(
                f"is truncated or corrupt: box {kind.decode('latin-1')!r} at byte {i} runs past"
                " the end of its container",
                file=name,
                expected=_EXPECTED,
            )
        yield kind, i + header, i + size
        i += size


def _child(data: bytes, span: tuple[int, int], path: list[bytes], name: str) -> tuple[int, int]:
    """The payload span of the first box at ``path`` below ``span``, or (0, 0)."""
    start, end = span
    for depth, kind in enumerate(path):
        if depth >= _MAX_DEPTH:
            return 0, 0
        found = next(((s, e) for k, s, e in _boxes(data, start, end, name) if k == kind), None)
        if found is None:
            return 0, 0
        start, end = found
    return start, end


def _duration(data: bytes, span: tuple[int, int]) -> tuple[int, int] | None:
    """(time scale, duration) of an ``mvhd`` or ``mdhd`` payload (version 0 or 1)."""
    start, end = span
    if end - start < 24:
        return None
    if data[start] == 1:
        if end - start < 36:
            return None
        scale, duration = struct.unpack_from(">IQ", data, start + 20)
    else:
        scale, duration = struct.unpack_from(">II", data, start + 12)
    return int(scale), int(duration)


def _seconds(value: tuple[int, int] | None) -> float | None:
    if value is None or value[0] <= 0 or value[1] <= 0 or value[1] in (0xFFFFFFFF, 2**64 - 1):
        return None
    return value[1] / value[0]


def _video_track(data: bytes, moov: tuple[int, int], name: str) -> dict[str, float | int] | None:
    """Size, duration and sample count of the first video track of ``moov``."""
    for kind, s, e in _boxes(data, *moov, name):
        if kind != b"trak":
            continue
        hdlr = _child(data, (s, e), [b"mdia", b"hdlr"], name)
        if hdlr[1] - hdlr[0] < 12 or data[hdlr[0] + 8 : hdlr[0] + 12] != b"vide":
            continue
        out: dict[str, float | int] = {}
        tkhd = _child(data, (s, e), [b"tkhd"], name)
        if tkhd[1] - tkhd[0] >= 8:
            w, h = struct.unpack_from(">II", data, tkhd[1] - 8)
            out["width"], out["height"] = w >> 16, h >> 16
        seconds = _seconds(_duration(data, _child(data, (s, e), [b"mdia", b"mdhd"], name)))
        if seconds is not None:
            out["duration"] = seconds
        stsz = _child(data, (s, e), [b"mdia", b"minf", b"stbl", b"stsz"], name)
        if stsz[1] - stsz[0] >= 12:
            out["frames"] = struct.unpack_from(">I", data, stsz[0] + 8)[0]
        return out
    return None


def _probe_iso(data: bytes, name: str) -> VideoProbe:
    # Every top-level box is walked: a file cut short shows in its last box (often ``mdat``).
    top = {kind: (s, e) for kind, s, e in reversed(list(_boxes(data, 0, len(data), name)))}
    moov = top.get(b"moov", (0, 0))
    if moov == (0, 0):
        raise RecordingError(
            "has no 'moov' box: the file is cut short or not a finished recording",
            file=name,
            expected=_EXPECTED,
        )
    track = _video_track(data, moov, name)
    if track is None:
        raise RecordingError("has no video track", file=name, expected=_EXPECTED)
    mvhd = _child(data, moov, [b"mvhd"], name)
    duration = track.get("duration") or _seconds(_duration(data, mvhd))
    frames = int(track["frames"]) if track.get("frames") else None
    return VideoProbe(
        container="mp4",
        duration=duration,
        width=int(track["width"]) if track.get("width") else None,
        height=int(track["height"]) if track.get("height") else None,
        frames=frames,
        fps=frames / duration if frames and duration else None,
    )


# ------------------------------------------------------------------------------------- AVI


def _chunks(data: bytes, start: int, end: int) -> Iterator[tuple[bytes, int, int]]:
    """(id, payload start, payload end) of RIFF chunks in data[start:end] (word aligned)."""
    i = start
    while i + 8 <= end:
        kind, size = struct.unpack_from("<4sI", data, i)
        stop = min(i + 8 + size, end)
        yield kind, i + 8, stop
        i = i + 8 + size + (size & 1)


def _probe_avi(data: bytes, name: str) -> VideoProbe:
    avih: tuple[int, int] | None = None
    has_video = False
    for kind, s, e in _chunks(data, 12, len(data)):
        if kind != b"LIST" or data[s : s + 4] != b"hdrl":
            continue
        for sub, ss, se in _chunks(data, s + 4, e):
            if sub == b"avih":
                avih = (ss, se)
            elif sub == b"LIST" and data[ss : ss + 4] == b"strl":
                strh = next(((a, b) for k, a, b in _chunks(data, ss + 4, se) if k == b"strh"), None)
                has_video |= strh is not None and data[strh[0] : strh[0] + 4] == b"vids"
        break
    if avih is None or avih[1] - avih[0] < 40:
        raise RecordingError(
            "has no AVI main header ('avih'): the file is cut short or corrupt",
            file=name,
            expected=_EXPECTED,
        )
    if not has_video:
        raise RecordingError("has no video stream", file=name, expected=_EXPECTED)
    usec, _, _, _, frames, _, _, _, width, height = struct.unpack_from("<10I", data, avih[0])
    fps = 1e6 / usec if usec else None
    return VideoProbe(
        container="avi",
        duration=frames / fps if fps and frames else None,
        width=width or None,
        height=height or None,
        frames=frames or None,
        fps=fps,
    )
