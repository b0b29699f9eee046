"""Robots the service knows: the planning package's built-ins and uploaded URDF (+ MJCF) models.

Built-ins are described once (joints and limits, loaded through the job function
``app.jobs.tasks.describe_robot``) and cached; uploaded models are checked by loading them the
same way before they are stored, so a job never receives a model the planner cannot read.
"""

from __future__ import annotations

import functools
import threading
from typing import Any

from sqlalchemy.orm import Session

from app.db import crud
from app.db.blobs import BlobStore
from app.db.models import RobotRecord
from app.errors import BioPlanError
from app.jobs import tasks
from app.services.errors import ConflictError, NotFoundError, ServiceError, UnknownRobotError


def uploaded_robot(row: RobotRecord) -> dict[str, Any]:
    """The JSON form of an uploaded robot (``app.api.schemas.RobotInfo``)."""
    out = dict(row.description)
    out.update(
        name=row.name,
        builtin=False,
        payload=row.payload if row.payload is not None else out.get("payload"),
        has_mjcf=row.mjcf_sha256 is not None,
        urdf_name=row.urdf_name,
        mjcf_name=row.mjcf_name,
    )
    return out


class RobotCatalog:
    """Built-in and uploaded robots: descriptions, specs for jobs, uploads and deletions.

    Args:
        blobs: the file store that keeps uploaded models.
    """

    def __init__(self, *, blobs: BlobStore) -> None:
        self.blobs = blobs
        self._described: dict[str, dict[str, Any]] = {}
        self._lock = threading.Lock()

    @functools.cached_property
    def builtin(self) -> list[str]:
        """Names of the built-in robots."""
        return tasks.builtin_robots()

    def describe_builtin(self, name: str) -> dict[str, Any]:
        """Joints and limits of a built-in robot (loaded once, then cached)."""
        with self._lock:
            cached = self._described.get(name)
        if cached is None:
            cached = {**tasks.describe_robot({"name": name}), "builtin": True}
            with self._lock:
                self._described[name] = cached
        return dict(cached)

    def all(self, session: Session) -> list[dict[str, Any]]:
        """Built-in robots first, then uploaded ones."""
        out = [self.describe_builtin(name) for name in self.builtin]
        return out + [uploaded_robot(r) for r in crud.list_robots(session=session)]

    def describe(self, session: Session, name: str) -> dict[str, Any]:
        """One robot's description.

        Raises:
            NotFoundError: no such robot.
        """
        if name in self.builtin:
            return self.describe_builtin(name)
        row = crud.get_robot(session=session, name=name)
        if row is None:
            raise NotFoundError(f"robot {name!r} does not exist")
        return uploaded_robot(row)

    def _unknown(self, session: Session, name: str) -> UnknownRobotError:
        uploaded = [r.name for r in crud.list_robots(session=session)]
        names = sorted(self.builtin + uploaded)
        return UnknownRobotError(f"unknown robot {name!r} (expected one of {names})", field="robot")

    def joints(self, session: Session, name: str) -> list[str]:
        """Joint names of a built-in or uploaded robot.

        Raises:
            UnknownRobotError: no such robot.
        """
        if name in self.builtin:
            return list(self.describe_builtin(name)["joint_names"])
        row = crud.get_robot(session=session, name=name)
        if row is None:
            raise self._unknown(session, name)
        return list(row.description.get("joint_names", []))

    def spec(self, session: Session, name: str) -> dict[str, Any]:
        """The plain-data robot spec for a job: a built-in name, or the uploaded files.

        Raises:
            UnknownRobotError: no such robot.
        """
        if name in self.builtin:
            return {"name": name}
        row = crud.get_robot(session=session, name=name)
        if row is None:
            raise self._unknown(session, name)
        return {
            "name": row.name,
            "urdf": self.blobs.get(row.urdf_sha256),
            "urdf_name": row.urdf_name,
            "mjcf": None if row.mjcf_sha256 is None else self.blobs.get(row.mjcf_sha256),
            "mjcf_name": row.mjcf_name,
            "payload": row.payload,
        }

    def upload(
        self,
        session: Session,
        *,
        name: str,
        urdf: tuple[str, bytes],
        mjcf: tuple[str, bytes] | None,
        payload: float | None,
    ) -> dict[str, Any]:
        """Store a robot model after checking that the planning package can load it.

        Args:
            name: the name requests will use.
            urdf, mjcf: (the user's file name, the bytes).
            payload: default payload [kg], or None for the model's own.

        Raises:
            ConflictError: a robot of that name exists.
            ServiceError: the model cannot be loaded (``file`` names the URDF).
        """
        if name in self.builtin or crud.get_robot(session=session, name=name) is not None:
            raise ConflictError(f"a robot named {name!r} already exists", field="name")
        spec = {
            "name": name,
            "urdf": urdf[1],
            "mjcf": None if mjcf is None else mjcf[1],
            "payload": payload,
        }
        try:
            description = tasks.describe_robot(spec)
        except BioPlanError as exc:
            raise ServiceError(
                f"{urdf[0]}: cannot load the robot model: {exc}", file=urdf[0]
            ) from None
        row = crud.create_robot(
            session=session,
            blobs=self.blobs,
            name=name,
            urdf=urdf,
            mjcf=mjcf,
            payload=payload,
            description=description,
        )
        return uploaded_robot(row)

    def delete(self, session: Session, name: str) -> None:
        """Delete an uploaded robot.

        Raises:
            ConflictError: the robot is built in.
            NotFoundError: no such robot.
        """
        if name in self.builtin:
            raise ConflictError(f"{name!r} is built in and cannot be deleted")
        if not crud.delete_robot(session=session, blobs=self.blobs, name=name):
            raise NotFoundError(f"robot {name!r} does not exist")
