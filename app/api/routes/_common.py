"""HTTP-only helpers shared by the routers: path and query types, documented answers, the
export download; what they read comes from ``app.services``."""

from __future__ import annotations

from datetime import UTC, datetime
from pathlib import PurePosixPath
from typing import TYPE_CHECKING, Annotated, Literal, TypedDict

from fastapi import Depends, Path, Query, Response
from pydantic import BeforeValidator, Field

from app.api.deps import SettingsDep
from app.api.errors import ApiError
from app.api.schemas import Problem
from app.names import METHODS
from app.services.results import ExportFile

#: Ids in paths: positive and within a 32-bit integer, so no database overflows.
IdPath = Annotated[int, Path(ge=1, le=2**31 - 1)]
#: The most samples per series a read returns: enough for min/max decimation on any screen
#: (two per pixel of a 4K plot); 100 000 let 16 clients push other requests' p99 to 11 s.
MAX_POINTS = 10_000


class FileAnswer(TypedDict):
    """The route arguments of a GET whose 200 is a file, not JSON (:func:`file_answer`)."""

    response_class: type[Response]
    responses: dict[int | str, dict[str, object]]


def file_answer(
    media_type: str, description: str, response_class: type[Response] = Response
) -> FileAnswer:
    """The route arguments of a GET whose 200 is a file of ``media_type``, not JSON: its
    response class and the OpenAPI ``responses`` that name the media type."""
    responses: dict[int | str, dict[str, object]] = {
        200: {"content": {media_type: {}}, "description": description}
    }
    return {"response_class": response_class, "responses": responses}


#: The error answers every route documents, with the problem's schema.
PROBLEM_RESPONSES: dict[int | str, dict[str, object]] = {
    code: {
        "description": desc,
        "content": {"application/problem+json": {"schema": Problem.model_json_schema()}},
    }
    for code, desc in (
        (400, "the body cannot be parsed as its Content-Type says"),
        (401, "API token missing or wrong"),
        (404, "not found"),
        (409, "conflict"),
        (413, "request body too large"),
        (422, "invalid request"),
        (429, "too many requests: waiting jobs or open event streams at their cap (Retry-After)"),
    )
}


#: Media type of each export format (``app.planning.export.FORMATS``).
EXPORT_MEDIA_TYPES: dict[str, str] = {
    "csv": "text/csv",
    "json": "application/json",
    "yaml": "application/yaml",
    "mcap": "application/octet-stream",
    "script": "text/plain",
    "mot": "text/plain",
}
#: The trajectory routes' documented answers: a file of one of the export media types.
EXPORT_RESPONSES: dict[int | str, dict[str, object]] = {
    200: {
        "description": "the export file",
        "content": {media: {} for media in sorted(set(EXPORT_MEDIA_TYPES.values()))},
    }
}
#: Names of stored arrays (``t``, ``standard_q``, ``bound_energy``...).
ArrayNames = Annotated[
    list[Annotated[str, Field(pattern=r"^[a-z][a-z0-9_]*$", max_length=64)]] | None,
    Query(description="array names (default: all); one this result lacks is a 404"),
]
#: Highest export rate [Hz] (``app.planning.export.MAX_RATE_HZ``).
MAX_EXPORT_RATE_HZ = 20_000.0

if TYPE_CHECKING:
    ExportFormatName = str
    ExportMethod = str
else:
    ExportFormatName = Literal[tuple(EXPORT_MEDIA_TYPES)]
    ExportMethod = Literal[tuple(METHODS)]

FormatQuery = Annotated[ExportFormatName, Query(description="export format")]
RateQuery = Annotated[
    float | None,
    Query(gt=0, le=MAX_EXPORT_RATE_HZ, description="sample rate [Hz] (default: the format's)"),
]
MethodQuery = Annotated[
    ExportMethod | None, Query(description="method to export (default: the optimised one)")
]
SamplesQuery = Annotated[
    int | None,
    Query(
        ge=2,
        description="samples over the motion instead of a rate (rate = (samples - 1) / "
        "duration); the schema's maximum is this server's BIOPLAN_MAX_EXPORT_SAMPLES, which "
        "also caps what a rate may ask for (fewer for robots of more than six joints)",
    ),
]
ForceQuery = Annotated[
    bool,
    Query(
        description="export although a sample leaves the robot's limits (position, speed, "
        "stated acceleration, torque) or a URScript for a robot that is not a UR; the file "
        "records what was exceeded (default: 409)"
    ),
]
AllowUnsafeQuery = Annotated[
    bool,
    Query(
        description="export a method the plan's collision check found in contact; the file "
        "records the first contact (default: 409)"
    ),
]
GoalQuery = Annotated[
    bool,
    Query(
        description="yaml: a control_msgs/action/FollowJointTrajectory goal instead of the "
        "bare trajectory_msgs/msg/JointTrajectory"
    ),
]
#: A ROS 2 name (``app.planning.export`` refuses anything else).
ROS_NAME_PATTERN = r"^/?[A-Za-z_][A-Za-z0-9_]*(/[A-Za-z_][A-Za-z0-9_]*)*$"
#: Decimal numbers separated by commas (degrees).
_NUMBER = r"\s*[-+]?(\d+(\.\d*)?|\.\d+)([eE][-+]?\d+)?\s*"
DEGREES_LIST_PATTERN = rf"^{_NUMBER}(,{_NUMBER})*$"
TopicQuery = Annotated[
    str | None,
    Query(
        max_length=256,
        pattern=ROS_NAME_PATTERN,
        description="yaml, mcap: the controller's topic (or action, with goal), e.g. "
        "/scaled_joint_trajectory_controller/joint_trajectory (default: /joint_trajectory; "
        "goal: /joint_trajectory_controller/follow_joint_trajectory)",
    ),
]
FromPositionQuery = Annotated[
    str | None,
    Query(
        max_length=1024,
        pattern=DEGREES_LIST_PATTERN,
        description="yaml, mcap: the arm's current joint positions [deg], comma separated, one "
        "per joint: the file first approaches the plan's start from there",
    ),
]


def export_options(
    settings: SettingsDep,
    samples: SamplesQuery = None,
    force: ForceQuery = False,
    allow_unsafe: AllowUnsafeQuery = False,
    goal: GoalQuery = False,
    topic: TopicQuery = None,
    from_position: FromPositionQuery = None,
) -> dict[str, object]:
    """The export query options every trajectory download takes beside its format, rate and
    method, with this server's sample cap (``app.services.results.export_trajectory``'s
    keyword arguments)."""
    return {
        "samples": samples,
        "max_samples": settings.max_export_samples,
        "force": force,
        "allow_unsafe": allow_unsafe,
        "goal": goal,
        "topic": topic,
        "from_position": from_position,
    }


#: ``export_options`` as a dependency (its query parameters are the route's).
ExportOptions = Annotated[dict[str, object], Depends(export_options)]


def export_response(out: ExportFile, fmt: str) -> Response:
    """An export file (``app.services.results.ExportFile``) streamed as an attachment of
    format ``fmt``'s media type."""
    from fastapi.responses import StreamingResponse

    return StreamingResponse(
        out.chunks,
        media_type=EXPORT_MEDIA_TYPES[fmt],
        headers={"Content-Disposition": f'attachment; filename="{out.filename}"'},
    )


def _iso_only(value: object) -> object:
    """Refuse a bare number as a date (pydantic would read ``0.5`` as a Unix time)."""
    if isinstance(value, str):
        try:
            float(value)
        except ValueError:
            return value
        raise ValueError(f"{value!r} is a number: expected an ISO 8601 date, e.g. 2026-11-26")
    return value


#: A date and time in a query, ISO 8601 only ("2026-11-26" or "2026-11-26T08:00:00Z").
IsoDateTimeQuery = Annotated[
    datetime | None,
    BeforeValidator(_iso_only),
    Query(description="ISO 8601 date or date and time (UTC when no zone is given)"),
]


def utc(value: datetime | None, field: str) -> datetime | None:
    """A query datetime in UTC (naive values are taken as UTC)."""
    if value is None:
        return None
    try:
        return value.astimezone(UTC) if value.tzinfo else value.replace(tzinfo=UTC)
    except (OverflowError, ValueError):
        raise ApiError(422, f"{field} is out of range: {value!r}", field=field) from None


def upload_name(name: str | None, fallback: str, *, field: str) -> str:
    """An uploaded file's base name, kept as metadata only (storage is by content hash).

    Raises:
        ApiError: 422 when the name holds control characters (a NUL byte was stored and its
            download then dropped the connection).
    """
    raw = name or ""
    if any(ord(ch) < 32 or ord(ch) == 127 for ch in raw):
        shown = raw.encode("unicode_escape").decode("ascii")
        raise ApiError(
            422,
            f"file name {shown!r} contains control characters: rename the file",
            field=field,
            file=shown,
        )
    base = PurePosixPath(raw.replace("\\", "/")).name.strip()
    return base[:255] or fallback
