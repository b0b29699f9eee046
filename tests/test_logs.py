"""BioPlan's log (``app.logs``): the science packages' named loggers, ``set_log_level`` for a
library user, and ``bioplan -v/-vv/--quiet``."""

from __future__ import annotations

import json
import logging
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest

from app.cli import build_parser
from app.errors import BioPlanError
from app.logs import MAX_BYTES, MAX_LINES, ROOT, LogTail, capture, get_logger, set_log_level
from app.recordings import read_recording
from tests.utils.data import shared_file

NORAXON = "noraxon_curls_biceps_brachioradialis/2023-04-20-15-06_BR_posredni.csv"
#: A plan that runs in about a second: the paper's PSO on a tiny budget and the jerk-limited
#: profile, on the 2-DOF human arm.
PLAN = ("plan", "--robot", "human_arm_2dof", "--particles", "6", "--iterations", "3")


@pytest.fixture(autouse=True)
def _restore_logging() -> Iterator[None]:
    """Each test leaves the ``bioplan`` logger as it found it."""
    logger = logging.getLogger(ROOT)
    level, handlers, propagate = logger.level, list(logger.handlers), logger.propagate
    yield
    logger.setLevel(level)
    logger.handlers[:] = handlers
    logger.propagate = propagate


def run_cli(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "app.cli", *args], capture_output=True, text=True, timeout=300
    )


def _lines(stderr: str, level: str) -> list[str]:
    return [line for line in stderr.splitlines() if line.startswith(f"{level} bioplan.")]


# ------------------------------------------------------------------------------- the library


def test_set_log_level_shows_what_a_reader_decided(capsys: pytest.CaptureFixture[str]) -> None:
    """INFO names the format the reader sniffed and the channels it read, as the recording
    itself says; at WARNING the same read prints nothing."""
    path = shared_file(NORAXON)
    before = set_log_level("WARNING")
    assert before == logging.NOTSET or isinstance(before, int)
    read_recording(path)
    assert capsys.readouterr().err == ""

    import app

    assert app.set_log_level("info") == logging.WARNING  # the level it had, in any case
    rec = read_recording(path)
    err = capsys.readouterr().err
    [line] = _lines(err, "INFO")
    n_emg = len(rec.of_kind("emg"))
    assert line.startswith(f"INFO bioplan.recordings: {path.name}: read as {rec.format}")
    assert f"{n_emg} emg" in line


def test_without_our_handler_records_reach_the_application(
    caplog: pytest.LogCaptureFixture,
) -> None:
    """``handler=False``: no stderr line of BioPlan's, the records go to the application's
    handlers (here pytest's) with the package's logger name."""
    path = shared_file(NORAXON)
    set_log_level("INFO", handler=False)
    with caplog.at_level(logging.INFO, logger=ROOT):
        read_recording(path)
    names = {r.name for r in caplog.records if r.levelno == logging.INFO}
    assert names == {"bioplan.recordings"}


def test_bad_levels_and_packages_are_named() -> None:
    with pytest.raises(BioPlanError, match=r"'LOUD'.*DEBUG, INFO, WARNING"):
        set_log_level("LOUD")
    with pytest.raises(BioPlanError, match="log level True"):
        set_log_level(True)
    assert get_logger("planning").name == "bioplan.planning"
    with pytest.raises(BioPlanError, match=r"'viewer'.*planning, analysis"):
        get_logger("viewer")


def test_a_log_tail_keeps_the_last_lines_and_says_how_many_went() -> None:
    tail = LogTail()
    log = get_logger("simulation")
    with capture(tail):
        for i in range(MAX_LINES + 100):
            log.info("cell %d", i)
        log.debug("not kept: below INFO")
    log.info("not kept: after the capture")
    lines = tail.lines()
    assert len(lines) == MAX_LINES + 1
    assert "100 earlier line(s) left out" in lines[0]
    assert lines[1].endswith("INFO bioplan.simulation: cell 100")
    assert lines[-1].endswith(f"cell {MAX_LINES + 99}")
    # The lines not yet handed over are at most what is kept.
    assert len(tail.take()) == MAX_LINES and tail.take() == []


def test_a_log_tail_keeps_at_most_its_bytes() -> None:
    tail = LogTail()
    tail.extend(["x" * 999] * 100)  # 100 kB
    kept = tail.lines()
    assert sum(len(line) + 1 for line in kept[1:]) <= MAX_BYTES
    assert len(kept) - 1 == MAX_BYTES // 1000
    assert f"{100 - MAX_BYTES // 1000} earlier line(s)" in kept[0]


# ------------------------------------------------------------------------------------- the CLI


def test_verbose_plan_names_its_methods_on_stderr_and_keeps_json_pure() -> None:
    quiet = run_cli(*PLAN, "--method", "paper,jerk_limited", "--json")
    loud = run_cli("-v", *PLAN, "--method", "paper,jerk_limited", "--json")
    assert quiet.returncode == loud.returncode == 0, loud.stderr
    assert _lines(quiet.stderr, "INFO") == []
    info = _lines(loud.stderr, "INFO")
    methods = "quintic, paper, jerk_limited over 1 s, abs_work"
    assert f"INFO bioplan.planning: plan of human_arm_2dof: {methods}" in info
    assert any(
        line.startswith("INFO bioplan.planning: paper: PSO of 6 particles x 3") for line in info
    )
    assert any("jerk_limited" in line for line in info)
    assert _lines(loud.stderr, "DEBUG") == []
    # stdout is the one JSON document, the same plan with or without -v.
    a, b = json.loads(quiet.stdout), json.loads(loud.stdout)
    assert a["methods"].keys() == b["methods"].keys() == {"quintic", "paper", "jerk_limited"}
    best = b["methods"]["paper"]["solver"]["best_cost"]
    assert any(f"best abs_work = {best:.6g}" in line for line in info)


def test_a_methods_failure_is_said_with_v_and_each_step_with_vv() -> None:
    """The paper's method failing at 0.7 s (the plan goes on with the jerk-limited profile; its
    result states the failure): an INFO line with -v, nothing by default; -vv adds the PSO's
    iterations (DEBUG)."""
    args = (*PLAN, "--method", "paper,jerk_limited", "--duration", "0.7", "--json")
    default, info, debug = run_cli(*args), run_cli("-v", *args), run_cli("-vv", *args)
    for proc in (default, info, debug):
        assert proc.returncode == 0, proc.stderr
    errors = json.loads(default.stdout)["method_errors"]
    assert set(errors) == {"paper"}
    assert default.stderr == ""
    [failed] = [line for line in _lines(info.stderr, "INFO") if " failed " in line]
    assert failed == f"INFO bioplan.planning: paper failed (infeasible): {errors['paper']['error']}"
    assert _lines(info.stderr, "DEBUG") == []
    steps = [line for line in _lines(debug.stderr, "DEBUG") if "PSO iteration" in line]
    assert [s.split("iteration ")[1].split(",")[0] for s in steps] == ["1/3", "2/3", "3/3"]


def test_quiet_shows_errors_only(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """A warning and an error logged during a plan: both by default, the error only with
    --quiet; the plan's JSON on stdout either way."""
    from app.cli import main
    from app.planning import planner

    real = planner.run_jerk_limited

    def noisy(*args: object, **kwargs: object) -> object:
        get_logger("planning").warning("a degraded result")
        get_logger("planning").error("a logged error")
        return real(*args, **kwargs)  # type: ignore[arg-type]

    monkeypatch.setattr(planner, "run_jerk_limited", noisy)
    for flags, shown in (((), ["WARNING", "ERROR"]), (("--quiet",), ["ERROR"])):
        assert main([*flags, *PLAN, "--method", "jerk_limited", "--json"]) == 0
        out, err = capsys.readouterr()
        assert [line.split()[0] for line in err.splitlines()] == shown
        assert "jerk_limited" in json.loads(out)["methods"]


def test_the_global_flags_and_pose_envs_own_verbose_do_not_clash() -> None:
    parser = build_parser()
    args = parser.parse_args(["pose-env", "--verbose"])
    assert args.verbose is True and args.log_verbosity == 0
    args = parser.parse_args(["-vv", "pose-env"])
    assert args.verbose is False and args.log_verbosity == 2
    with pytest.raises(SystemExit):  # -v and --quiet together
        parser.parse_args(["-v", "--quiet", "plan"])


def test_main_leaves_the_callers_logging_as_it_was(tmp_path: Path) -> None:
    from app.cli import main

    logger = logging.getLogger(ROOT)
    logger.setLevel(logging.NOTSET)
    code = main(["-v", "profiles", "--robot", "human_arm_2dof", "--method", "none", "--json"])
    assert code == 0
    assert logger.level == logging.NOTSET and logger.propagate
    assert not [h for h in logger.handlers if type(h).__name__ == "_StderrHandler"]
