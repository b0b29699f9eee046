"""One error shape for every failure: ``application/problem+json`` (RFC 9457).

``{"type", "title", "status", "detail", "field"?, "file"?, "errors"?, "job"?}``. Bad requests are
4xx: validation errors and unreadable recordings or robot models are 422, unknown resources 404,
conflicts 409, oversized bodies 413. Anything unexpected is logged with its traceback and
answered with a plain 500 problem that never contains the traceback.
"""

from __future__ import annotations

import logging
import uuid
from http import HTTPStatus
from typing import Any

from fastapi import FastAPI, Request
from fastapi.encoders import jsonable_encoder
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse
from starlette.exceptions import HTTPException as StarletteHTTPException
from starlette.types import ASGIApp, Message, Receive, Scope, Send

logger = logging.getLogger(__name__)

PROBLEM_JSON = "application/problem+json"


class ApiError(Exception):
    """Raise from a route to answer with a problem.

    Args:
        status: HTTP status code.
        detail: what is wrong and what was expected, in one sentence.
        title: short summary (default: the status phrase).
        field: the request field at fault.
        file: the uploaded file at fault.
        extra: more members of the problem (e.g. the ``job`` a 409 is waiting for).
    """

    def __init__(
        self,
        status: int,
        detail: str,
        *,
        title: str | None = None,
        field: str | None = None,
        file: str | None = None,
        headers: dict[str, str] | None = None,
        extra: dict[str, Any] | None = None,
    ) -> None:
        super().__init__(detail)
        self.status = status
        self.detail = detail
        self.title = title or HTTPStatus(status).phrase
        self.field = field
        self.file = file
        self.headers = headers
        self.extra = extra or {}


def problem(
    status: int,
    title: str,
    detail: str | None,
    *,
    headers: dict[str, str] | None = None,
    members: dict[str, Any] | None = None,
    **extra: Any,
) -> JSONResponse:
    """A problem response; ``extra`` members are left out when None, ``members`` never are."""
    body: dict[str, Any] = {"type": "about:blank", "title": title, "status": status}
    body["detail"] = detail
    body.update({k: v for k, v in extra.items() if v is not None})
    body.update(jsonable_encoder(members or {}))  # e.g. a job's datetimes
    return JSONResponse(body, status_code=status, media_type=PROBLEM_JSON, headers=headers)


def _phrase(status: int) -> str:
    try:
        return HTTPStatus(status).phrase
    except ValueError:
        return "Error"


async def _api_error(request: Request, exc: Exception) -> JSONResponse:
    assert isinstance(exc, ApiError)
    return problem(
        exc.status,
        exc.title,
        exc.detail,
        field=exc.field,
        file=exc.file,
        headers=exc.headers,
        members=exc.extra,
    )


async def _http_error(request: Request, exc: Exception) -> JSONResponse:
    assert isinstance(exc, StarletteHTTPException)
    detail = exc.detail if isinstance(exc.detail, str) else str(exc.detail)
    return problem(
        exc.status_code, _phrase(exc.status_code), detail, headers=dict(exc.headers or {})
    )


def _field_of(loc: tuple[Any, ...]) -> str:
    parts = [str(p) for p in loc]
    if parts and parts[0] in ("body", "query", "path", "header", "cookie", "form"):
        parts = parts[1:]
    return ".".join(parts) or "body"


async def _validation_error(request: Request, exc: Exception) -> JSONResponse:
    assert isinstance(exc, RequestValidationError)
    errors = []
    for err in exc.errors():
        loc = tuple(err.get("loc", ()))
        errors.append(
            {
                "field": _field_of(loc),
                "location": str(loc[0]) if loc else "body",
                "message": str(err.get("msg", "invalid")),
                "type": str(err.get("type", "")),
            }
        )
    first = errors[0] if errors else {"field": "body", "message": "invalid request"}
    return problem(
        422,
        "Invalid request",
        f"{first['field']}: {first['message']}",
        field=first["field"],
        errors=errors,
    )


async def _science_error(request: Request, exc: Exception) -> JSONResponse:
    # RecordingError carries file/channel; RobotError and other ValueErrors a one-line message.
    file = getattr(exc, "file", None)
    channel = getattr(exc, "channel", None)
    title = "Unreadable recording" if file is not None else "Invalid input"
    return problem(
        422,
        title,
        str(exc),
        file=file if isinstance(file, str) else None,
        field=f"channel {channel}" if isinstance(channel, str) else None,
    )


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


def install_error_handlers(app: FastAPI, *, max_body_bytes: int) -> None:
    """Register the problem+json handlers and the body-size limit on ``app``."""
    from app.recordings.types import RecordingError

    app.add_exception_handler(ApiError, _api_error)
    app.add_exception_handler(StarletteHTTPException, _http_error)
    app.add_exception_handler(RequestValidationError, _validation_error)
    app.add_exception_handler(RecordingError, _science_error)
    app.add_exception_handler(ValueError, _science_error)
    app.add_middleware(BodyLimitMiddleware, limit=max_body_bytes)
    app.add_middleware(CatchAllMiddleware)
