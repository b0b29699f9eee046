"""Everything that wraps every request, in one place: the perimeter (Host, cross-site writes,
the API token, all checked before the body is read), body-size limit, CORS, the catch-all 500.

``install_middleware(app, settings)`` is the only call; the order is explicit there (Starlette
runs the last one added first). Routes keep the token as a dependency too
(``app.api.deps.require_token``), so a route mounted outside this app is not left open.
"""

from __future__ import annotations

import hmac
import ipaddress
import logging
import uuid
from urllib.parse import urlsplit

from fastapi import FastAPI
from starlette.exceptions import HTTPException as StarletteHTTPException
from starlette.types import ASGIApp, Message, Receive, Scope, Send

from app.api.errors import problem
from app.config import Settings, is_loopback

logger = logging.getLogger(__name__)


class BodyTooLarge(StarletteHTTPException):
    """The request body exceeds its limit (raised while it streams in)."""

    def __init__(self, limit: int, variable: str) -> None:
        super().__init__(
            413, f"the request body is larger than the limit of {limit} bytes ({variable})"
        )


class BodyLimitMiddleware:
    """Refuses request bodies over their limit: ``limit`` bytes for uploads (multipart forms),
    ``json_limit`` for every other body (JSON requests: no free-form field, a template's
    ``source`` say, can make a stored job and every list of jobs huge). At once when
    Content-Length says so, else as soon as the streamed bytes pass it (nothing larger is ever
    buffered or parsed).
    """

    def __init__(self, app: ASGIApp, limit: int, json_limit: int) -> None:
        self.app = app
        self.limit = limit
        self.json_limit = json_limit

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        headers = dict(scope.get("headers", []))
        upload = headers.get(b"content-type", b"").lower().startswith(b"multipart/")
        limit = self.limit if upload else min(self.limit, self.json_limit)
        variable = "BIOPLAN_MAX_UPLOAD_MB" if limit == self.limit else "BIOPLAN_MAX_JSON_KB"
        try:
            declared = int(headers.get(b"content-length", b"-1"))
        except ValueError:
            declared = -1
        if declared > limit:
            exc = BodyTooLarge(limit, variable)
            await problem(413, "Content Too Large", exc.detail)(scope, receive, send)
            return
        seen = 0

        async def counting_receive() -> Message:
            nonlocal seen
            message = await receive()
            if message["type"] == "http.request":
                seen += len(message.get("body", b""))
                if seen > limit:
                    # An HTTPException passes through FastAPI's body parsing unchanged and
                    # reaches the problem handler.
                    raise BodyTooLarge(limit, variable)
            return message

        await self.app(scope, counting_receive, send)


class CatchAllMiddleware:
    """Turns an unexpected exception into a logged problem 500 (no traceback to the client)."""

    def __init__(self, app: ASGIApp) -> None:
        self.app = app

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        started = False

        async def tracking_send(message: Message) -> None:
            nonlocal started
            if message["type"] == "http.response.start":
                started = True
            await send(message)

        try:
            await self.app(scope, receive, tracking_send)
        except Exception:
            ref = uuid.uuid4().hex[:12]
            logger.exception(
                "unhandled error (ref %s) on %s %s", ref, scope.get("method"), scope.get("path")
            )
            if started:
                raise
            response = problem(
                500,
                "Internal Server Error",
                f"an unexpected error occurred; the server log has the details (ref {ref})",
            )
            await response(scope, receive, send)


SAFE_METHODS = frozenset({"GET", "HEAD", "OPTIONS"})
OPEN_READS = ("/api/health", "/api/meta")
LOOPBACK_NAMES = frozenset({"localhost", "127.0.0.1", "::1"})


def _host_name(value: str) -> str:
    """``Host`` header or URL authority -> lower-case name without port or brackets."""
    value = value.strip().lower()
    if value.startswith("["):
        return value[1 : value.find("]")] if "]" in value else value[1:]
    return value.rsplit(":", 1)[0] if value.count(":") == 1 else value


def _is_wildcard(host: str) -> bool:
    try:
        return ipaddress.ip_address(host.strip("[]")).is_unspecified
    except ValueError:
        return False


class PerimeterMiddleware:
    """What is checked before a request's body is read (so a refused upload costs nothing):

    - ``Host`` names this server (DNS rebinding): the loopback names, the bound host and
      ``BIOPLAN_ALLOWED_HOSTS``; a wildcard bind without a list answers any name.
    - A write (any method but GET/HEAD/OPTIONS) from a browser comes from this site: refused
      when ``Sec-Fetch-Site`` says ``cross-site`` or ``Origin`` names another host than
      ``Host`` (and is not a configured CORS origin), with or without a token.
    - With ``BIOPLAN_API_TOKEN``: writes, and with ``BIOPLAN_PROTECT_READS`` every ``/api``
      read but health and meta, carry ``Authorization: Bearer <token>``.
    """

    def __init__(self, app: ASGIApp, settings: Settings) -> None:
        self.app = app
        self.token = settings.token
        self.protect_reads = settings.protect_reads and self.token is not None
        names = {_host_name(h) for h in settings.allowed_hosts} | LOOPBACK_NAMES
        self.any_host = _is_wildcard(settings.host) and not settings.allowed_hosts
        if not _is_wildcard(settings.host):
            names.add(_host_name(settings.host))
        self.hosts = frozenset(names)
        self.origins = frozenset(o.rstrip("/").lower() for o in settings.cors_origins)

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        headers = {k.decode("latin-1").lower(): v.decode("latin-1") for k, v in scope["headers"]}
        refusal = self._refusal(str(scope["method"]), str(scope["path"]), headers)
        if refusal is None:
            await self.app(scope, receive, send)
            return
        status, title, detail = refusal
        extra = {"WWW-Authenticate": "Bearer"} if status == 401 else None
        await problem(status, title, detail, headers=extra)(scope, receive, send)

    def _refusal(
        self, method: str, path: str, headers: dict[str, str]
    ) -> tuple[int, str, str] | None:
        host = _host_name(headers.get("host", ""))
        if not self.any_host and host not in self.hosts and not is_loopback(host):
            return (
                421,
                "Misdirected Request",
                f"this server does not answer to the host name {host!r}: add it to "
                "BIOPLAN_ALLOWED_HOSTS to serve it under that name",
            )
        write = method.upper() not in SAFE_METHODS
        if write and self._cross_site(headers):
            return 403, "Forbidden", "cross-site writes are refused (Origin / Sec-Fetch-Site)"
        needs_token = write or (
            self.protect_reads and path.startswith("/api") and not path.startswith(OPEN_READS)
        )
        if needs_token and self.token is not None and not self._has_token(headers):
            what = "writes" if write else "reads"
            return (
                401,
                "Unauthorized",
                f"this server requires an API token for {what}: "
                "send 'Authorization: Bearer <token>'",
            )
        return None

    def _cross_site(self, headers: dict[str, str]) -> bool:
        origin = headers.get("origin")
        if origin is not None and origin.rstrip("/").lower() in self.origins:
            return False
        if headers.get("sec-fetch-site", "").lower() == "cross-site":
            return True
        if origin is None or origin == "null":
            return origin == "null"  # no Origin: not a browser's cross-site request
        # Another port of the same machine is another site too: compare name and port.
        return urlsplit(origin).netloc.lower() != headers.get("host", "").strip().lower()

    def _has_token(self, headers: dict[str, str]) -> bool:
        scheme, _, sent = headers.get("authorization", "").partition(" ")
        assert self.token is not None
        return scheme.lower() == "bearer" and hmac.compare_digest(
            sent.strip().encode(), self.token.encode()
        )


def install_middleware(app: FastAPI, settings: Settings) -> None:
    """Add the middleware. Outermost first: CORS (when configured, so every answer, a 413 or a
    500 too, carries its headers), the catch-all 500, the perimeter, the body-size limit."""
    # The upload limit is enforced while the body streams in, not after it is buffered.
    app.add_middleware(
        BodyLimitMiddleware,
        limit=settings.max_upload_bytes,
        json_limit=int(settings.max_json_kb * 1024),
    )
    # Before any body is read: host, cross-site writes, token.
    app.add_middleware(PerimeterMiddleware, settings=settings)
    app.add_middleware(CatchAllMiddleware)
    if settings.cors_origins:
        from fastapi.middleware.cors import CORSMiddleware

        app.add_middleware(
            CORSMiddleware,
            allow_origins=settings.cors_origins,
            allow_methods=["GET", "POST", "DELETE"],
            allow_headers=["Authorization", "Content-Type"],
        )
