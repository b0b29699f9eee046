"""Everything that wraps every request, in one place: body-size limit, CORS, the catch-all 500.

``install_middleware(app, settings)`` is the only call; the order is explicit there (Starlette
runs the last one added first). Authentication is a dependency (``app.api.deps.require_token``).
"""

from __future__ import annotations

import logging
import uuid

from fastapi import FastAPI
from starlette.exceptions import HTTPException as StarletteHTTPException
from starlette.types import ASGIApp, Message, Receive, Scope, Send

from app.api.errors import problem
from app.config import Settings

logger = logging.getLogger(__name__)


class BodyTooLarge(StarletteHTTPException):
    """The request body exceeds the upload limit (raised while it streams in)."""

    def __init__(self, limit: int) -> None:
        super().__init__(
            413,
            f"the request body is larger than the upload limit of {limit} bytes "
            "(BIOPLAN_MAX_UPLOAD_MB)",
        )


class BodyLimitMiddleware:
    """Refuses request bodies over ``limit`` bytes: at once when Content-Length says so, else
    as soon as the streamed bytes pass the limit (nothing larger is ever buffered or parsed).
    """

    def __init__(self, app: ASGIApp, limit: int) -> None:
        self.app = app
        self.limit = limit

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        for key, value in scope.get("headers", []):
            if key == b"content-length":
                try:
                    declared = int(value)
                except ValueError:
                    break
                if declared > self.limit:
                    exc = BodyTooLarge(self.limit)
                    await problem(413, "Content Too Large", exc.detail)(scope, receive, send)
                    return
        seen = 0

        async def counting_receive() -> Message:
            nonlocal seen
            message = await receive()
            if message["type"] == "http.request":
                seen += len(message.get("body", b""))
                if seen > self.limit:
                    # An HTTPException passes through FastAPI's body parsing unchanged and
                    # reaches the problem handler.
                    raise BodyTooLarge(self.limit)
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


def install_middleware(app: FastAPI, settings: Settings) -> None:
    """Add the middleware. Outermost first: CORS (when configured, so every answer, a 413 or a
    500 too, carries its headers), the catch-all 500, the body-size limit."""
    # The upload limit is enforced while the body streams in, not after it is buffered.
    app.add_middleware(BodyLimitMiddleware, limit=settings.max_upload_bytes)
    app.add_middleware(CatchAllMiddleware)
    if settings.cors_origins:
        from fastapi.middleware.cors import CORSMiddleware

        app.add_middleware(
            CORSMiddleware,
            allow_origins=settings.cors_origins,
            allow_methods=["GET", "POST", "DELETE"],
            allow_headers=["Authorization", "Content-Type"],
        )
