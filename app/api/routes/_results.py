"""One router factory for the result kinds (plans, simulations, profiles, sweeps, fronts,
cohorts, analyses, poses, identifications): the submit, list, get, relabel, arrays, trajectory
and delete routes they share, made from a declarative ``ResultRoutes`` per kind. A router keeps
only its own routes (plans' ``/compare``, cohorts' ``/csv``...).

Every endpoint here takes keyword arguments and states its parameters in ``__signature__``, so
the path parameter keeps each kind's name (``{plan_id}``, ``{cohort_id}``...) in the OpenAPI
document and the query parameters their constraints.
"""

from __future__ import annotations

import contextlib
import inspect
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Annotated, Any

from fastapi import APIRouter, Query, Response
from pydantic import BaseModel
from sqlalchemy.orm import Session

from app.api.checks import check_task
from app.api.deps import RobotsDep, ServicesDep, SessionDep, WriteAccess
from app.api.errors import ApiError
from app.api.result_models import RESULT_OUT_MODELS
from app.api.routes._common import (
    EXPORT_RESPONSES,
    MAX_POINTS,
    ArrayNames,
    ExportOptions,
    FormatQuery,
    IdPath,
    MethodQuery,
    RateQuery,
    export_response,
)
from app.api.schemas import ArraysOut, Job, JobState, LabelPatch, Page, ResultOut, left_out
from app.services import Services
from app.services.errors import ConflictError
from app.services.results import (
    delete_job,
    export_file,
    get_result_row,
    job_of,
    list_results,
    relabel,
    result_arrays,
    result_out,
)

__all__ = ["ROBOT_FILTER", "ResultRoutes", "add_result_routes", "robot_task"]

#: The ``robot`` filter of a list (a robot's name as stored).
ROBOT_FILTER = Annotated[str | None, Query(max_length=100)]

#: A page of results: ``(session, *, limit, offset, state, **filters) -> (items, total)``.
PageFn = Callable[..., tuple[list[dict[str, Any]], int]]
#: One result as served: ``(session, result_id) -> item``.
ItemFn = Callable[[Session, int], dict[str, Any]]
#: An item (listed or fetched) as the kind serves it: ``(session, item) -> item``.
ShapeFn = Callable[[Session, dict[str, Any]], dict[str, Any]]
#: Validate a request and queue its job: ``(body, session, services) -> job``.
SubmitFn = Callable[[Any, Session, Services], dict[str, Any]]

_KW = inspect.Parameter.KEYWORD_ONLY
_EMPTY = inspect.Parameter.empty
_SESSION = ("session", SessionDep, _EMPTY)
_LIST_DEFAULTS: tuple[tuple[str, Any, Any], ...] = (
    ("limit", Annotated[int, Query(ge=1, le=500)], 50),
    ("offset", Annotated[int, Query(ge=0, le=10**9)], 0),
    ("state", JobState | None, None),
)
_TRAJECTORY_QUERIES: tuple[tuple[str, Any, Any], ...] = (
    ("format", FormatQuery, inspect.Parameter.empty),
    ("rate", RateQuery, None),
    ("method", MethodQuery, None),
    ("options", ExportOptions, inspect.Parameter.empty),
)

_RELABEL_DOC = "Give the {noun} a short name (shown in every list), or remove it with ``null``."
_DELETE_DOC = (
    "Delete a {noun} (its job and result); one still queued or running is cancelled first."
)
_TRAJECTORY_DOC = """One method's trajectory as a file (``bioplan export``): csv, json, yaml (ROS 2
    JointTrajectory), mcap (rosbag2), script (URScript) or mot (OpenSim); ``docs/export.md``.
    A file past the robot's limits or into a contact is refused (409) unless ``force`` /
    ``allow_unsafe``, which the file records."""


@dataclass(frozen=True)
class ResultRoutes:
    """What the shared routes of one result kind are made from.

    Attributes:
        kind: the stored kind (``app.db.models.RESULT_MODELS``), e.g. ``"plan"``.
        noun: the singular in route names and messages (``get_plan``, "plan 3 does not exist");
            default ``kind``.
        plural: the plural in the list route's name (``list_plans``); default ``noun`` + "s".
        response_model: what list items and fetched results are (a ``Page`` of it for lists);
            default the kind's typed model of ``RESULT_OUT_MODELS``. Served with
            ``exclude_unset``: a field a stored result lacks is not added as null.
        filters: the list's query parameters beside ``limit``, ``offset`` and ``state``: name to
            annotated type, each defaulting to None and handed to ``page`` by name.
        page: a page of items; default ``list_results`` of ``kind``.
        item: one result; default ``result_out`` of ``kind``.
        shape: applied to every listed and fetched item (adds or rewrites fields).
        submit, request: ``POST ""`` (202 + the job, ``Location`` its result) when given.
        label, arrays, trajectory, delete: which of the optional routes the kind has.
        docs: route descriptions by operation (``submit``, ``list``, ``get``, ``relabel``,
            ``arrays``, ``trajectory``, ``delete``); relabel, delete and trajectory have defaults.
        names: operation names that differ from ``<op>_<noun>`` (``list_<plural>``).
    """

    kind: str
    noun: str = ""
    plural: str = ""
    response_model: Any = ResultOut
    filters: Mapping[str, Any] = field(default_factory=dict)
    page: PageFn | None = None
    item: ItemFn | None = None
    shape: ShapeFn | None = None
    submit: SubmitFn | None = None
    request: type[BaseModel] | None = None
    label: bool = False
    arrays: bool = False
    trajectory: bool = False
    delete: bool = False
    docs: Mapping[str, str] = field(default_factory=dict)
    names: Mapping[str, str] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if self.response_model is ResultOut:  # the kind's typed result (app.api.result_models)
            object.__setattr__(self, "response_model", RESULT_OUT_MODELS.get(self.kind, ResultOut))
        object.__setattr__(self, "noun", self.noun or self.kind)
        object.__setattr__(self, "plural", self.plural or f"{self.noun}s")

    @classmethod
    def robot_task(cls, kind: str, request: type[BaseModel], **docs: str) -> ResultRoutes:
        """A plan or simulation: submitted with ``robot_task``, listed by robot, relabelled,
        its arrays and trajectory files served."""
        return cls(
            kind, filters={"robot": ROBOT_FILTER}, submit=robot_task(kind), request=request,
            label=True, arrays=True, trajectory=True, docs=docs,
        )  # fmt: skip

    @property
    def id_name(self) -> str:
        """The path parameter's name (``plan_id``)."""
        return f"{self.noun}_id"

    def name(self, op: str) -> str:
        """The operation's route name (its OpenAPI summary and operationId come from it)."""
        default = {
            "list": f"list_{self.plural}",
            "arrays": f"get_{self.noun}_arrays",
            "trajectory": f"get_{self.noun}_trajectory",
        }.get(op, f"{op}_{self.noun}")
        return self.names.get(op, default)

    def doc(self, op: str) -> str | None:
        """The operation's description."""
        if op in self.docs:
            return self.docs[op]
        defaults = {"relabel": _RELABEL_DOC, "delete": _DELETE_DOC, "trajectory": _TRAJECTORY_DOC}
        return defaults[op].format(noun=self.noun) if op in defaults else None


def robot_task(kind: str) -> SubmitFn:
    """The submit of a plan or simulation: the planner's refusals first (``check_task``), then
    the job with the request's fields as its params."""

    def submit(body: Any, session: Session, services: Services) -> dict[str, Any]:
        check_task(body, session, services)
        return services.jobs.submit(
            kind=kind,
            params=body.model_dump(mode="json", exclude={"label"}),
            resource={"robot": body.robot},
            label=body.label,
            left_out=left_out(body),
        )

    return submit


def _endpoint(
    fn: Callable[..., Any], name: str, doc: str | None, params: list[tuple[str, Any, Any]]
) -> Callable[..., Any]:
    """``fn`` (keyword arguments only) with the signature FastAPI reads its parameters from."""
    fn.__name__ = fn.__qualname__ = name
    fn.__doc__ = doc
    fn.__signature__ = inspect.Signature(  # type: ignore[attr-defined]
        [inspect.Parameter(n, _KW, annotation=a, default=d) for n, a, d in params]
    )
    return fn


def add_result_routes(router: APIRouter, spec: ResultRoutes) -> None:
    """Add the shared routes of ``spec``'s kind to ``router`` (whose prefix is the kind's), in
    this order: submit, list, get, relabel, delete, arrays, trajectory (each when ``spec``
    asks for it)."""
    if spec.submit is not None:
        _add_submit(router, spec, spec.submit)
    _add_list(router, spec)
    _add_get(router, spec)
    if spec.label:
        _add_relabel(router, spec)
    if spec.delete:
        _add_delete(router, spec)
    if spec.arrays:
        _add_arrays(router, spec)
    if spec.trajectory:
        _add_trajectory(router, spec)


def _id_param(spec: ResultRoutes) -> tuple[str, Any, Any]:
    """The path parameter of one result, named after the kind (``plan_id``...)."""
    return (spec.id_name, IdPath, _EMPTY)


def _one(spec: ResultRoutes, session: Session, result_id: int) -> dict[str, Any]:
    """One result as the kind serves it (its own ``item`` and ``shape`` when it has them)."""
    kind = spec.kind
    out = spec.item(session, result_id) if spec.item else result_out(session, kind, result_id)
    return spec.shape(session, out) if spec.shape else out


def _add_submit(router: APIRouter, spec: ResultRoutes, submit_fn: SubmitFn) -> None:
    """``POST ""``: queue a job (202, its ``Location`` the result's URL)."""
    if spec.request is None:
        raise ValueError(f"{spec.kind}: a submit needs its request model (request=...)")

    def submit(**kw: Any) -> dict[str, Any]:
        job = submit_fn(kw["body"], kw["session"], kw["services"])
        kw["response"].headers["Location"] = job["result_url"]
        return job

    router.post("", status_code=202, response_model=Job, dependencies=[WriteAccess])(
        _endpoint(
            submit,
            spec.name("submit"),
            spec.doc("submit"),
            [
                ("body", spec.request, _EMPTY),
                _SESSION,
                ("services", ServicesDep, _EMPTY),
                ("response", Response, _EMPTY),
            ],
        )
    )


def _add_list(router: APIRouter, spec: ResultRoutes) -> None:
    """``GET ""``: a page of results, with the kind's filters."""

    def list_(**kw: Any) -> dict[str, Any]:
        session, limit, offset = kw.pop("session"), kw["limit"], kw["offset"]
        if spec.page is not None:
            items, total = spec.page(session, **kw)
        else:
            items, total = list_results(session, spec.kind, **kw)
        if spec.shape is not None:
            items = [spec.shape(session, item) for item in items]
        return {"items": items, "total": total, "limit": limit, "offset": offset}

    filters = [(name, annotation, None) for name, annotation in spec.filters.items()]
    page_model: Any = Page  # a generic built at run time (mypy reads ``Page[x]`` as a type)
    router.get(
        "", response_model=page_model[spec.response_model], response_model_exclude_unset=True
    )(
        _endpoint(
            list_,
            spec.name("list"),
            spec.doc("list"),
            [_SESSION, *_LIST_DEFAULTS, *filters],
        )
    )


def _add_get(router: APIRouter, spec: ResultRoutes) -> None:
    """``GET /{id}``: one result."""
    id_name = spec.id_name

    def get(**kw: Any) -> dict[str, Any]:
        return _one(spec, kw["session"], kw[id_name])

    router.get(
        f"/{{{id_name}:int}}", response_model=spec.response_model, response_model_exclude_unset=True
    )(_endpoint(get, spec.name("get"), spec.doc("get"), [_SESSION, _id_param(spec)]))


def _add_relabel(router: APIRouter, spec: ResultRoutes) -> None:
    """``PATCH /{id}``: set or clear a result's label."""
    id_name = spec.id_name

    def relabel_(**kw: Any) -> dict[str, Any]:
        session, result_id = kw["session"], kw[id_name]
        out = relabel(session, spec.kind, result_id, kw["body"].label)
        return _one(spec, session, result_id) if spec.item or spec.shape else out

    router.patch(
        f"/{{{id_name}:int}}",
        response_model=spec.response_model,
        response_model_exclude_unset=True,
        dependencies=[WriteAccess],
    )(
        _endpoint(
            relabel_,
            spec.name("relabel"),
            spec.doc("relabel"),
            [_SESSION, _id_param(spec), ("body", LabelPatch, _EMPTY)],
        )
    )


def _add_delete(router: APIRouter, spec: ResultRoutes) -> None:
    """``DELETE /{id}``: a result and its job (a queued or running job is cancelled first)."""
    id_name = spec.id_name

    def delete(**kw: Any) -> Response:
        services, session, result_id = kw["services"], kw["session"], kw[id_name]
        get_result_row(session, spec.kind, result_id)  # 404 when there is none
        if job_of(session, result_id)["state"] in ("queued", "running"):
            with contextlib.suppress(ConflictError):  # it ended meanwhile
                services.jobs.cancel(result_id)
        if not delete_job(session, services.blobs, result_id):
            raise ApiError(404, f"{spec.noun} {result_id} does not exist")
        return Response(status_code=204)

    router.delete(f"/{{{id_name}:int}}", status_code=204, dependencies=[WriteAccess])(
        _endpoint(
            delete,
            spec.name("delete"),
            spec.doc("delete"),
            [("services", ServicesDep, _EMPTY), _SESSION, _id_param(spec)],
        )
    )


def _add_arrays(router: APIRouter, spec: ResultRoutes) -> None:
    """``GET /{id}/arrays``: a result's stored arrays, down-sampled to ``points``."""
    id_name = spec.id_name

    def arrays(**kw: Any) -> dict[str, Any]:
        return result_arrays(
            kw["session"], spec.kind, kw[id_name], points=kw["points"], names=kw["name"]
        )

    router.get(f"/{{{id_name}:int}}/arrays", response_model=ArraysOut)(
        _endpoint(
            arrays,
            spec.name("arrays"),
            spec.doc("arrays"),
            [
                _SESSION,
                _id_param(spec),
                ("points", Annotated[int, Query(ge=2, le=MAX_POINTS)], 500),
                ("name", ArrayNames, None),
            ],
        )
    )


def _add_trajectory(router: APIRouter, spec: ResultRoutes) -> None:
    """``GET /{id}/trajectory``: a result's motion as an export file."""
    id_name = spec.id_name

    def trajectory(**kw: Any) -> Response:
        # export_file's refusals are 404, 409 and 422 naming the field.
        out = export_file(
            kw["session"],
            kw["robots"],
            spec.kind,
            kw[id_name],
            fmt=kw["format"],
            rate=kw["rate"],
            method=kw["method"],
            **kw["options"],
        )
        return export_response(out, kw["format"])

    router.get(
        f"/{{{id_name}:int}}/trajectory", response_class=Response, responses=EXPORT_RESPONSES
    )(
        _endpoint(
            trajectory,
            spec.name("trajectory"),
            spec.doc("trajectory"),
            [_SESSION, ("robots", RobotsDep, _EMPTY), _id_param(spec), *_TRAJECTORY_QUERIES],
        )
    )
