"""The viser server wrapper: real port when the asked one is busy, client paths, stop, and how
each tab's comparison is found (real websocket clients)."""

from __future__ import annotations

import itertools
import logging
import socket
import time
import urllib.request
from collections.abc import Iterator
from typing import Any

import pytest

from app.viewer import server as server_module
from app.viewer.access import parse_client_path
from app.viewer.comparison import Comparison
from app.viewer.scene import PreparedCache
from app.viewer.server import ViewerServer
from tests.viewer._fakes import connect_client as _connect
from tests.viewer._fakes import issued_path
from tests.viewer._fakes import listening_socket as _listening_socket


@pytest.mark.parametrize(
    ("path", "expected"),
    [
        ("/bioplan/plan/7", ("plan", 7)),
        ("/bioplan/simulation/12/", ("simulation", 12)),
        ("/bioplan/plan/7?x=1", ("plan", 7)),
        ("/bioplan/sweep/7", None),
        ("/bioplan/plan/0", None),
        ("/bioplan/plan/-1", None),
        ("/bioplan/plan/12345678901", None),
        ("/bioplan/plan/7/../../etc", None),
        ("/", None),
        ("", None),
        (None, None),
    ],
)
def test_client_paths(path: str | None, expected: tuple[str, int] | None) -> None:
    parsed = parse_client_path(path)
    assert (parsed if parsed is None else parsed[:2]) == expected


def test_busy_port_moves_and_the_real_port_is_reported(
    plan_comparison: Comparison, caplog: pytest.LogCaptureFixture
) -> None:
    busy = _listening_socket()
    asked = busy.getsockname()[1]
    viewer = ViewerServer(PreparedCache(lambda k, i: plan_comparison), port=asked)
    try:
        with caplog.at_level(logging.WARNING, logger="app.viewer.server"):
            port = viewer.start()
        assert port != asked and port == viewer.port
        assert f"viewer port {asked} was busy" in caplog.text
        # Something really serves viser's client there.
        page = urllib.request.urlopen(f"http://127.0.0.1:{port}/", timeout=10).read()
        assert b"<html" in page.lower() and len(page) > 100_000
        assert viewer.url == f"http://127.0.0.1:{port}"
        url = viewer.client_url("plan", 7)
        prefix = f"http://127.0.0.1:{port}/?websocket=ws%3A%2F%2F127.0.0.1%3A{port}%2Fbioplan%2Fplan%2F7%3Ftoken%3D"
        assert url.startswith(prefix) and url.endswith("&hideViserLogo")
        assert viewer.sessions() == []
    finally:
        viewer.stop()
        busy.close()
    assert not viewer.running
    with pytest.raises(RuntimeError, match="not running"):
        _ = viewer.port
    # Stopped means nothing listens there any more (TIME_WAIT of our request is fine).
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as again:
        again.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        again.bind(("127.0.0.1", port))


@pytest.fixture
def viewer(plan_comparison: Comparison) -> Iterator[ViewerServer]:
    with _listening_socket() as sock:
        port = sock.getsockname()[1]  # free (viser's own port=0 reads as "busy" to us)
    server = ViewerServer(PreparedCache(lambda k, i: plan_comparison), port=port, autoplay=False)
    server.start()
    try:
        yield server
    finally:
        server.stop()


def _session_of(
    viewer: ViewerServer, known: set[int], timeout: float = 60.0, hint: str = ""
) -> dict[str, Any]:
    """The session of the next tab that connects (waits for its scene to be built)."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        session = next((s for s in viewer.sessions() if s["client_id"] not in known), None)
        if session is not None:
            known.add(session["client_id"])
            return session
        time.sleep(0.05)
    raise AssertionError(f"no session for the tab{hint}")


def test_the_handshake_path_names_the_comparison(viewer: ViewerServer) -> None:
    """The fast path: viser's private connection table still gives the websocket's path.

    If this fails after a viser upgrade, ``app.viewer.server._handshake_path`` needs updating;
    until then tabs are matched by the fallback (see the next test), which can swap two tabs
    opened at the same moment.
    """
    known: set[int] = set()
    broken = " (viser no longer gives _handshake the websocket's path?)"
    with _connect(viewer, issued_path(viewer, "simulation", 31)):
        first = _session_of(viewer, known, hint=broken)
        handshake = server_module._handshake(viewer._server, first["client_id"])
        assert handshake is not None and handshake[0].startswith("/bioplan/simulation/31?token="), (
            "viser no longer exposes the websocket path where _handshake reads it"
        )
        with _connect(viewer, issued_path(viewer, "plan", 7)):
            second = _session_of(viewer, known, hint=broken)
    assert (first["kind"], first["id"]) == ("simulation", 31)
    assert (second["kind"], second["id"]) == ("plan", 7)
    assert server_module._handshake(viewer._server, first["client_id"] + 100) is None


class _Recorder:
    """A GUI handle that records every assignment (what viser would send to the browser)."""

    def __init__(self, log: list[tuple[str, str, Any]], name: str, **props: Any) -> None:
        object.__setattr__(self, "_log", log)
        object.__setattr__(self, "_name", name)
        for key, value in props.items():
            object.__setattr__(self, key, value)

    def __setattr__(self, key: str, value: Any) -> None:
        self._log.append((self._name, key, value))
        object.__setattr__(self, key, value)


def test_playing_sends_the_phase_text_only_at_boundaries_and_the_gui_at_4_hz(
    plan_comparison: Comparison, monkeypatch: pytest.MonkeyPatch
) -> None:
    from contextlib import nullcontext
    from types import SimpleNamespace

    from app.viewer.comparison import LABELS
    from app.viewer.playback import PlaybackClock
    from app.viewer.scene import ComparisonScene, PreparedComparison
    from app.viewer.server import ViewerSession
    from tests.viewer.test_scene import FakeTarget

    now = [100.0]
    monkeypatch.setattr(server_module.time, "monotonic", lambda: now[0])
    target = FakeTarget()
    client = SimpleNamespace(client_id=1, scene=target.scene, atomic=nullcontext)
    scene = ComparisonScene(client, PreparedComparison(plan_comparison))
    log: list[tuple[str, str, Any]] = []
    gui = {
        name: _Recorder(log, name, max=plan_comparison.duration)
        for name in ("play", "time", "phase", "plot")
    }
    clock = PlaybackClock(plan_comparison.duration, loop=False, now=lambda: now[0])
    session = ViewerSession(client=client, kind="plan", id=7, scene=scene, clock=clock, gui=gui)
    clock.play()
    shown = []
    while now[0] < 100.0 + plan_comparison.duration + 0.1:  # 60 ticks a second, to the end
        session.tick()
        shown.append(scene.index)
        now[0] += 1 / 60
    assert shown[-1] == len(plan_comparison.t) - 1 and len(set(shown)) > 50
    # The phase text is sent only when it changes: at most once per change of either
    # trajectory's phase along what was shown, not with every GUI refresh.
    seen = [tuple(plan_comparison.phase_at(label, i) for label in LABELS) for i in shown]
    changes = 1 + sum(a != b for a, b in itertools.pairwise(seen))
    texts = [v for name, key, v in log if name == "phase" and key == "content"]
    assert 0 < len(texts) <= changes and len(set(texts)) == len(texts)
    assert f"solid: standard quintic: **{seen[-1][0]}**" in texts[-1]
    # Slider and plot cursor: at most 4 updates a second while moving, plus the first.
    slider = [v for name, key, v in log if name == "time" and key == "value"]
    assert 2 <= len(slider) <= 2 + 4 * plan_comparison.duration and slider == sorted(slider)
    # (the phase text goes with the pose that changed it: issue 29, tests/viewer/
    # test_phase_sources.py; so it is not bound to the slider's rate)
    assert len([1 for name, key, _ in log if name == "plot" and key == "data"]) == len(slider)


def test_the_compare_pages_pair_reaches_the_tab(viewer: ViewerServer) -> None:
    """The Compare page's "solid"/"ghost" choice travels in the websocket path (percent-encoded
    inside the iframe's address) and the tab shows that pair; a pair the plan did not make, or
    one method twice, leaves the default."""
    url = viewer.client_url("plan", 7, ("human_optimal", "bound"))
    assert url.endswith("%26methods%3Dhuman_optimal%2Cbound&hideViserLogo")
    known: set[int] = set()
    # The fixture planned the quintic and the paper's method: the swapped pair is a choice.
    with _connect(viewer, issued_path(viewer, "plan", 7, ("paper", "quintic"))):
        chosen = _session_of(viewer, known)
    with _connect(viewer, issued_path(viewer, "plan", 7, ("bound", "bound"))):
        twice = _session_of(viewer, known)
    with _connect(viewer, issued_path(viewer, "plan", 7, ("bound", "nonsense"))):
        unknown = _session_of(viewer, known)
    assert (chosen["solid"], chosen["ghost"]) == ("paper", "quintic")
    assert (twice["solid"], twice["ghost"]) == ("quintic", "paper")
    assert (unknown["solid"], unknown["ghost"]) == ("quintic", "paper")
