"""``bioplan analyze``: every option changes the result and is echoed in the JSON settings.

Inputs are synthetic curls written as the files users upload (``tests/analysis/_synthetic``):
known rest/top angles, a known velocity-peak position, a 16:9 frame, EMG bursts at known times.
"""

from __future__ import annotations

import json
import os
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from app.cli import main
from tests.analysis import _synthetic as syn

RATE = 60.0
Run = Callable[..., dict[str, Any]]


@pytest.fixture(scope="module")
def files(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    d = tmp_path_factory.mktemp("cli_analyze")
    t, y = syn.elbow_curls(3, RATE)
    cycle = syn.RISE_S + syn.HOLD_S + syn.LOWER_S + syn.REST_S
    bursts = [syn.REST_S + k * cycle for k in range(3)]
    return {
        "pose": syn.write_mediapipe_csv(d / "pose.csv", y),
        "both_arms": syn.write_mediapipe_csv(d / "both.csv", y, left_elbow_deg=0.5 * y + 10),
        "emg": syn.write_emg_csv(d / "emg.csv", bursts, seconds=float(t[-1]) + 0.5),
    }


@pytest.fixture()
def run(capsys: pytest.CaptureFixture[str]) -> Run:
    def go(*args: str | Path) -> dict[str, Any]:
        code = main(["analyze", *map(str, args), "--json"])
        out = capsys.readouterr().out
        assert code == 0
        data: dict[str, Any] = json.loads(out)  # exactly one JSON object on stdout
        return data

    return go


def _lifts(data: dict[str, Any], k: int = 0) -> list[dict[str, Any]]:
    lifts: list[dict[str, Any]] = data["files"][k]["lifts"]
    return lifts


def test_frame_rate_sets_the_pose_clock(run: Run, files: dict[str, Path]) -> None:
    slow = run(files["pose"], "--frame-rate", RATE, "--image-size", *syn.IMAGE)
    fast = run(files["pose"], "--frame-rate", 2 * RATE, "--image-size", *syn.IMAGE)
    assert slow["settings"]["frame_rate_hz"] == RATE
    assert fast["settings"]["frame_rate_hz"] == 2 * RATE
    assert _lifts(fast)[1]["top_s"] == pytest.approx(_lifts(slow)[1]["top_s"] / 2, abs=0.02)


def test_image_size_undoes_the_aspect_distortion(run: Run, files: dict[str, Path]) -> None:
    true = run(files["pose"], "--frame-rate", RATE, "--image-size", *syn.IMAGE)
    raw = run(files["pose"], "--frame-rate", RATE)
    assert true["settings"]["image_size_px"] == list(syn.IMAGE)
    lo, hi = true["files"][0]["pose"]["elbow_range_deg"]
    assert (lo, hi) == pytest.approx((syn.REST_DEG, syn.TOP_DEG), abs=1.0)
    _raw_lo, raw_hi = raw["files"][0]["pose"]["elbow_range_deg"]
    assert raw_hi - syn.TOP_DEG > 5.0  # a 16:9 frame read as square stretches the angles
    assert not true["template"]["assumptions"]
    assert any("video size unknown" in a for a in raw["template"]["assumptions"])
    assert any("video size unknown" in w for w in raw["warnings"])


def test_side_picks_the_arm(run: Run, files: dict[str, Path]) -> None:
    base = ("--frame-rate", RATE, "--image-size", *syn.IMAGE)
    auto = run(files["both_arms"], *base)
    left = run(files["both_arms"], *base, "--side", "left")
    assert auto["files"][0]["pose"]["side"] == "right"  # the better visible arm
    assert left["files"][0]["pose"]["side"] == "left" and left["settings"]["side"] == "left"
    assert left["files"][0]["pose"]["elbow_range_deg"][1] == pytest.approx(
        0.5 * syn.TOP_DEG + 10, abs=1.0
    )


def test_together_joins_clocks_separate_keeps_files_apart(run: Run, files: dict[str, Path]) -> None:
    base = (files["pose"], files["emg"], "--frame-rate", RATE, "--image-size", *syn.IMAGE)
    apart = run(*base)
    joint = run(*base, "--together")
    assert apart["settings"]["session"] == "separate" and joint["settings"]["session"] == "together"
    assert len(apart["files"]) == 2 and len(joint["files"]) == 1
    # Separate trials: the pose file's 3 lifts (kinematics) and the EMG file's own 3 bursts
    # (EMG timing), each on its own clock, pooled in one template.
    assert len(_lifts(apart, 0)) == 3 and len(_lifts(apart, 1)) == 3
    assert apart["template"]["n_lifts"] == 3 and apart["template"]["emg_lifts"] == 3
    assert joint["template"]["n_lifts"] == 3 and joint["template"]["emg_lifts"] == 3
    assert all(lift["emg_peak_time_fraction"] for lift in _lifts(joint))
    assert joint["template"]["activation_order"][0] == "deltoid"


def test_offset_shifts_the_pose_onto_the_emg_clock(run: Run, files: dict[str, Path]) -> None:
    base = (files["pose"], files["emg"], "--frame-rate", RATE, "--image-size", *syn.IMAGE)
    zero = run(*base, "--together", "--offset", "0")
    later = run(*base, "--together", "--offset", "0.75")
    assert zero["settings"]["offset_s"] == 0 and later["settings"]["offset_s"] == 0.75
    for a, b in zip(_lifts(zero), _lifts(later), strict=True):
        assert b["start_s"] - a["start_s"] == pytest.approx(0.75, abs=1e-6)


def test_phase_bounds_move_the_phases(run: Run, files: dict[str, Path]) -> None:
    base = (files["pose"], "--frame-rate", RATE, "--image-size", *syn.IMAGE)
    default = run(*base)
    moved = run(*base, "--phase-bounds-deg", "60,110")
    assert moved["settings"]["phase_bounds_deg"] == [60.0, 110.0]
    assert moved["template"]["phase_bounds_deg"] == [60.0, 110.0]

    def a_end(data: dict[str, Any]) -> float:
        phase = next(p for p in _lifts(data)[0]["phases"] if p["name"] == "A")
        return float(phase["end_s"])

    assert a_end(moved) > a_end(default) + 0.05


@pytest.mark.parametrize(
    ("flag", "value", "key"),
    [("--body-mass", "95", "body_mass_kg"), ("--body-height", "1.95", "body_height_m"),
     ("--load", "20", "load_mass_kg")],
)  # fmt: skip
def test_body_and_load_change_the_energetics(
    run: Run, files: dict[str, Path], flag: str, value: str, key: str
) -> None:
    base = (files["pose"], "--frame-rate", RATE, "--image-size", *syn.IMAGE)
    default = run(*base)
    changed = run(*base, flag, value)
    assert changed["settings"][key] == float(value)
    work = [_lifts(d)[0]["energetics"]["metrics"]["pos_work"] for d in (default, changed)]
    assert work[1] > work[0] * 1.01  # heavier segments or load: more positive work


def test_emg_rate_rescales_the_emg_clock(run: Run, files: dict[str, Path]) -> None:
    stored = run(files["emg"])
    doubled = run(files["emg"], "--emg-rate", "2000")
    assert doubled["settings"]["emg_rate_hz"] == 2000.0
    assert doubled["files"][0]["emg"]["biceps"]["rate_hz"] == pytest.approx(2000.0)
    t0 = [lift["top_s"] for lift in _lifts(stored)]
    t1 = [lift["top_s"] for lift in _lifts(doubled)]
    np.testing.assert_allclose(t1, np.divide(t0, 2), atol=0.05)


def test_muscle_maps_and_exclude_drops_channels(run: Run, files: dict[str, Path]) -> None:
    default = run(files["emg"])
    mapped = run(files["emg"], "--muscle", "deltoid=triceps")
    dropped = run(files["emg"], "--exclude", "deltoid")
    assert set(default["files"][0]["emg"]) == {"biceps", "deltoid"}
    assert set(mapped["files"][0]["emg"]) == {"biceps", "triceps"}
    assert mapped["settings"]["muscle_map"] == {"deltoid": "triceps"}
    assert set(dropped["files"][0]["emg"]) == {"biceps"}
    assert dropped["settings"]["exclude_channels"] == ["deltoid"]


def test_pose_options_on_an_emg_file_are_named_not_ignored(
    run: Run, files: dict[str, Path]
) -> None:
    data = run(files["emg"], "--frame-rate", "30", "--image-size", "640", "480")
    assert "--frame-rate ignored: every file states its own timing" in data["warnings"]
    assert "--image-size ignored: no file holds image coordinates" in data["warnings"]
    # With a landmark file in the session they are used: no such warning.
    both = run(files["emg"], files["pose"], "--frame-rate", "30", "--image-size", "640", "480")
    assert not any("ignored" in w for w in both["warnings"])


def test_the_all_zero_channel_is_left_out_with_a_note(run: Run, files: dict[str, Path]) -> None:
    data = run(files["emg"])
    assert "spare" not in data["files"][0]["emg"]
    assert any("'spare'" in w for w in data["files"][0]["warnings"])


def test_emg_only_says_the_template_is_the_paper_default(run: Run, files: dict[str, Path]) -> None:
    data = run(files["emg"])
    tpl = data["template"]
    assert tpl["n_lifts"] == 0 and tpl["source"].startswith("paper default: no kinematics")
    assert any("paper's defaults" in w for w in data["warnings"])
    # EMG-only tops are the EMG's own peaks: no EMG timing against them.
    assert tpl["emg_peak_time_fraction"] == {}
    assert all(not lift["emg_peak_time_fraction"] for lift in _lifts(data))


def test_out_writes_the_template(run: Run, files: dict[str, Path], tmp_path: Path) -> None:
    from app.planning.human_template import HumanTemplate

    out = tmp_path / "template.json"
    run(files["pose"], "--frame-rate", RATE, "--image-size", *syn.IMAGE, "--out", out)
    tpl = HumanTemplate.from_json(out.read_text())
    assert tpl.peak_velocity_range_fraction == pytest.approx(syn.peak_range_fraction(), abs=0.03)


@pytest.mark.parametrize(
    ("args", "needle"),
    [
        (["--phase-bounds-deg", "90,40"], "phase bounds"),
        (["--phase-bounds-deg", "40"], "two angles"),
        (["--offset", "soon"], "--offset"),
        (["--image-size", "0", "1080"], "--image-size"),
        (["--body-mass", "-3"], "--body-mass"),
        (["--load", "-1"], "--load"),
        (["--exclude", "nosuch"], "nosuch"),
        (["--max-video-seconds", "0"], "--max-video-seconds"),
        (["--skeletons", "frames"], "--skeletons needs a video"),
    ],
)
def test_bad_options_are_one_line_exit_2(
    files: dict[str, Path], capsys: pytest.CaptureFixture[str], args: list[str], needle: str
) -> None:
    code = main(["analyze", str(files["emg"]), *args])
    err = capsys.readouterr().err.strip()
    assert code == 2 and needle in err and "\n" not in err


def test_video_without_pose_environment_is_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    video = tmp_path / "curl.mp4"
    video.write_bytes(b"\x00\x00\x00\x18ftypmp42" + bytes(64))
    monkeypatch.delenv("BIOPLAN_POSE_PYTHON", raising=False)
    monkeypatch.setenv("XDG_DATA_HOME", str(tmp_path / "nothing"))
    monkeypatch.chdir(tmp_path)  # no ./.venv-pose here
    code = main(["analyze", str(video)])
    err = capsys.readouterr().err.strip()
    assert code == 2 and "\n" not in err
    assert "--pose-python" in err and "BIOPLAN_POSE_PYTHON" in err and "pose-env" in err


def _pose_python() -> str:
    from app.recordings import RecordingError, find_pose_python

    try:
        return str(find_pose_python())
    except RecordingError:
        pytest.skip(
            "no pose environment (make test creates it; or set BIOPLAN_POSE_PYTHON /"
            " run 'bioplan pose-env')"
        )


def test_video_is_analysed_through_pose(run: Run, tmp_path: Path) -> None:
    from tests.conftest import shared_file

    video = shared_file("video_sports2d_demo/demo.mp4")
    py = _pose_python()
    data = run(video, "--pose-python", py, "--skeletons", tmp_path)
    (rec,) = data["files"]
    assert rec["format"] == "mediapipe_json" and rec["source"] == "demo.pose.json"
    assert rec["pose"]["rate_hz"] == pytest.approx(30.0)
    assert rec["pose"]["valid_fraction"] > 0.5
    # The video states its size: no aspect assumption.
    assert not data["template"]["assumptions"]
    frames = data["skeleton_frames"]
    assert 1 <= len(frames) <= 4 and all(Path(f).read_bytes()[:2] == b"\xff\xd8" for f in frames)
    assert os.path.dirname(frames[0]) == str(tmp_path)


def _fake_uv(tmp_path: Path) -> tuple[Path, Path]:
    """A stand-in ``uv`` on PATH that logs its arguments and makes ``venv`` create a python
    that exits 0 (so the import check passes), with no network."""
    log = tmp_path / "uv.log"
    bin_dir = tmp_path / "bin"
    bin_dir.mkdir()
    uv = bin_dir / "uv"
    uv.write_text(
        "#!/bin/sh\n"
        f'echo "$@" >> {log}\n'
        'if [ "$1" = venv ]; then for last; do :; done; mkdir -p "$last/bin";'
        ' printf "#!/bin/sh\\nexit 0\\n" > "$last/bin/python"; chmod +x "$last/bin/python"; fi\n'
    )
    uv.chmod(0o755)
    return bin_dir, log


def test_pose_env_creates_the_environment_with_the_given_python(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    bin_dir, log = _fake_uv(tmp_path)
    monkeypatch.setenv("PATH", f"{bin_dir}{os.pathsep}{os.environ['PATH']}")
    env = tmp_path / "pose"
    assert main(["pose-env", str(env), "--python", "/usr/bin/python3.11"]) == 0
    assert capsys.readouterr().out.strip() == str(env / "bin" / "python")
    calls = log.read_text().splitlines()
    assert calls[0] == f"venv --quiet --python /usr/bin/python3.11 {env}"
    assert "--no-deps mediapipe==0.10.21" in calls[1]
    assert "numpy<2" in calls[2] and "protobuf>=4.25,<5" in calls[2]
    # --verbose shows the installers' output: no --quiet; an existing env is not re-created.
    log.unlink()
    assert main(["pose-env", str(env), "--verbose"]) == 0
    calls = log.read_text().splitlines()
    assert len(calls) == 2 and all("--quiet" not in c for c in calls)


def test_pose_env_failure_is_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    bin_dir = tmp_path / "bin"
    bin_dir.mkdir()
    (bin_dir / "uv").write_text("#!/bin/sh\necho 'no network' >&2\nexit 1\n")
    (bin_dir / "uv").chmod(0o755)
    monkeypatch.setenv("PATH", f"{bin_dir}{os.pathsep}{os.environ['PATH']}")
    assert main(["pose-env", str(tmp_path / "pose")]) == 2
    first, error = capsys.readouterr().err.strip().splitlines()  # what runs, then one error
    assert first.startswith("creating the pose environment in")
    assert error.startswith("bioplan pose-env: error:")
    assert "no network" in error and "package index" in error
