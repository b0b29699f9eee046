"""Video to pose: frames per second of ``extract_pose`` on the shared demo video.

Run:  .venv/bin/python benchmarks/bench_pose.py [--video PATH] [--repeats 3] [--json]

The video is the shared Sports2D demo (230 frames, 30 fps, 1768 x 994 px). Timed, median of
``--repeats`` fresh runs: the whole :func:`app.recordings.extract_pose` call (start of the
worker in the pose environment, MediaPipe model load, decoding, pose on every frame, the
landmarks file and 4 skeleton frames), as frames / wall seconds; and the worker's own frame
rate from its progress events after the first frame (model load excluded); and frames per
CPU second of the worker (user + system time of the child process), which a busy machine does
not lower: the frame rate the machine gives when it is otherwise idle. Target: 15 frames
per second or more on the 2-core machine. Needs the pose environment (``make pose-env``, or
``BIOPLAN_POSE_PYTHON``).
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import statistics
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

DEFAULT_VIDEO = Path(__file__).resolve().parents[2] / "shared/data/video_sports2d_demo/demo.mp4"


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--video", type=Path, default=DEFAULT_VIDEO)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    args = parser.parse_args()

    from app.progress import Progress
    from app.recordings import extract_pose, find_pose_python

    py = find_pose_python()
    whole, steady, per_cpu, frames, with_pose = [], [], [], 0, 0
    for _ in range(args.repeats):
        marks: list[tuple[float, int]] = []

        def on_progress(update: Progress, marks: list[tuple[float, int]] = marks) -> None:
            marks.append((time.perf_counter(), update.done))

        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        start = time.perf_counter()
        x = extract_pose(args.video, pose_python=py, progress=on_progress)
        total = time.perf_counter() - start
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
        cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
        frames, with_pose = x.frames, x.frames_with_pose
        whole.append(frames / total)
        per_cpu.append(frames / cpu)
        (t0, d0), (t1, d1) = marks[0], marks[-1]
        if t1 > t0:
            steady.append((d1 - d0) / (t1 - t0))
    out = {
        "machine": {"cpus": os.cpu_count(), "load": os.getloadavg()[0]},
        "video": args.video.name,
        "frames": frames,
        "frames_with_pose": with_pose,
        "fps_whole_call": statistics.median(whole),
        "fps_after_first_frame": statistics.median(steady) if steady else None,
        "frames_per_cpu_second": statistics.median(per_cpu),
        "target_fps": 15.0,
    }
    if args.json:
        print(json.dumps(out, indent=2))
        return 0
    m = out["machine"]
    print(f"machine: {m['cpus']} CPUs, load {m['load']:.2f}; median of {args.repeats}")
    print(
        f"{args.video.name}: {frames} frames, pose in {with_pose}; "
        f"{out['fps_whole_call']:.1f} frames/s for the whole call, "
        f"{out['fps_after_first_frame'] or float('nan'):.1f} frames/s after the first frame"
        f"; {out['frames_per_cpu_second']:.1f} frames per CPU second of the worker (target >= 15)"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
