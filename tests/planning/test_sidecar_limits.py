"""Sidecars are read within limits: size, nesting, aliases, values and digits (issue 15 items
9 and 11): a 362-byte "billion laughs" file held a parse slot for 23-52 s while an error message
spelled it out; a 5,000-digit integer and a 10,000-deep nesting were server errors."""

from __future__ import annotations

from pathlib import Path

import pytest

from app.planning.robots import RobotError
from app.planning.robots._sidecar import (
    MAX_ALIASES,
    MAX_DEPTH,
    MAX_DIGITS,
    MAX_NODES,
    MAX_SIDECAR_BYTES,
    read_sidecar,
)


def _laughs() -> str:
    """Nested anchors inside a field (the old reader's error message spelled them out): nine
    aliases a level, 9**9 strings in all, in under 400 bytes."""
    levels = ["&a [" + ",".join(['"lol"'] * 9) + "]"]
    for p, n in zip("abcdefgh", "bcdefghi", strict=True):
        levels.append(f"&{n} [" + ",".join([f"*{p}"] * 9) + "]")
    return "locks: [" + ", ".join(levels) + "]\n"


def _refused(tmp_path: Path, text: str, name: str = "robot.yaml") -> str:
    path = tmp_path / name
    path.write_text(text)
    with pytest.raises(RobotError) as info:
        read_sidecar(path)
    message = str(info.value)
    assert message.startswith(f"{name}: "), message
    assert "\n" not in message and len(message) < 300, message  # never the expanded input
    return message


def test_billion_laughs_is_refused_without_expanding_it(tmp_path: Path) -> None:
    text = _laughs()
    assert len(text) < 400
    message = _refused(tmp_path, text)
    assert f"more than {MAX_NODES} values" in message and "lol" not in message


def test_many_aliases_are_refused(tmp_path: Path) -> None:
    block = "{gear_ratio: 50, torque_constant: 0.1, winding_resistance: 1}"
    joints = "\n".join(f"  j{i}: *m" for i in range(MAX_ALIASES + 1))
    message = _refused(tmp_path, f"defaults: &m {block}\nmotors:\n{joints}\n")
    assert f"more than {MAX_ALIASES} aliases" in message


def test_an_alias_shares_a_motor_block(tmp_path: Path) -> None:
    """Anchors stay usable within the limits: one motor block for two joints."""
    path = tmp_path / "ok.yaml"
    path.write_text(
        "motors:\n"
        "  shoulder: &m {gear_ratio: 50, torque_constant: 0.1, winding_resistance: 1}\n"
        "  elbow: *m\n"
    )
    sidecar = read_sidecar(path)
    assert sidecar.motors["shoulder"] == sidecar.motors["elbow"]
    assert sidecar.motors["elbow"].gear_ratio == 50.0


@pytest.mark.parametrize("literal", ["9" * 5000, "-" + "1" * 5000, "1" * 5000 + ".5"])
def test_a_huge_number_is_refused_naming_the_file(tmp_path: Path, literal: str) -> None:
    message = _refused(tmp_path, f"payload:\n  mass: {literal}\n", "arm.yaml")
    assert f"expected at most {MAX_DIGITS}" in message and "line 2" in message


def test_a_huge_integer_key_is_refused(tmp_path: Path) -> None:
    message = _refused(tmp_path, f"locks:\n  ? {'7' * 5000}\n  : 1\n")  # an explicit key
    assert "a number of 5000 characters" in message


@pytest.mark.parametrize(
    "text",
    [
        "locks: " + "[" * 10_000 + "]" * 10_000 + "\n",
        "locks: " + "{a: " * 10_000 + "1" + "}" * 10_000 + "\n",
        "".join("  " * i + f"k{i}:\n" for i in range(MAX_DEPTH + 5)),
    ],
    ids=["lists", "flow-mappings", "block-mappings"],
)
def test_deep_nesting_is_refused(tmp_path: Path, text: str) -> None:
    message = _refused(tmp_path, text)
    assert f"nested more than {MAX_DEPTH} deep" in message


def test_a_recursive_alias_is_refused(tmp_path: Path) -> None:
    message = _refused(tmp_path, "locks: &a {x: *a}\n")
    assert "alias inside the value it names" in message


def test_a_large_file_is_refused_before_parsing(tmp_path: Path) -> None:
    text = "# padding\n" * (MAX_SIDECAR_BYTES // 10 + 1)
    message = _refused(tmp_path, text)
    assert f"larger than {MAX_SIDECAR_BYTES} bytes" in message


def test_messages_quote_values_briefly(tmp_path: Path) -> None:
    """A bad value is quoted when short, described otherwise; a long field name is cut."""
    message = _refused(tmp_path, "payload:\n  mass: [" + ", ".join(["1"] * 500) + "]\n")
    assert "payload.mass is a list of 500 items: expected a number" in message
    message = _refused(tmp_path, "motors:\n  j:\n    gear_ratio: -50\n")
    assert message == "robot.yaml: motors.j.gear_ratio is -50: expected a number >= 1"
    long_name = "x" * 5000  # an explicit key: PyYAML refuses plain keys past 1024 characters
    message = _refused(tmp_path, f"velocity_limits:\n  ? {long_name}\n  : -1\n")
    assert "velocity_limits.xxx" in message and long_name not in message
    message = _refused(tmp_path, f"? {long_name}\n: 1\n")
    assert "unknown field xxx" in message and long_name not in message
