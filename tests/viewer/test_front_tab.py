"""A front's point in the 3-D viewer: the tab's address names the front and the point, the
tab plays the point (solid) beside the quintic at its duration (real websocket clients)."""

from __future__ import annotations

import time
from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest

from app.viewer.access import ViewerAccess
from app.viewer.comparison import Comparison, comparison_from_arrays
from app.viewer.scene import PreparedCache
from app.viewer.server import ViewerServer
from tests.viewer._fakes import connect_client, issued_path, listening_socket


@pytest.fixture(scope="module")
def front_viewer() -> Iterator[tuple[ViewerServer, dict[str, Any], list[tuple[Any, ...]]]]:
    """A viewer over a small front of the 2-DOF arm (the job's own output), and the calls its
    loader got."""
    from app.jobs.tasks import run_task
    from app.planning import load_robot
    from app.services.fronts import point_arrays

    out = run_task(
        "front",
        {"robot": {"name": "human_arm_2dof"}, "payload_mass": 5.0,
         "objectives": ["tau_sq", "jerk"], "points": 3, "intervals": 20, "tolerance": 0.01},
        lambda _: None,
    )  # fmt: skip
    robot = load_robot("human_arm_2dof", payload=5.0)
    calls: list[tuple[Any, ...]] = []

    def loader(kind: str, result_id: int, methods: tuple[str, str] | None = None) -> Comparison:
        calls.append((kind, result_id, methods))
        assert methods is not None and methods[1] == "quintic"
        arrays = point_arrays(out["arrays"], out["result"], methods[0], robot)
        return comparison_from_arrays(
            "front", result_id, arrays, out["result"], robot, methods=methods
        )

    with listening_socket() as sock:
        port = sock.getsockname()[1]
    server = ViewerServer(PreparedCache(loader), port=port, autoplay=False)
    server.start()
    try:
        yield server, out, calls
    finally:
        server.stop()


def _session(viewer: ViewerServer, timeout: float = 60.0) -> dict[str, Any]:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        sessions = viewer.sessions()
        if sessions:
            return sessions[0]
        time.sleep(0.05)
    raise AssertionError("no session for the front's tab")


def test_the_tab_plays_the_point_beside_the_quintic(
    front_viewer: tuple[ViewerServer, dict[str, Any], list[tuple[Any, ...]]],
) -> None:
    viewer, out, calls = front_viewer
    with connect_client(viewer, issued_path(viewer, "front", 3, ("p2", "quintic"))):
        session = _session(viewer)
    assert (session["kind"], session["id"]) == ("front", 3)
    assert (session["solid"], session["ghost"]) == ("p2", "quintic")
    assert calls == [("front", 3, ("p2", "quintic"))]
    # What the tab plays is the stored point on its own grid.
    prepared = viewer.prepare("front", 3, ("p2", "quintic"))
    np.testing.assert_array_equal(prepared.comparison.q["p2"], out["arrays"]["p2_q"])
    assert prepared.comparison.title.startswith("Front #3: human_arm_2dof, 5 kg, 1 s")


@pytest.mark.parametrize(
    ("methods", "expected"),
    [
        ("quintic,p12", ("quintic", "p12")),
        ("quintic,p_1", ("quintic", "p_1")),
        ("quintic,p\u00b2", None),  # not ASCII: no point id
        ("quintic,p1;x", None),
        ("quintic", None),
    ],
)
def test_a_fronts_address_and_its_point(methods: str, expected: tuple[str, str] | None) -> None:
    access = ViewerAccess()
    token = access.issue("front", 4)
    grant = access.admit(1, f"/bioplan/front/4?token={token}&methods={methods}", None, bool)
    assert (grant.kind, grant.id, grant.methods) == ("front", 4, expected)
