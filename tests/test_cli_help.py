"""``--help`` of every command shows every option's default, and values that look negative are
values: the parsers themselves, walked, not a list kept by hand."""

from __future__ import annotations

import argparse
import subprocess
import sys
from collections.abc import Iterator

import pytest

from app.cli import build_parser
from app.cli._common import EXIT_BAD_INPUT
from app.names import MAX_DURATION


def _parsers(
    parser: argparse.ArgumentParser, path: tuple[str, ...] = ("bioplan",)
) -> Iterator[tuple[tuple[str, ...], argparse.ArgumentParser]]:
    yield path, parser
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                yield from _parsers(sub, (*path, name))


PARSERS = list(_parsers(build_parser()))
#: Actions that take no value: a default there is not a setting to show.
_FLAGS = (
    argparse._StoreTrueAction,
    argparse._StoreFalseAction,
    argparse._HelpAction,
    argparse._VersionAction,
    argparse._CountAction,
)


def test_the_walk_finds_every_command() -> None:
    names = {" ".join(path) for path, _ in PARSERS}
    for command in ("plan", "profiles", "analyze", "pose-env", "simulate", "sweep", "export",
                    "demo", "samples", "serve", "submit", "submit plan"):  # fmt: skip
        assert f"bioplan {command}" in names, command


@pytest.mark.parametrize("path, parser", PARSERS, ids=[" ".join(p) for p, _ in PARSERS])
def test_every_option_with_a_default_shows_it(
    path: tuple[str, ...], parser: argparse.ArgumentParser
) -> None:
    formatter = parser._get_formatter()
    missing = []
    for action in parser._actions:
        if (
            not action.option_strings
            or isinstance(action, _FLAGS)
            or action.default in (None, argparse.SUPPRESS)
            or action.help == argparse.SUPPRESS
        ):
            continue
        text = formatter._expand_help(action) if action.help else ""
        shown = str(action.default) if action.default != [] else "none"
        if "default" not in text or shown not in text:
            missing.append(f"{action.option_strings[-1]} (default {action.default!r}): {text!r}")
    assert not missing, f"{' '.join(path)}: options whose --help hides the default: {missing}"


def _cli(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "app.cli", *args], capture_output=True, text=True, timeout=300
    )


@pytest.mark.parametrize(
    "args, says",
    [
        (("sweep", "--durations", "-1,1"), "--durations must be a positive number, got -1"),
        (("sweep", "--durations=-1,1"), "--durations must be a positive number, got -1"),
        (("plan", "--duration", "-2"), "--duration must be a positive number, got -2"),
        (
            ("plan", "--robot", "human_arm_2dof", "--start-deg", "-10", "--method", "quintic"),
            "--start-deg needs 2 angles",
        ),
    ],
)
def test_a_negative_value_is_read_as_the_value(args: tuple[str, ...], says: str) -> None:
    """argparse takes "-1,1" for an option ("expected one argument"): here it is the value,
    and the error is about the value."""
    done = _cli(*args)
    assert done.returncode == EXIT_BAD_INPUT
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and says in lines[0], done.stderr
    assert "expected one argument" not in done.stderr


def test_duration_above_the_api_cap_is_one_line_naming_the_cap() -> None:
    """`bioplan plan --duration 1e4` ended in a ruckig traceback; now the CLI states the API's
    cap in --help and refuses above it in one line, exit code 2."""
    done = _cli("plan", "--duration", "1e4")
    assert done.returncode == EXIT_BAD_INPUT
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1, done.stderr
    assert f"at most {MAX_DURATION:g}" in lines[0] and "Traceback" not in done.stderr
    helped = _cli("plan", "--help").stdout
    assert f"at most {MAX_DURATION:g}" in " ".join(helped.split())


def test_the_api_caps_duration_with_the_same_constant() -> None:
    from app.api.schemas import PlanRequest, SweepRequest

    schema = PlanRequest.model_json_schema()
    assert schema["properties"]["duration"]["maximum"] == MAX_DURATION
    sweep = SweepRequest.model_json_schema()["properties"]["durations"]["items"]
    assert sweep["maximum"] == MAX_DURATION
