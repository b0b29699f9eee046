"""``bioplan analyze``: recordings of lifts in, lifts, phases, onsets and a human template out;
``bioplan pose-env``: create the separate environment that turns videos into pose."""

from __future__ import annotations

import argparse
import json
import math
import os
import shutil
import subprocess
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from app.analysis.pipeline import AnalysisOptions
from app.cli._common import (
    CliError,
    add_json_args,
    add_options,
    finite,
    floats,
    options_from_args,
    positive,
    progress_printer,
    write_out,
)
from app.jsonsafe import json_safe
from app.names import MAX_VIDEO_SECONDS, PHASE_BOUNDS_DEG


def _muscle_map(pairs: Sequence[str] | None) -> dict[str, str] | None:
    if not pairs:
        return None
    out: dict[str, str] = {}
    for pair in pairs:
        label, sep, site = pair.partition("=")
        if not sep or not label or not site:
            raise CliError(f"--muscle expects LABEL=SITE (e.g. 'Biceps.EMG4=biceps'), got {pair!r}")
        out[label] = site
    return out


def _offset(text: str | None) -> float | str | None:
    if text is None or text == "auto":
        return text
    return finite(
        text,
        not_number=f"--offset expects seconds or 'auto', got {text!r}",
        not_finite=f"--offset must be finite, got {text!r}",
    )


def _bounds(text: str) -> tuple[float, float]:
    values = floats(text, "phase-bounds-deg")
    if len(values) != 2:
        raise CliError(f"--phase-bounds-deg expects two angles A/B,B/C, got {text!r}")
    return values[0], values[1]


def _image_size(values: Sequence[int] | None) -> tuple[int, int] | None:
    if values is None:
        return None
    w, h = values
    if w <= 0 or h <= 0:
        raise CliError(f"--image-size expects a width and height > 0 in pixels, got {w} {h}")
    return (w, h)


def _pose_from_videos(args: argparse.Namespace, files: list[str]) -> tuple[list[Any], list[str]]:
    """Recordings of the files, videos turned into pose first; and what was written."""
    from app.recordings import extract_pose, is_video, read_recording, save_skeletons

    recordings: list[Any] = []
    written: list[str] = []
    show = progress_printer(not args.json)
    for f in files:
        if is_video(f):
            extraction = extract_pose(
                f,
                pose_python=args.pose_python,
                max_seconds=args.max_video_seconds,
                skeleton_frames=4 if args.skeletons else 0,
                progress=show,
            )
            recordings.append(extraction.recording())
            if args.skeletons:
                written += [str(p) for p in save_skeletons(extraction, args.skeletons)]
        else:
            recordings.append(
                read_recording(
                    f,
                    emg_rate=args.emg_rate,
                    muscle_map=_muscle_map(args.muscle),
                    frame_rate=args.frame_rate,
                    image_size=_image_size(args.image_size),
                )
            )
    return recordings, written


def _unused_pose_options(args: argparse.Namespace, recordings: list[Any]) -> list[str]:
    """Warnings for --frame-rate / --image-size when no file could use them (only MediaPipe
    landmark files lack a frame rate or an image size; a session's EMG file ignores them)."""
    if any(str(r.format).startswith("mediapipe") for r in recordings):
        return []
    out = []
    if args.frame_rate is not None:
        out.append("--frame-rate ignored: every file states its own timing")
    if args.image_size is not None:
        out.append("--image-size ignored: no file holds image coordinates")
    return out


#: The ``AnalysisOptions`` whose flags are written here by hand, as the command line takes them
#: in another form than the field (for each: its flags; none: the CLI does not offer it).
#: Every other field is a flag made from the field (``add_options``).
HAND_MADE: dict[str, tuple[str, ...]] = {
    "muscle_map": ("--muscle",),  # repeated LABEL=SITE, not one mapping
    "exclude_channels": ("--exclude",),  # repeated, one channel each
    "bounds": ("--phase-bounds-deg",),  # "A/B,B/C" in degrees; the field is in radians
    "offset": ("--offset",),  # seconds or 'auto' in one text
    "pose_options": ("--side", "--landmarks"),  # two of arm_angles' options
    "emg_options": (),  # library only: emg_process's filter settings
}


def _pose_options(args: argparse.Namespace) -> dict[str, Any]:
    """The options of :func:`app.analysis.arm_angles` that --side and --landmarks give."""
    pose: dict[str, Any] = {}
    if args.side != "auto":
        pose["side"] = args.side
    if args.landmarks:
        from app.analysis.pose import landmark_spec

        landmark_spec(args.landmarks)  # an unknown preset or a malformed mapping stops here
        pose["landmarks"] = args.landmarks
    return pose


def analysis_options(args: argparse.Namespace) -> AnalysisOptions:
    """Every option of the analysis from the flags: the fields made into flags as they are,
    the :data:`HAND_MADE` ones read from their flags here.

    Raises:
        CliError: a value out of its range or malformed, naming the flag.
    """
    made = options_from_args(AnalysisOptions, args, exclude=tuple(HAND_MADE))
    return made.replace(
        muscle_map=_muscle_map(args.muscle),
        exclude_channels=frozenset(args.exclude or ()),
        bounds=tuple(math.radians(b) for b in _bounds(args.phase_bounds_deg)),
        offset=_offset(args.offset),
        pose_options=_pose_options(args),
    )


def _settings(args: argparse.Namespace) -> dict[str, Any]:
    """Keyword options of :func:`app.analysis.analyze_recordings` from the flags."""
    options = analysis_options(args)
    if args.frame_rate is not None:
        positive("frame-rate", args.frame_rate)
    positive("max-video-seconds", args.max_video_seconds)
    return {
        # Every analysis option under its own name; the phase bounds as given, in degrees.
        **{name: getattr(options, name) for name in options.names() if name != "bounds"},
        "phase_bounds_deg": _bounds(args.phase_bounds_deg),
        "body_mass": positive("body-mass", args.body_mass),
        "body_height": positive("body-height", args.body_height),
        "load_mass": args.load,
        "together": args.together,
    }


def cmd_analyze(args: argparse.Namespace) -> int:
    from app.analysis import analyze_recordings
    from app.recordings import is_video

    for f in args.files:
        if not Path(f).is_file():
            raise CliError(f"{f}: no such file")
    if args.load < 0 or not math.isfinite(args.load):
        raise CliError(f"--load must be a mass >= 0 kg, got {args.load}")
    if args.skeletons and not any(is_video(f) for f in args.files):
        raise CliError("--skeletons needs a video (mp4, mov, avi) among the files")
    options = _settings(args)
    recordings, skeletons = _pose_from_videos(args, list(args.files))
    result = analyze_recordings(recordings, **options)
    result.warnings.extend(_unused_pose_options(args, recordings))
    result.settings["frame_rate_hz"] = args.frame_rate
    result.settings["image_size_px"] = list(args.image_size) if args.image_size else None
    result.settings["side"] = args.side
    payload = json_safe(result.to_dict())
    if skeletons:
        payload["skeleton_frames"] = skeletons
    if args.plot:
        from app.analysis import write_analysis_plots

        paths = write_analysis_plots(result, Path(args.plot))
        payload["plots"] = [str(p) for p in paths]
    if args.out:
        write_out(args.out, result.template.to_json() + "\n")
    if args.json:
        print(json.dumps(payload, indent=2, allow_nan=False))
        return 0
    print(result.summary())
    for label, what in ((args.plot, "figures"), (args.skeletons, "skeleton frames")):
        if label:
            print(f"{what} written to {label}")
    if args.out:
        print(f"template written to {args.out}")
    return 0


#: CPython versions MediaPipe 0.10.21 (the pose environment's) has wheels for.
POSE_PYTHONS = ((3, 9), (3, 12))


def _pose_base_python(given: str | None) -> str:
    """The interpreter the pose environment is made from, checked: a CPython MediaPipe 0.10.21
    has wheels for (else a CliError that says what to give instead)."""
    base = (shutil.which(given) or given) if given else sys.executable
    probe = "import sys; print(sys.implementation.name, *sys.version_info[:2])"
    try:
        done = subprocess.run([base, "-c", probe], capture_output=True, text=True, timeout=60)
        name, major, minor = done.stdout.split()
        version = (int(major), int(minor))
    except (OSError, ValueError, subprocess.TimeoutExpired):
        raise CliError(f"--python {base}: not a Python interpreter that runs") from None
    (lo_major, lo_minor), (hi_major, hi_minor) = POSE_PYTHONS
    if name != "cpython" or not POSE_PYTHONS[0] <= version <= POSE_PYTHONS[1]:
        raise CliError(
            f"the pose environment needs CPython {lo_major}.{lo_minor}-{hi_major}.{hi_minor}"
            f" (MediaPipe 0.10.21 has wheels for no other), but {base} is {name} {major}.{minor}:"
            f" give --python python{hi_major}.{hi_minor} (or another in that range);"
            " everything but video works without it"
        )
    return base


def cmd_pose_env(args: argparse.Namespace) -> int:
    from app.recordings import create_pose_env, default_pose_env

    target = Path(args.dir) if args.dir else default_pose_env()
    base = _pose_base_python(args.python)
    uv = shutil.which("uv")
    tool = f"uv ({uv})" if uv else "venv + pip (uv is not on PATH)"
    pins = os.environ.get("UV_CONSTRAINT" if uv else "PIP_CONSTRAINT")
    print(
        f"creating the pose environment in {target} (MediaPipe 0.10.21) from {base} with {tool}"
        + (f", versions pinned by {pins}" if pins else "")
        + " ...",
        file=sys.stderr,
    )
    py = create_pose_env(target, python=base, quiet=not args.verbose)
    print(py)
    return 0


def register(sub: Any) -> None:
    """Add ``analyze`` and ``pose-env`` to the ``bioplan`` subcommands."""
    p = sub.add_parser("analyze", help="analyse EMG, pose and video recordings into a template")
    _add_input_arguments(p)
    _add_analysis_arguments(p)
    _add_output_arguments(p)
    p.set_defaults(handler=cmd_analyze)
    _register_pose_env(sub)


def _add_input_arguments(p: argparse.ArgumentParser) -> None:
    """``analyze``'s files and how to read them (rates, channels, landmarks, clocks)."""
    p.add_argument(
        "files",
        nargs="+",
        help="recording files (format detected from content); videos (mp4, mov, avi) are"
        " turned into pose first",
    )
    p.add_argument(
        "--muscle", action="append", default=None, metavar="LABEL=SITE", help="map a channel"
    )
    p.add_argument(
        "--exclude", action="append", default=None, metavar="CHANNEL", help="leave a channel out"
    )
    p.add_argument(
        "--frame-rate", type=float, default=None, help="pose frame rate [Hz] for files without one"
    )
    p.add_argument(
        "--image-size",
        type=int,
        nargs=2,
        default=None,
        metavar=("W", "H"),
        help="video size [px] of MediaPipe files that do not state it",
    )
    p.add_argument(
        "--side",
        choices=("auto", "left", "right"),
        default="auto",
        help="which arm (auto: the better visible one)",
    )
    p.add_argument(
        "--landmarks",
        default=None,
        metavar="PRESET|ROLE=NAME,...",
        help="which markers are the shoulder, elbow and wrist: a preset (plugin_gait_right,"
        " plugin_gait_left, opencap_right, opencap_left, pose2sim_right, pose2sim_left; without"
        " _right/_left: the better side) or 'shoulder=RSHO,elbow=RELB,wrist=RWRA' (NAME+NAME"
        " averages)",
    )
    p.add_argument(
        "--offset", default=None, help="EMG-to-pose clock offset [s], or 'auto' (cross-correlation)"
    )
    p.add_argument(
        "--together",
        action="store_true",
        help="the files were recorded at the same time (one clock); default: separate trials",
    )


def _add_analysis_arguments(p: argparse.ArgumentParser) -> None:
    """``analyze``'s analysis settings: lift quality, phases, the subject, the load and how
    videos are turned into pose (the pose environment, the longest video)."""
    # Every AnalysisOptions field but the hand-made ones (the EMG rate, keeping low-quality lifts).
    add_options(p, AnalysisOptions, exclude=tuple(HAND_MADE))
    p.add_argument(
        "--phase-bounds-deg",
        default=",".join(f"{b:g}" for b in PHASE_BOUNDS_DEG),
        help="A/B and B/C elbow angles [deg]",
    )
    p.add_argument("--body-mass", type=float, default=75.0, help="subject mass [kg]")
    p.add_argument("--body-height", type=float, default=1.75, help="subject height [m]")
    p.add_argument("--load", type=float, default=12.0, help="dumbbell mass [kg]")
    p.add_argument(
        "--pose-python",
        default=None,
        help="python of the pose environment for videos (default: $BIOPLAN_POSE_PYTHON, then"
        " the one 'bioplan pose-env' creates)",
    )
    p.add_argument(
        "--max-video-seconds",
        type=float,
        default=MAX_VIDEO_SECONDS,
        help="longest video accepted [s]",
    )


def _add_output_arguments(p: argparse.ArgumentParser) -> None:
    """``analyze``'s outputs: skeleton frames, JSON, the template file and figures."""
    p.add_argument(
        "--skeletons", default=None, metavar="DIR", help="write video frames with the skeleton"
    )
    add_json_args(p, out=False)
    p.add_argument("--out", default=None, help="write the HumanTemplate JSON here")
    p.add_argument("--plot", default=None, metavar="DIR", help="write figures into DIR")


def _register_pose_env(sub: Any) -> None:
    """Add ``pose-env``, which creates the environment that extracts pose from videos."""
    e = sub.add_parser("pose-env", help="create the environment that extracts pose from videos")
    e.add_argument(
        "dir",
        nargs="?",
        default=None,
        help="where to create it (default: $XDG_DATA_HOME/bioplan/pose-env)",
    )
    e.add_argument(
        "--python", default=None, help="interpreter to base it on (CPython 3.9-3.12; default: this)"
    )
    e.add_argument("--verbose", action="store_true", help="show the installers' output")
    e.set_defaults(handler=cmd_pose_env)
