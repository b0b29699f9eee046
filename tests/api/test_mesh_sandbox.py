"""Issue 23 item 6: the viewer's meshes are parsed in the upload sandbox, never in the server.

A robot's meshes are its owner's files; a stored mesh that costs more memory than the sandbox
allows leaves the robot drawn without meshes (and a warning), the server unaffected.
"""

from __future__ import annotations

import logging
import os
from collections.abc import Iterator

import pytest

from app.services import sandbox
from app.services.core import read_meshes
from app.services.sandbox import ParseSandbox


def _where(*args: object) -> list[object]:
    """Stands in for ``load_link_meshes``: says which process ran it and with what."""
    from app.viewer import kinematics

    return [os.getpid(), args, kinematics._mesh_limits]


def _hungry(*args: object) -> list[object]:
    """Stands in for a mesh that decodes to far more than the sandbox allows."""
    return [bytearray(1024 * 1024 * 1024)]


@pytest.fixture
def limited() -> Iterator[ParseSandbox]:
    box = ParseSandbox(memory_mb=128, seconds=120)
    sandbox.use(box)
    try:
        yield box
    finally:
        sandbox.release(box)


def test_meshes_are_read_in_a_child_with_the_servers_caps(limited: ParseSandbox) -> None:
    from app.planning.robots._package import MeshLimits

    caps = MeshLimits(max_bytes=1234, max_triangles=56, max_unpacked=7890)
    pid, args, seen = read_meshes(caps, _where, "robot.urdf", ("pkg",), None)
    assert pid != os.getpid()  # not parsed in the server's process
    assert args == ("robot.urdf", ("pkg",), None)
    assert seen == caps  # the child checks meshes against the server's caps


def test_a_mesh_set_past_the_memory_limit_is_drawn_without_meshes(
    limited: ParseSandbox, caplog: pytest.LogCaptureFixture
) -> None:
    with caplog.at_level(logging.WARNING):
        assert read_meshes(None, _hungry, "robot.urdf") == []
    assert "robot drawn without meshes" in caplog.text
    assert "BIOPLAN_PARSE_MEMORY_MB" in caplog.text
