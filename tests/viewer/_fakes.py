"""Test doubles and clients shared by the viewer's tests: a scene that records what a viser
scene would send, a real websocket client like viser's page, a free listening socket."""

from __future__ import annotations

import contextlib
import socket
from typing import Any

from app.viewer.server import ViewerServer


class Handle:
    """Records every property assignment, like a viser scene-node handle would send it."""

    def __init__(self, log: list[tuple[str, str]], name: str, **props: Any) -> None:
        object.__setattr__(self, "_log", log)
        object.__setattr__(self, "name", name)
        for k, v in props.items():
            object.__setattr__(self, k, v)

    def __setattr__(self, key: str, value: Any) -> None:
        self._log.append((self.name, key))
        object.__setattr__(self, key, value)


class FakeScene:
    def __init__(self) -> None:
        self.nodes: dict[str, Handle] = {}
        self.updates: list[tuple[str, str]] = []

    def _add(self, name: str, **props: Any) -> Handle:
        assert name not in self.nodes, f"node {name} added twice"
        handle = Handle(self.updates, name, **props)
        object.__setattr__(handle, "remove", lambda: self.nodes.pop(name))
        self.nodes[name] = handle
        return handle

    def __getattr__(self, method: str) -> Any:
        if not method.startswith("add_"):
            raise AttributeError(method)

        def add(name: str, *args: Any, **props: Any) -> Handle:
            props.setdefault("visible", True)
            return self._add(name, kind=method, args=args, **props)

        return add


class FakeTarget:
    def __init__(self) -> None:
        self.scene = FakeScene()


def listening_socket() -> socket.socket:
    sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    sock.bind(("127.0.0.1", 0))
    sock.listen(1)
    return sock


def connect_client(
    viewer: ViewerServer, path: str, *, width: int = 800, origin: str | None = None
) -> Any:
    """A websocket client like viser's own page: its version as subprotocol, any path, the
    ``Origin`` a browser would send (None: none, as a non-browser client), and the camera
    message the page sends first (viser calls a client connected only after it)."""
    import msgspec
    import viser
    from viser._messages import ViewerCameraMessage
    from websockets.exceptions import ConnectionClosed
    from websockets.sync.client import connect

    ws = connect(
        f"ws://127.0.0.1:{viewer.port}{path}",
        subprotocols=[f"viser-v{viser.__version__}"],  # type: ignore[list-item]
        max_size=None,
        open_timeout=20,
        origin=origin,  # type: ignore[arg-type]
    )
    camera = ViewerCameraMessage(
        wxyz=(1.0, 0.0, 0.0, 0.0),
        position=(2.0, -2.0, 1.5),
        fov=1.0,
        near=0.01,
        far=100.0,
        image_height=600,
        image_width=width,
        look_at=(0.0, 0.0, 0.5),
        up_direction=(0.0, 0.0, 1.0),
    )
    message = {"type": "ViewerCameraMessage", **camera.as_serializable_dict()}
    with contextlib.suppress(ConnectionClosed):  # refused at once: the caller sees the close
        ws.send(msgspec.msgpack.encode(message))
    return ws


def issued_path(
    viewer: ViewerServer, kind: str, result_id: int, methods: tuple[str, str] | None = None
) -> str:
    """The websocket path (with its capability) that the API hands the Compare page."""
    url = viewer.websocket_url(kind, result_id, methods)
    return url.split(f":{viewer.port}", 1)[1]
