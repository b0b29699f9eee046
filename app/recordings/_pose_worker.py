"""Pose-extraction worker: runs in the separate pose environment, never imported by BioPlan.

MediaPipe 0.10.21 (the last release whose ``solutions.pose`` ships its model inside the wheel,
so it works offline) needs numpy<2 and protobuf<5, which the main environment cannot have. So
this script imports only the standard library, numpy, cv2 and mediapipe, and talks to the main
process (``app.recordings.video``) over stdout, one JSON object per line:

- ``{"event": "start", "frames": N, "fps": F, "width": W, "height": H}``
- ``{"event": "progress", "done": i, "of": N}`` (throttled)
- ``{"event": "done", "landmarks": PATH, "frames": n, "with_pose": k, "skeletons": [PATH...],
  "persons": {"checked": [i...], "another": [i...]}}``
- ``{"event": "error", "code": CODE, "message": TEXT}`` with CODE one of ``corrupt``,
  ``too_long``, ``no_person``, ``environment``; then exit status 3.

The landmarks file is MediaPipe JSON as ``app.recordings`` reads it (``fps``, ``image_width``,
``image_height``, ``frames`` with ``timestamp_ms`` and ``pose_landmarks``). Skeleton frames are
JPEG images of a few frames with the detected skeleton drawn on them, for the user to check the
fit: ``CANDIDATES`` times as many as asked for, evenly spread, from which the main process keeps
the frames that show the tracked person well.

MediaPipe Pose follows one person. To count people, every ``CHECK_EVERY_S`` seconds the tracked
person's box is painted grey and a second, single-image Pose looks at what is left: a pose found
there is another person (``persons.another`` lists those frames, ``persons.checked`` the frames
looked at). The document's ``persons`` key carries the same.

Usage: ``python _pose_worker.py VIDEO OUT_DIR MAX_SECONDS N_SKELETON_FRAMES``
"""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path
from typing import Any, NoReturn

ERROR_EXIT = 3
#: Skeleton frames drawn per frame asked for (the main process picks among them).
CANDIDATES = 3
#: How often another person is looked for [s], and the margin around the tracked person's box
#: painted over (a fraction of the box).
CHECK_EVERY_S = 1.0 / 3.0
MASK_MARGIN = 0.15
#: Skeleton images are shrunk to at most this width [px] (they are for a web page).
SKELETON_WIDTH = 640
#: The skeleton drawn: MediaPipe Pose ids of the arm, trunk and leg segments.
BONES = (
    (11, 12), (11, 13), (13, 15), (12, 14), (14, 16), (11, 23), (12, 24), (23, 24),
    (23, 25), (25, 27), (24, 26), (26, 28),
)  # fmt: skip


def emit(**event: Any) -> None:
    sys.stdout.write(json.dumps(event) + "\n")
    sys.stdout.flush()


def fail(code: str, message: str) -> NoReturn:
    emit(event="error", code=code, message=message)
    sys.exit(ERROR_EXIT)


def landmarks_of(result: Any) -> list[dict[str, float]]:
    if result.pose_landmarks is None:
        return []
    return [
        {
            "x": float(lm.x),
            "y": float(lm.y),
            "z": float(lm.z),
            "visibility": float(lm.visibility),
            "presence": float(lm.presence),
        }
        for lm in result.pose_landmarks.landmark
    ]


def draw_skeleton(cv2: Any, image: Any, lms: list[dict[str, float]]) -> Any:
    """The frame, shrunk to SKELETON_WIDTH, with bones and joints drawn (BGR)."""
    h, w = image.shape[:2]
    scale = min(1.0, SKELETON_WIDTH / w)
    out = cv2.resize(image, (round(w * scale), round(h * scale))) if scale < 1 else image.copy()
    oh, ow = out.shape[:2]
    pts = [(round(lm["x"] * ow), round(lm["y"] * oh)) for lm in lms]
    seen = [lm["visibility"] >= 0.5 for lm in lms]
    for a, b in BONES:
        if seen[a] and seen[b]:
            cv2.line(out, pts[a], pts[b], (0, 255, 0), 2, cv2.LINE_AA)
    for k in {k for bone in BONES for k in bone}:
        if seen[k]:
            cv2.circle(out, pts[k], 4, (0, 0, 255), -1, cv2.LINE_AA)
    return out


def another_person(other: Any, rgb: Any, lms: list[dict[str, float]]) -> bool:
    """Whether a second pose is found once the tracked person's box is painted grey."""
    h, w = rgb.shape[:2]
    xs = [min(max(lm["x"], 0.0), 1.0) for lm in lms]
    ys = [min(max(lm["y"], 0.0), 1.0) for lm in lms]
    mx, my = MASK_MARGIN * (max(xs) - min(xs)), MASK_MARGIN * (max(ys) - min(ys))
    x0, x1 = max(0, int((min(xs) - mx) * w)), min(w, int((max(xs) + mx) * w) + 1)
    y0, y1 = max(0, int((min(ys) - my) * h)), min(h, int((max(ys) + my) * h) + 1)
    masked = rgb.copy()
    masked[y0:y1, x0:x1] = 127
    return other.process(masked).pose_landmarks is not None


def open_video(cv2: Any, path: str, max_seconds: float) -> tuple[Any, int, float, int, int]:
    cap = cv2.VideoCapture(path)
    if not cap.isOpened():
        fail("corrupt", "cannot be decoded as a video")
    frames = int(cap.get(cv2.CAP_PROP_FRAME_COUNT))
    fps = float(cap.get(cv2.CAP_PROP_FPS))
    width, height = int(cap.get(cv2.CAP_PROP_FRAME_WIDTH)), int(cap.get(cv2.CAP_PROP_FRAME_HEIGHT))
    if frames < 2 or not 0 < fps < 1000 or width < 2 or height < 2:
        fail("corrupt", f"has no readable video stream ({frames} frames at {fps:g} fps)")
    if frames / fps > max_seconds:
        fail("too_long", f"lasts {frames / fps:.1f} s, longer than the limit of {max_seconds:g} s")
    return cap, frames, fps, width, height


def main(argv: list[str]) -> None:
    video, out_dir, max_seconds, n_skeletons = argv[0], Path(argv[1]), float(argv[2]), int(argv[3])
    try:
        import cv2
        import mediapipe as mp
    except ImportError as exc:
        fail("environment", f"the pose environment cannot import {exc.name}: {exc}")
    cap, total, fps, width, height = open_video(cv2, video, max_seconds)
    emit(event="start", frames=total, fps=fps, width=width, height=height)
    # Skeleton frames near evenly spaced targets: the first frame with a pose at or after each.
    n_targets = CANDIDATES * n_skeletons
    pending = sorted({round(k * (total - 1) / max(n_targets - 1, 1)) for k in range(n_targets)})
    frames: list[dict[str, Any]] = []
    skeletons: list[str] = []
    persons: dict[str, list[int]] = {"checked": [], "another": []}
    every = max(1, round(CHECK_EVERY_S * fps))
    last = 0.0
    tracker = mp.solutions.pose.Pose(
        static_image_mode=False,
        model_complexity=1,
        min_detection_confidence=0.5,
        min_tracking_confidence=0.5,
    )
    # A second, single-image Pose (no tracking) looks for another person; Python 3.9 has no
    # parenthesised with-statement.
    single = mp.solutions.pose.Pose(
        static_image_mode=True, model_complexity=1, min_detection_confidence=0.5
    )
    with tracker as pose, single as other:
        while True:
            ok, image = cap.read()
            if not ok:
                break
            i = len(frames)
            if (i + 1) / fps > max_seconds:
                fail("too_long", f"runs past the limit of {max_seconds:g} s")
            rgb = cv2.cvtColor(image, cv2.COLOR_BGR2RGB)
            lms = landmarks_of(pose.process(rgb))
            frames.append({"frame": i, "timestamp_ms": 1000.0 * i / fps, "pose_landmarks": [lms]})
            if lms and i % every == 0:
                persons["checked"].append(i)
                if another_person(other, rgb, lms):
                    persons["another"].append(i)
            if lms and pending and i >= pending[0]:
                pending.pop(0)
                path = out_dir / f"skeleton_{i:06d}.jpg"
                cv2.imwrite(str(path), draw_skeleton(cv2, image, lms))
                skeletons.append(str(path))
            now = time.monotonic()
            if now - last > 0.1:
                emit(event="progress", done=i + 1, of=max(total, i + 1))
                last = now
    if len(frames) < 2:
        fail("corrupt", f"has {len(frames)} decodable frame(s)")
    with_pose = sum(bool(f["pose_landmarks"][0]) for f in frames)
    if with_pose == 0:
        fail("no_person", f"no person detected in any of its {len(frames)} frames")
    for f in frames:
        if not f["pose_landmarks"][0]:
            f["pose_landmarks"] = []
    landmarks = out_dir / "landmarks.json"
    doc = {
        "fps": fps,
        "image_width": width,
        "image_height": height,
        "persons": persons,
        "frames": frames,
    }
    landmarks.write_text(json.dumps(doc), encoding="utf-8")
    emit(event="progress", done=len(frames), of=len(frames))
    emit(
        event="done",
        landmarks=str(landmarks),
        frames=len(frames),
        with_pose=with_pose,
        skeletons=skeletons,
        persons=persons,
    )


if __name__ == "__main__":
    main(sys.argv[1:])
