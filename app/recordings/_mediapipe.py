"""MediaPipe Pose landmarks from CSV (named or indexed columns) and from JSON.

Coordinates stay MediaPipe's normalised image coordinates (unit ``"norm"``): x is divided by
the image width and y by the height, so angles computed from raw values are distorted unless
the frame is square. With ``image_size=(width, height)``, x and z are multiplied by
width/height (MediaPipe scales z like x), which puts all three in units of the image height
and makes angles true. Confidence is MediaPipe's ``visibility`` (``presence`` when there is
no visibility, 1 when neither is stored).

MediaPipe Pose follows one person; when the track jumps to someone (or something) else, the
reader says so: ``metadata["pose_track"]`` holds the persons followed, the frames where the
track switched and the tracked person's frames (see ``_pose_quality``), and a warning names
them. A video's document may state what the extraction saw of other people (``persons``:
frames checked, frames where another person was found), kept as ``metadata["persons"]``.
"""

from __future__ import annotations

import dataclasses
import json
import math
import re
from typing import Any

import numpy as np

from app.recordings._common import F64, Options, Source, check_rate, grid_rate, position_channel
from app.recordings._pose_quality import frame_ranges, identity, image_landmarks
from app.recordings._table import detect_layout, read_table
from app.recordings.types import Channel, Recording

LANDMARK_NAMES: tuple[str, ...] = (
    "nose",
    "left_eye_inner",
    "left_eye",
    "left_eye_outer",
    "right_eye_inner",
    "right_eye",
    "right_eye_outer",
    "left_ear",
    "right_ear",
    "mouth_left",
    "mouth_right",
    "left_shoulder",
    "right_shoulder",
    "left_elbow",
    "right_elbow",
    "left_wrist",
    "right_wrist",
    "left_pinky",
    "right_pinky",
    "left_index",
    "right_index",
    "left_thumb",
    "right_thumb",
    "left_hip",
    "right_hip",
    "left_knee",
    "right_knee",
    "left_ankle",
    "right_ankle",
    "left_heel",
    "right_heel",
    "left_foot_index",
    "right_foot_index",
)
_ARMS = (
    ("left_shoulder", "left_elbow", "left_wrist"),
    ("right_shoulder", "right_elbow", "right_wrist"),
)
_AXES = {
    "x": "x",
    "y": "y",
    "z": "z",
    "v": "v",
    "vis": "v",
    "visibility": "v",
    "p": "p",
    "presence": "p",
}
_NAMED = re.compile(r"^(?P<lm>[a-z_]+?)_(?P<ax>x|y|z|v|vis|visibility|presence)$")
_INDEXED = re.compile(r"^(?P<ax>x|y|z|v|vis|visibility|presence)_?(?P<id>\d{1,2})$")
_INDEXED2 = re.compile(
    r"^(?:landmark|lm|kp|point|p)?_?(?P<id>\d{1,2})_(?P<ax>x|y|z|v|vis|visibility|presence)$"
)


def landmark_column(column: str) -> tuple[str, str] | None:
    """(landmark name, axis x/y/z/v/p) for a CSV column, or None."""
    c = column.strip().lower().replace(" ", "_").replace(".", "_")
    m = _NAMED.match(c)
    if m and m.group("lm") in LANDMARK_NAMES:
        return m.group("lm"), _AXES[m.group("ax")]
    for pattern in (_INDEXED, _INDEXED2):
        m = pattern.match(c)
        if m and int(m.group("id")) < len(LANDMARK_NAMES):
            return LANDMARK_NAMES[int(m.group("id"))], _AXES[m.group("ax")]
    return None


def _image_factor(src: Source, opts: Options, metadata: dict[str, Any]) -> float:
    if opts.image_size is None:
        metadata["coordinates"] = "normalised: x / image width, y / image height"
        return 1.0
    w, h = opts.image_size
    metadata["image_size"] = [w, h]
    metadata["coordinates"] = "x and z scaled by width/height: all in units of image height"
    return w / h


def _require_arm(src: Source, found: set[str]) -> None:
    if not any(all(lm in found for lm in arm) for arm in _ARMS):
        raise src.error(
            "has no arm landmarks",
            expected="shoulder, elbow and wrist of one side (MediaPipe ids 11/13/15 or 12/14/16)",
        )


def _frame_rate(src: Source, opts: Options) -> float | None:
    value = opts.frame_rate if opts.frame_rate is not None else opts.rate
    if value is None:
        return None
    return check_rate(value, src=src, what="frame rate")


def _timing(
    src: Source,
    opts: Options,
    *,
    seconds: F64 | None,
    frames: F64 | None,
    line: int | None = None,
) -> tuple[float, float, F64 | None]:
    """(rate, start, explicit times) from timestamps, frame numbers + frame rate, or a rate."""
    fr = _frame_rate(src, opts)
    if seconds is not None:
        if not np.all(np.isfinite(seconds)) or np.any(np.diff(seconds) <= 0):
            bad = np.flatnonzero(~np.isfinite(seconds[1:]) | (np.diff(seconds) <= 0))
            raise src.error(
                f"timestamps do not increase (frame {int(bad[0]) + 1 if bad.size else 0})",
                line=line,
                expected="strictly increasing timestamps",
            )
        rate, uniform = grid_rate(seconds)
        rate = check_rate(rate, src=src, what="frame rate from the timestamps")
        return rate, float(seconds[0]), None if uniform else seconds
    if fr is None:
        raise src.error(
            "has no timestamps and no frame rate",
            expected="a time/timestamp column, or the frame_rate option",
        )
    if frames is not None:
        t = frames / fr
        if not np.all(np.isfinite(t)) or np.any(np.diff(t) <= 0):
            raise src.error("frame numbers do not increase", expected="increasing frame numbers")
        gaps = np.diff(frames) > 1.5
        if gaps.any():
            src.warn(f"{int(gaps.sum())} gap(s) in the frame numbers; times are irregular there")
        return fr, float(t[0]), None if not gaps.any() else t
    return fr, 0.0, None


def _channels(
    src: Source,
    xyz: dict[str, F64],
    conf: dict[str, F64 | None],
    *,
    rate: float,
    start: float,
    times: F64 | None,
    factor: float,
) -> dict[str, Channel]:
    out: dict[str, Channel] = {}
    for name in LANDMARK_NAMES:
        if name not in xyz:
            continue
        p = xyz[name]
        if factor != 1.0:
            p = p * np.array([factor, 1.0, factor])
        out[name] = position_channel(
            name,
            p,
            rate=rate,
            unit="norm",
            kind="landmark",
            src=src,
            confidence=conf.get(name),
            start=start,
            time=times,
        )
    return out


def read_mediapipe_csv(src: Source, opts: Options) -> Recording:
    """Landmark CSV: ``<name>_x,_y,_z,_v`` columns or ``x0,y0,...`` indexed by landmark id."""
    data = src.text()
    layout = detect_layout(data, src)
    table = read_table(data, layout, src)
    if table.n_rows < 2:
        raise src.error(
            f"has {table.n_rows} frame(s)",
            line=layout.first_data_line,
            expected="at least 2 frames",
        )
    parts: dict[str, dict[str, F64]] = {}
    seconds = frames = None
    for column, values in table.numeric.items():
        lm = landmark_column(column)
        if lm is not None:
            parts.setdefault(lm[0], {})[lm[1]] = values
            continue
        c = column.strip().lower()
        if c in ("timestamp_ms", "time_ms", "ms"):
            seconds = table.finite(column) / 1000.0
        elif c in ("time", "t", "time_s", "seconds", "timestamp"):
            seconds = table.finite(column)
            if c == "timestamp" and values.size > 1 and float(np.median(np.diff(values))) >= 1.0:
                seconds = seconds / 1000.0  # MediaPipe timestamps are milliseconds
        elif c in ("frame", "frame_index", "frame_idx", "frame_number", "frame#"):
            frames = table.finite(column)
    complete = {k: v for k, v in parts.items() if "x" in v and "y" in v}
    _require_arm(src, set(complete))
    metadata: dict[str, Any] = {"frames": table.n_rows, "landmark_set": "MediaPipe Pose (33)"}
    factor = _image_factor(src, opts, metadata)
    rate, start, times = _timing(
        src, opts, seconds=seconds, frames=frames, line=layout.first_data_line
    )
    xyz: dict[str, F64] = {}
    conf: dict[str, F64 | None] = {}
    for name, axes in complete.items():
        z = axes.get("z", np.zeros(table.n_rows))
        xyz[name] = np.column_stack([axes["x"], axes["y"], z])
        conf[name] = axes.get("v", axes.get("p"))
    if table.text:
        metadata["annotations"] = {k: v.to_pylist() for k, v in table.text.items()}
    channels = _channels(src, xyz, conf, rate=rate, start=start, times=times, factor=factor)
    _track_check(src, channels, metadata)
    return Recording(channels=channels, source=src.name, format="mediapipe_csv", metadata=metadata)


def _track_check(src: Source, channels: dict[str, Channel], metadata: dict[str, Any]) -> None:
    """Record (and warn) when the pose track jumps from one person to another."""
    lms = image_landmarks(channels)
    if not lms:
        return
    first = next(iter(channels.values()))
    who = identity(lms, np.asarray(first.times, dtype=np.float64))
    if not who.switches:
        return
    tracked = frame_ranges(np.flatnonzero(who.person == 0))
    metadata["pose_track"] = {
        "persons": who.n_persons,
        "switch_frames": list(who.switches),
        "tracked_frames": tracked,
    }
    shown = ", ".join(str(k) for k in who.switches[:6]) + (" ..." if len(who.switches) > 6 else "")
    src.warn(
        f"the pose track jumps to another person (or object) at frame(s) {shown}: it follows"
        f" {who.n_persons} in turn; the tracked person (most frames) is in frames {tracked},"
        " and lifts in the other frames are flagged as low pose quality"
    )


def _persons(info: dict[str, Any], metadata: dict[str, Any]) -> None:
    """What the video's extraction saw of other people (``persons`` in the document)."""
    persons = info.get("persons")
    if not isinstance(persons, dict):
        return
    checked, another = persons.get("checked"), persons.get("another")
    if isinstance(checked, list) and isinstance(another, list):
        metadata["persons"] = {
            "frames_checked": len(checked),
            "frames_with_another_person": [int(k) for k in another if isinstance(k, int)],
        }


# ---------------------------------------------------------------------------------------------
# JSON


def _frames_of(obj: Any) -> tuple[list[Any], dict[str, Any]]:
    if isinstance(obj, list):
        return obj, {}
    if isinstance(obj, dict):
        for key in ("frames", "results", "poses", "data", "detections"):
            if isinstance(obj.get(key), list):
                return obj[key], {k: v for k, v in obj.items() if k != key}
        if any(k in obj for k in ("pose_landmarks", "landmarks", "landmark")):
            return [obj], {}
    return [], {}


def _landmark_list(frame: Any) -> tuple[list[Any], bool]:
    """(landmarks of the first pose, whether there were several poses)."""
    lms: Any = frame
    if isinstance(frame, dict):
        lms = None
        for key in ("pose_landmarks", "landmarks", "landmark", "keypoints"):
            if key in frame:
                lms = frame[key]
                break
    if isinstance(lms, dict) and "landmark" in lms:
        lms = lms["landmark"]
    if not isinstance(lms, list) or not lms:
        return [], False
    first = lms[0]
    if isinstance(first, list) and first and isinstance(first[0], dict | list):
        return first, len(lms) > 1
    if isinstance(first, dict) and "landmark" in first:
        return first["landmark"] if isinstance(first["landmark"], list) else [], len(lms) > 1
    return lms, False


def _num(v: Any) -> float:
    if isinstance(v, bool) or not isinstance(v, int | float):
        return math.nan
    return float(v)


def read_mediapipe_json(src: Source, opts: Options) -> Recording:
    """Landmarks as serialised from MediaPipe's Tasks API results.

    Accepted shapes: a list of frames, or ``{"frames": [...], "image_width", "image_height",
    "fps"}``; a frame is ``{"timestamp_ms", "pose_landmarks": [[{x, y, z, visibility,
    presence} x 33], ...]}`` (``landmarks`` / ``landmark`` also accepted, a single pose list
    too, or protobuf JSON ``{"landmark": [...]}``). The first pose of each frame is used; a
    frame without a pose is a row of NaN with confidence 0. ``timestamp_ms``/``timestamp``
    are milliseconds (MediaPipe's convention), ``time`` is seconds, ``frame`` needs
    ``frame_rate``.
    """
    frames, info = _load_json(src)
    n = len(frames)
    parsed = _parse_frames(frames)
    found = {
        LANDMARK_NAMES[k]
        for k in range(len(LANDMARK_NAMES))
        if np.isfinite(parsed.pos[:, k, 0]).any()
    }
    _require_arm(src, found)
    metadata: dict[str, Any] = {"frames": n, "landmark_set": "MediaPipe Pose (33)"}
    if parsed.several:
        metadata["multi_pose_frames"] = parsed.several
        src.warn(f"{parsed.several} frame(s) hold several poses; the first pose is used")
    opts = _options_from_info(opts, info)
    factor = _image_factor(src, opts, metadata)
    stamps = parsed.stamps
    seconds = stamps if parsed.stamp_scale is not None and np.isfinite(stamps).all() else None
    if parsed.stamp_scale is not None and seconds is None:
        raise src.error("some frames have no timestamp", expected="a timestamp in every frame")
    frames_arr = parsed.frame_no if np.isfinite(parsed.frame_no).all() else None
    rate, start, times = _timing(src, opts, seconds=seconds, frames=frames_arr)
    xyz = {
        LANDMARK_NAMES[k]: parsed.pos[:, k, :]
        for k in range(len(LANDMARK_NAMES))
        if LANDMARK_NAMES[k] in found
    }
    confs: dict[str, F64 | None] = {
        LANDMARK_NAMES[k]: parsed.conf[:, k] for k in range(len(LANDMARK_NAMES))
    }
    channels = _channels(src, xyz, confs, rate=rate, start=start, times=times, factor=factor)
    _persons(info, metadata)
    _track_check(src, channels, metadata)
    return Recording(channels=channels, source=src.name, format="mediapipe_json", metadata=metadata)


def _load_json(src: Source) -> tuple[list[Any], dict[str, Any]]:
    """(frames, the document's other keys) of a MediaPipe JSON file."""
    try:
        obj = json.loads(src.text().decode("utf-8-sig"))
    except UnicodeDecodeError as exc:
        raise src.error(f"is not UTF-8 text: {exc.reason}", expected="JSON") from None
    except json.JSONDecodeError as exc:
        raise src.error(f"is not valid JSON: {exc.msg}", line=exc.lineno, expected="JSON") from None
    frames, info = _frames_of(obj)
    if len(frames) < 2:
        raise src.error(f"has {len(frames)} frame(s)", expected="a list of at least 2 frames")
    return frames, info


def _options_from_info(opts: Options, info: dict[str, Any]) -> Options:
    """The image size and frame rate the file states, unless the user gave them."""
    width = info.get("image_width", info.get("width"))
    height = info.get("image_height", info.get("height"))
    if (
        opts.image_size is None
        and isinstance(width, int)
        and isinstance(height, int)
        and width > 0
        and height > 0
    ):
        opts = dataclasses.replace(opts, image_size=(width, height))
    fps = info.get("fps", info.get("frame_rate"))
    if opts.frame_rate is None and opts.rate is None and isinstance(fps, int | float) and fps > 0:
        opts = dataclasses.replace(opts, frame_rate=float(fps))
    return opts


@dataclasses.dataclass
class _Frames:
    """Per-frame arrays of a JSON document: (n, 33, 3) positions, (n, 33) confidence,
    timestamps [s] and frame numbers (NaN where absent)."""

    pos: F64
    conf: F64
    stamps: F64
    frame_no: F64
    stamp_scale: float | None = None
    several: int = 0


_STAMP_KEYS = (("timestamp_ms", 1e-3), ("timestamp", 1e-3), ("time", 1.0), ("t", 1.0),
               ("time_s", 1.0))  # fmt: skip


def _parse_frames(frames: list[Any]) -> _Frames:
    n, k_all = len(frames), len(LANDMARK_NAMES)
    out = _Frames(
        pos=np.full((n, k_all, 3), np.nan),
        conf=np.zeros((n, k_all)),
        stamps=np.full(n, np.nan),
        frame_no=np.full(n, np.nan),
    )
    for i, frame in enumerate(frames):
        if isinstance(frame, dict):
            for key, scale in _STAMP_KEYS:
                if key in frame:
                    out.stamps[i] = _num(frame[key]) * scale
                    out.stamp_scale = scale
                    break
            for key in ("frame", "frame_index", "frame_idx"):
                if key in frame:
                    out.frame_no[i] = _num(frame[key])
                    break
        lms, multi = _landmark_list(frame)
        out.several += multi
        for j, lm in enumerate(lms[:k_all]):
            parsed = _landmark(lm, j)
            if parsed is not None:
                k, x, y, z, c = parsed
                out.pos[i, k] = (x, y, z)
                out.conf[i, k] = c if math.isfinite(c) else 0.0
    return out


def _landmark(lm: Any, j: int) -> tuple[int, float, float, float, float] | None:
    """(landmark index, x, y, z, confidence) of one landmark (a dict or a list)."""
    if isinstance(lm, dict):
        k = j
        name = lm.get("name")
        if isinstance(name, str) and name.lower() in LANDMARK_NAMES:
            k = LANDMARK_NAMES.index(name.lower())
        c = _num(lm.get("visibility", lm.get("presence", 1.0)))
        return k, _num(lm.get("x")), _num(lm.get("y")), _num(lm.get("z", 0.0)), c
    if isinstance(lm, list) and len(lm) >= 2:
        z = _num(lm[2]) if len(lm) > 2 else 0.0
        c = _num(lm[3]) if len(lm) > 3 else 1.0
        return j, _num(lm[0]), _num(lm[1]), z, c
    return None
