"""One error shape for every failure: ``application/problem+json`` (RFC 9457).

``{"type", "title", "status", "detail", "field"?, "file"?, "errors"?, "job"?}``. Only bad input
is a 4xx: request validation and any ``BioPlanError`` (an unreadable recording or robot model, a
task the planner refuses, a service's ``ServiceError``) are 422, with ``NotFoundError`` 404 and
``ConflictError`` 409; routes raise ``ApiError`` for the rest (401, 413...). Anything else,
``ValueError`` included, is a bug: ``app.api.middleware.CatchAllMiddleware`` logs it with its
traceback and answers a plain 500 problem that never contains the traceback.
"""

from __future__ import annotations

import logging
import re
from http import HTTPStatus

from fastapi import FastAPI, Request
from fastapi.encoders import jsonable_encoder
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse
from sqlalchemy.exc import OperationalError
from starlette.exceptions import HTTPException as StarletteHTTPException

from app.errors import BioPlanError, one_line, storage_problem
from app.services.errors import ConflictError, NotFoundError, ParseLimitError

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
        extra: dict[str, object] | None = None,
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
    members: dict[str, object] | None = None,
    **extra: object,
) -> JSONResponse:
    """A problem response; ``extra`` members are left out when None, ``members`` never are."""
    body: dict[str, object] = {"type": "about:blank", "title": title, "status": status}
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
    if exc.status_code == 400 and detail == "There was an error parsing the body":
        detail = "the request body cannot be parsed: expected UTF-8 JSON, as its Content-Type says"
    headers = dict(exc.headers or {})
    status = exc.status_code
    if status == 405 and request.url.path.startswith("/api/"):
        allowed = _allowed_methods(request)
        if allowed:
            headers["Allow"] = ", ".join(allowed)
        else:  # no API route here (the pages' static files refused the method): no such URL
            status, detail = 404, "Not Found"
            headers.pop("Allow", None)
    return problem(status, _phrase(status), detail, headers=headers)


def _allowed_methods(request: Request) -> list[str]:
    """Every method the API documents at this path (GET brings HEAD): Starlette's 405 names
    only the first route's (``Allow: GET, HEAD`` for ``/api/plans``, which also takes POST).
    An integer path parameter matches digits only, as its route's ``:int`` convertor does."""
    path = request.url.path
    methods: set[str] = set()
    for template, operations in request.app.openapi().get("paths", {}).items():
        if re.fullmatch(_path_pattern(template, operations), path):
            methods |= {m.upper() for m in operations if m in _HTTP_METHODS}
    if "GET" in methods:
        methods.add("HEAD")
    return sorted(methods)


_HTTP_METHODS = {"get", "put", "post", "delete", "patch", "options", "head"}


def _path_pattern(template: str, operations: dict[str, object]) -> str:
    integers = {
        p["name"]
        for op in operations.values()
        if isinstance(op, dict)
        for p in op.get("parameters", [])
        if p.get("in") == "path" and p.get("schema", {}).get("type") == "integer"
    }
    pattern = ""
    for literal, name in re.findall(r"([^{]*)(?:\{(\w+)\})?", template):
        pattern += re.escape(literal)
        if name:
            pattern += "[0-9]+" if name in integers else "[^/]+"
    return pattern


#: Names pydantic gives the members of a union in an error's location (``offset.float``).
_UNION_MEMBERS = {"float", "int", "str", "bool", "none", "list", "dict", "tuple"}


def _field_of(loc: tuple[int | str, ...]) -> str:
    """The request field of a validation error: ``durations.0``, ``offset`` (not
    ``offset.constrained-float``: a union member's tag is no field)."""
    parts = [str(p) for p in loc]
    if parts and parts[0] in ("body", "query", "path", "header", "cookie", "form"):
        parts = parts[1:]
    named = [
        p
        for k, p in enumerate(parts)
        if k == 0 or p.isdigit() or (p.isidentifier() and p not in _UNION_MEMBERS)
    ]
    return ".".join(named) or "body"


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


def _status_of(exc: BioPlanError) -> int:
    status = getattr(exc, "status", None)  # a refusal that states its own (429: a full queue)
    if isinstance(status, int) and 400 <= status < 500:
        return status
    if isinstance(exc, ParseLimitError):
        return 413
    if isinstance(exc, NotFoundError):
        return 404
    if isinstance(exc, ConflictError):
        return 409
    return 422


async def _bad_input(request: Request, exc: Exception) -> JSONResponse:
    """Any ``BioPlanError``: its one-line message, and the field, file or job it names."""
    assert isinstance(exc, BioPlanError)
    status = _status_of(exc)
    file = getattr(exc, "file", None)
    field = getattr(exc, "field", None)
    channel = getattr(exc, "channel", None)
    if field is None and isinstance(channel, str):
        field = f"channel {channel}"
    job = getattr(exc, "job", None)
    title = getattr(exc, "title", None)
    if title is None and status != 422:
        title = _phrase(status)
    elif title is None:
        title = "Unreadable file" if file is not None else "Invalid input"
    named = job is not None or getattr(exc, "names_job", False)
    files = getattr(exc, "files", None)  # every unreadable file of an upload, each with its own
    extra = {"job": job} if named else {}
    if isinstance(files, list):
        extra["files"] = files
    headers = getattr(exc, "headers", None)  # e.g. Retry-After of a 429
    return problem(
        status,
        title,
        one_line(str(exc)),
        headers=headers if isinstance(headers, dict) else None,
        file=file if isinstance(file, str) else None,
        field=field if isinstance(field, str) else None,
        members=extra or None,
    )


STORAGE_FULL = "the server's storage is full: nothing was stored; try again once space is freed"
STORAGE_READ_ONLY = (
    "the server's data directory is read-only: nothing was changed; try again once it is writable"
)


async def _storage_error(request: Request, exc: Exception) -> JSONResponse:
    """A full or read-only disk is the server's condition, not the client's input and not a
    bug: 507."""
    condition = storage_problem(exc)
    if condition is None:
        raise exc  # a bug: the catch-all middleware logs it and answers 500
    logger.error("storage %s on %s %s: %s", condition, request.method, request.url.path, exc)
    detail = STORAGE_FULL if condition == "full" else STORAGE_READ_ONLY
    return problem(507, "Insufficient Storage", detail)


def install_error_handlers(app: FastAPI) -> None:
    """Register the problem+json handlers on ``app`` (bad input only: see the module doc;
    and a full disk, 507)."""
    app.add_exception_handler(ApiError, _api_error)
    app.add_exception_handler(StarletteHTTPException, _http_error)
    app.add_exception_handler(RequestValidationError, _validation_error)
    app.add_exception_handler(BioPlanError, _bad_input)
    app.add_exception_handler(OSError, _storage_error)
    app.add_exception_handler(OperationalError, _storage_error)
