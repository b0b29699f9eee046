"""Who may open a viewer tab: a capability per comparison, the page's own origin, a bound on
connections.

The viewer's websocket streams a plan's title, power curve and every joint pose. Without a
check any web page could open ``ws://127.0.0.1:<port>/bioplan/plan/2`` from the user's browser
and read them, and enumerate the ids. So:

- The API issues a capability (an unguessable token from :func:`secrets.token_urlsafe`) for one
  comparison whenever it hands the Compare page the iframe's address; the token travels in the
  websocket path (``/bioplan/<kind>/<id>?token=...``). A token opens only the comparison it was
  issued for, and expires (``ttl_s``, renewed when the page asks again).
- A browser's handshake carries ``Origin``: it must be the viewer's own page (the iframe's
  document: one of the allowed host names at the viewer's port). A client without ``Origin``
  is not a browser, so no other site can drive it; it still needs the token.
- Connections are bounded in all and per token; the excess is refused.

A refusal happens right after the websocket handshake, before any message of the scene is
sent (``app.viewer.server`` closes the connection with code 1008 and the reason).
"""

from __future__ import annotations

import secrets
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from urllib.parse import parse_qs, urlsplit

__all__ = ["Grant", "Refused", "ViewerAccess", "parse_client_path"]

#: Seconds a capability stays valid after the API last issued it.
DEFAULT_TTL_S = 3600.0
#: Viewer connections at once, in all and per capability (a tab that reconnects, a second tab).
DEFAULT_MAX_CONNECTIONS = 32
DEFAULT_MAX_PER_TOKEN = 4
_KINDS = ("plan", "simulation", "front")


class Refused(Exception):
    """A connection the viewer does not serve; the message says why (logged, and sent as the
    close reason)."""


@dataclass(frozen=True)
class Grant:
    """What an admitted connection may see."""

    kind: str
    id: int
    methods: tuple[str, str] | None
    token: str


@dataclass
class _Capability:
    kind: str
    id: int
    expires: float
    clients: set[int] = field(default_factory=set)


def parse_client_path(path: str | None) -> tuple[str, int, dict[str, str]] | None:
    """``(kind, id, query)`` from a websocket path ``/bioplan/<plan|simulation|front>/<id>[?...]``
    (each query key's first value), else None."""
    if not path:
        return None
    parts = urlsplit(path)
    segments = [s for s in parts.path.split("/") if s]
    if len(segments) != 3 or segments[0] != "bioplan" or segments[1] not in _KINDS:
        return None
    digits = segments[2]
    if not digits.isdigit() or digits.startswith("0") or len(digits) > 10:
        return None
    query = {k: v[0] for k, v in parse_qs(parts.query).items()}
    return segments[1], int(digits), query


def _methods(value: str | None) -> tuple[str, str] | None:
    pair = (value or "").split(",")
    # Method names, or a front's point ids (``p0``, ``p12``).
    if len(pair) == 2 and all(
        m.isascii() and m.replace("_", "").isalnum() and len(m) <= 32 for m in pair
    ):
        return pair[0], pair[1]
    return None


class ViewerAccess:
    """Capabilities, origins and connection bounds of one viewer (thread-safe).

    Args:
        ttl_s: seconds a capability stays valid after it was last issued.
        max_connections: admitted connections at once, in all.
        max_per_token: admitted connections at once per capability.
        now: the clock (monotonic seconds; tests pass their own).
    """

    def __init__(
        self,
        *,
        ttl_s: float = DEFAULT_TTL_S,
        max_connections: int = DEFAULT_MAX_CONNECTIONS,
        max_per_token: int = DEFAULT_MAX_PER_TOKEN,
        now: Callable[[], float] = time.monotonic,
    ) -> None:
        self.ttl_s = ttl_s
        self.max_connections = max_connections
        self.max_per_token = max_per_token
        self._now = now
        self._tokens: dict[str, _Capability] = {}
        self._issued: dict[tuple[str, int], str] = {}
        self._clients: dict[int, str] = {}
        self._lock = threading.Lock()

    def issue(self, kind: str, result_id: int) -> str:
        """The capability for comparison ``kind``/``result_id`` (the same token while it is
        valid, its expiry renewed: a page that reloads keeps working)."""
        with self._lock:
            self._expire()
            token = self._issued.get((kind, result_id))
            if token is None:
                token = secrets.token_urlsafe(24)
                self._tokens[token] = _Capability(kind, result_id, 0.0)
                self._issued[(kind, result_id)] = token
            self._tokens[token].expires = self._now() + self.ttl_s
            return token

    def admit(
        self,
        client_id: int,
        path: str | None,
        origin: str | None,
        origin_ok: Callable[[str], bool],
    ) -> Grant:
        """Admit a new connection, or raise :class:`Refused` saying why.

        Args:
            client_id: the connection's id (released with :meth:`release`).
            path: the websocket handshake's request path (None: it could not be read).
            origin: the handshake's ``Origin`` header (None: not a browser).
            origin_ok: whether an ``Origin`` is the viewer's own page.
        """
        if path is None:
            raise Refused("the websocket's path could not be read, so its capability cannot "
                          "be checked (viser's internals changed?)")  # fmt: skip
        if origin is not None and not origin_ok(origin):
            raise Refused(f"foreign origin {origin[:100]!r}")
        target = parse_client_path(path)
        if target is None:
            raise Refused("not a comparison's address (/bioplan/<plan|simulation|front>/<id>)")
        kind, result_id, query = target
        token = query.get("token", "")
        with self._lock:
            self._expire()
            cap = self._tokens.get(token)
            if cap is None or cap.expires < self._now():
                raise Refused("no valid capability (a missing, wrong or expired token)")
            if (cap.kind, cap.id) != (kind, result_id):
                raise Refused(f"the capability is not for {kind} {result_id}")
            if len(self._clients) >= self.max_connections:
                raise Refused(f"too many viewer connections (at most {self.max_connections})")
            if len(cap.clients) >= self.max_per_token:
                raise Refused(f"too many connections to one comparison's viewer (at most "
                              f"{self.max_per_token})")  # fmt: skip
            cap.clients.add(client_id)
            self._clients[client_id] = token
        return Grant(kind, result_id, _methods(query.get("methods")), token)

    def release(self, client_id: int) -> None:
        """A connection ended (admitted or not)."""
        with self._lock:
            token = self._clients.pop(client_id, None)
            cap = self._tokens.get(token or "")
            if cap is not None:
                cap.clients.discard(client_id)

    def connections(self) -> int:
        with self._lock:
            return len(self._clients)

    def _expire(self) -> None:
        now = self._now()
        for token, cap in list(self._tokens.items()):
            if cap.expires < now and not cap.clients:
                del self._tokens[token]
                self._issued.pop((cap.kind, cap.id), None)
