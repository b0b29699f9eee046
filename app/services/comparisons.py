"""Finished plans, simulations and fronts' points, read from the database as the viewer's
``Comparison``, and what the dashboard shows of them: the Compare page's data and the HTML
exports."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray
from sqlalchemy.orm import Session, sessionmaker

from app.db.arrays import decode_arrays
from app.errors import BioPlanError, without_paths
from app.jobs.tasks import RobotSpec, robot_from_spec
from app.planning.export import public_result
from app.services.errors import ConflictError, NotFoundError, ServiceError
from app.services.job_views import not_finished
from app.services.results import get_result_row
from app.services.robots import RobotCatalog
from app.viewer.comparison import (
    KINDS,
    Comparison,
    Kind,
    NothingToCompare,
    comparison_from_arrays,
)
from app.viewer.export import report_html, scene_html
from app.viewer.scene import Layout, PreparedCache, PreparedComparison

if TYPE_CHECKING:
    from app.planning.robots import Robot


def load_robot_spec(
    spec: RobotSpec, payload: float | None, folder: Path | None = None
) -> tuple[Robot, str]:
    """Load a robot from a job spec: ``{"name"}`` (built in) or an uploaded robot's files.

    Args:
        spec: the robot's spec (``RobotCatalog.spec``).
        payload: [kg], or None for the robot's default.
        folder: where an uploaded robot's files are kept (``RobotCatalog.folder``), so the
            viewer can read its URDF and meshes later; None: a temporary folder.

    Returns:
        The robot (with ``payload`` kg, or its default when None) and its URDF text.
    """
    with robot_from_spec(spec, payload, folder=folder) as robot:
        return robot, Path(robot.urdf_path).read_text(encoding="utf-8")


class ComparisonLoader:
    """Reads finished plans and simulations as :class:`Comparison` (``(kind, id) -> ...``).

    Args:
        sessions: session factory of the service database.
        robots: the robot catalogue (uploaded robots' files).
    """

    def __init__(self, sessions: sessionmaker[Session], robots: RobotCatalog) -> None:
        self.sessions = sessions
        self.robots = robots

    def __call__(
        self, kind: str, result_id: int, methods: tuple[str, str] | None = None
    ) -> Comparison:
        """The comparison of plan or simulation ``result_id``.

        Args:
            kind: ``plan``, ``simulation`` or ``front``.
            result_id: its id.
            methods: the two planned methods to show (None: quintic and paper); for a front
                ``(point id, "quintic")`` (either way round).

        Raises:
            NotFoundError: unknown kind or id.
            ConflictError: the job has not succeeded (no result or arrays yet).
            NotFoundError: a method that this result did not plan (``field`` = methods).
        """
        if kind not in KINDS:
            raise NotFoundError(f"unknown comparison kind {kind!r} (expected one of {KINDS})")
        if kind == "front":
            return self._front_point(result_id, methods)
        result, arrays, spec = self._stored(kind, result_id)
        planned = list(result.get("methods") or ("quintic", "paper"))
        failed = result.get("method_errors") or {}
        for method in methods or ():
            if method not in planned:
                why = (
                    f"failed in {kind} {result_id} ({failed[method].get('error')})"
                    if isinstance(failed.get(method), dict)
                    else f"was not planned in {kind} {result_id}"
                )
                raise NotFoundError(
                    f"method '{method}' {why}: expected two of {', '.join(planned)}",
                    field="methods",
                )
        return self._compare(kind, result_id, arrays, result, self._robot(spec, result), methods)

    def _front_point(self, front_id: int, methods: tuple[str, str] | None) -> Comparison:
        """A point of front ``front_id`` beside the quintic at its duration, in the slots
        ``methods`` gives (solid, ghost): the point and ``quintic``, either way round.

        Raises:
            NotFoundError: no such front, or no such point (field ``pid``).
            ConflictError: the front has no result yet.
        """
        from app.services.fronts import point_arrays, viewed_point

        pid = viewed_point(methods)  # NotFoundError naming pid
        result, arrays, spec = self._stored("front", front_id)
        result.pop("motions", None)  # the exports' blocks: not the viewer's
        loaded = self._robot(spec, result)
        arrays = point_arrays(arrays, result, pid, loaded[0])
        return self._compare("front", front_id, arrays, result, loaded, methods)

    def _stored(
        self, kind: str, result_id: int
    ) -> tuple[dict[str, Any], dict[str, NDArray[np.generic]], RobotSpec]:
        """The finished result ``kind`` ``result_id``: (result JSON, decoded arrays, robot spec).

        Raises:
            NotFoundError: no such result.
            ConflictError: its job has not succeeded (no result or arrays yet).
        """
        with self.sessions() as session:
            row = get_result_row(session, kind, result_id, arrays=True)
            if row.result is None or row.arrays is None:
                raise not_finished(session, result_id, f"{kind} {result_id}", lacks="no result yet")
            return dict(row.result), decode_arrays(row.arrays), self.robots.spec(session, row.robot)

    def _robot(
        self, spec: RobotSpec, result: Mapping[str, Any]
    ) -> tuple[Robot, str, tuple[Path, ...] | None]:
        """The result's robot at its planned payload, its URDF text and the folders the viewer
        may read its meshes from (None: a built-in robot)."""
        payload = (result.get("conditions") or {}).get("payload")
        folder = self.robots.folder(spec)
        robot, urdf = load_robot_spec(spec, None if payload is None else float(payload), folder)
        return robot, urdf, None if folder is None else (folder,)

    def _compare(
        self,
        kind: Kind,
        result_id: int,
        arrays: Mapping[str, NDArray[np.generic]],
        result: dict[str, object],
        loaded: tuple[Robot, str, tuple[Path, ...] | None],
        methods: tuple[str, str] | None,
    ) -> Comparison:
        """The viewer's comparison of a stored result with its loaded robot (``_robot``)."""
        robot, urdf, roots = loaded
        return comparison_from_arrays(
            kind,
            result_id,
            arrays,
            result,
            robot,
            urdf=urdf,
            methods=methods,
            allowed_roots=roots,
        )


def prepare_comparison(
    cache: PreparedCache, kind: str, result_id: int, pair: tuple[str, str] | None
) -> PreparedComparison:
    """A finished plan or simulation prepared for the viewer (``Services.comparisons``), with
    methods ``pair`` shown as standard and optimised (None: the result's own pair).

    Raises:
        ConflictError: nothing to compare (field ``methods``), or no result yet.
        NotFoundError: no such result or method.
        ServiceError: the robot cannot be loaded (its name, never a server folder).
    """
    try:
        return cache(kind, result_id, pair)
    except NothingToCompare as exc:
        raise ConflictError(str(exc), field="methods") from None
    except ServiceError:
        raise  # unknown result or method, no result yet: already the service's own answer
    except BioPlanError as exc:
        raise ServiceError(without_paths(exc)) from None


def comparison_data(prepared: PreparedComparison, points: int) -> dict[str, Any]:
    """The Compare page's data: summary (phases, metrics, floors), ``curves`` per joint with
    ``points`` samples [SI units] and the public ``result``."""
    c = prepared.comparison
    out = c.summary()
    out["curves"] = c.curves(points=points)
    out["result"] = public_result(c.result)
    return out


def comparison_file(prepared: PreparedComparison, fmt: str, layout: Layout) -> str:
    """A self-contained HTML file: ``scene`` (3-D animation, robots ``side_by_side`` or
    ``ghost``) or ``report`` (curves and metrics)."""
    if fmt == "scene":
        return scene_html(prepared, layout=layout)
    return report_html(prepared.comparison)
