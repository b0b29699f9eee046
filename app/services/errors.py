"""Bad requests the services find by looking at the stored data.

Every one is a ``BioPlanError`` (bad input, never a bug), so the CLI and the API treat them as
they treat a reader's or the planner's errors. The API maps them by type: ``NotFoundError`` to
404, ``ConflictError`` to 409, any other ``BioPlanError`` to 422; nothing here knows HTTP.
"""

from __future__ import annotations

from typing import TypeVar

from app.errors import BioPlanError

__all__ = [
    "AnalysisPending",
    "ConflictError",
    "NotFoundError",
    "ParseLimitError",
    "ServiceError",
    "UnknownRobotError",
    "found",
]

T = TypeVar("T")


class ServiceError(BioPlanError):
    """A request the services refuse.

    Args:
        message: what is wrong and what was expected, in one line.
        field: the request field at fault, when there is one.
        file: the uploaded file at fault, when there is one.
        job: a job the caller may follow or inspect (JSON form), when there is one.

    Attributes:
        title: a short summary for people (None: the API's default for the kind of error).
        names_job: whether ``job`` is part of the answer even when it is None.
    """

    title: str | None = None
    names_job = False

    def __init__(
        self,
        message: str,
        *,
        field: str | None = None,
        file: str | None = None,
        job: dict[str, object] | None = None,
    ) -> None:
        super().__init__(message)
        self.field = field
        self.file = file
        self.job = job


class NotFoundError(ServiceError):
    """The resource a request names does not exist: in its path, or in its body (``field``
    then says which member names it, e.g. ``recording_id`` or ``robot``)."""


def found(row: T | None, what: str) -> T:
    """``row``, which a lookup of ``what`` (``"recording 3"``) gave; None is a NotFoundError
    saying that ``what`` does not exist."""
    if row is None:
        raise NotFoundError(f"{what} does not exist")
    return row


class ConflictError(ServiceError):
    """The resource exists but is not in a state that allows the request (not finished...)."""


class ParseLimitError(ServiceError):
    """An upload needed more memory or time to read than the server allows (413)."""

    title = "Payload Too Large"


class UnknownRobotError(NotFoundError):
    """A request names a robot that is neither built in nor uploaded (404 naming ``robot``:
    the set of robots changes with every upload, so no schema can list it)."""


class AnalysisPending(ConflictError):
    """A recording has no finished analysis with plot overlays yet.

    ``job`` is its newest analysis job (queued, running, failed or cancelled), or None when none
    was ever submitted, so the page can follow it, report it, or start one.
    """

    title = "No analysis yet"
    names_job = True
