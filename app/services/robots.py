"""Robots the service knows: the planning package's built-ins and uploaded URDF (+ MJCF) models.

Built-ins are described once (joints and limits, loaded through the job function
``app.jobs.tasks.describe_robot``) and cached; uploaded models are checked by loading them the
same way before they are stored, so a job never receives a model the planner cannot read.
"""

from __future__ import annotations

import functools
import os
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

from sqlalchemy.orm import Session

from app.db import crud
from app.db.blobs import BlobStore
from app.db.models import RobotRecord
from app.errors import BioPlanError
from app.jobs import tasks
from app.jobs.tasks import RobotSpec, robot_options
from app.services.errors import (
    ConflictError,
    NotFoundError,
    ParseLimitError,
    ServiceError,
    UnknownRobotError,
    found,
)
from app.services.sandbox import read_untrusted

if TYPE_CHECKING:
    from app.config import Settings
    from app.planning.robots import MeshLimits

_MB = 1024 * 1024
#: The settings behind each ``MeshLimits`` cap, named in a refusal.
_SETTING_OF = {
    "max_bytes": "BIOPLAN_MAX_MESH_MB",
    "max_triangles": "BIOPLAN_MAX_MESH_TRIANGLES",
    "max_unpacked": "BIOPLAN_MAX_ROBOT_UNPACKED_MB",
}


class DataQuotaError(ParseLimitError):
    """An upload that would take the data directory past its quota (413 naming
    ``BIOPLAN_DATA_QUOTA_MB``): refused before anything of it is written."""

    title = "Payload Too Large"


@dataclass(frozen=True)
class UploadLimits:
    """What an uploaded robot may hold and where it is counted against the quota.

    Attributes:
        mesh: caps on each mesh and on a package's unpacked total.
        data_dir: the data directory the quota is for (None: no quota).
        quota_bytes: disk space the data directory may take in all [bytes].
    """

    mesh: MeshLimits = field(default_factory=lambda: _mesh_limits())
    data_dir: Path | None = None
    quota_bytes: int | None = None

    @classmethod
    def from_settings(cls, settings: Settings) -> UploadLimits:
        return cls(
            mesh=mesh_limits(settings),
            data_dir=settings.data_dir,
            quota_bytes=int(settings.data_quota_mb * _MB),
        )


def _mesh_limits() -> MeshLimits:
    from app.planning.robots import MeshLimits

    return MeshLimits()


def mesh_limits(settings: Settings) -> MeshLimits:
    """The mesh caps of ``settings`` (``BIOPLAN_MAX_MESH_MB``, ``BIOPLAN_MAX_MESH_TRIANGLES``,
    ``BIOPLAN_MAX_ROBOT_UNPACKED_MB``)."""
    from app.planning.robots import MeshLimits

    return MeshLimits(
        max_bytes=int(settings.max_mesh_mb * _MB),
        max_triangles=settings.max_mesh_triangles,
        max_unpacked=int(settings.max_robot_unpacked_mb * _MB),
    )


def _tree_bytes(folder: Path) -> int:
    """Disk space the files under ``folder`` take [bytes] (allocated blocks: a sparse file
    counts what it holds), without following links."""
    total, pending = 0, [str(folder)]
    while pending:
        try:
            entries = os.scandir(pending.pop())
        except OSError:
            continue  # gone meanwhile, or unreadable: not ours to count
        with entries:
            for entry in entries:
                try:
                    if entry.is_dir(follow_symlinks=False):
                        pending.append(entry.path)
                    else:
                        total += entry.stat(follow_symlinks=False).st_blocks * 512
                except OSError:
                    continue
    return total


def check_data_quota(
    data_dir: Path | None,
    quota_bytes: int | None,
    file: str,
    needed: int,
    *,
    what: str = "this upload",
) -> None:
    """Refuse an upload of ``needed`` bytes that the data directory's quota cannot hold,
    before anything of it is written (robots and recordings alike).

    Raises:
        DataQuotaError: 413 naming ``file`` and ``BIOPLAN_DATA_QUOTA_MB``.
    """
    if data_dir is None or quota_bytes is None:
        return
    used = data_usage(data_dir)
    if used + needed > quota_bytes:
        raise DataQuotaError(
            f"{file}: storing {what} needs {needed / _MB:.1f} MB and the data directory "
            f"already holds {used / _MB:.1f} MB of its {quota_bytes / _MB:.0f} MB quota "
            "(BIOPLAN_DATA_QUOTA_MB)",
            file=file,
        )


_usage_cache: dict[Path, tuple[float, int]] = {}
_usage_lock = threading.Lock()


def data_usage(folder: Path, *, max_age_s: float = 0.0) -> int:
    """Disk space the data directory ``folder`` takes [bytes]; with ``max_age_s``, a figure
    measured that recently for the same question may be reused (``/api/health`` is polled);
    without, it is measured afresh (an upload's quota check)."""
    key = Path(folder).resolve()
    if max_age_s <= 0:
        return _tree_bytes(key)
    now = time.monotonic()
    with _usage_lock:
        cached = _usage_cache.get(key)
    if cached is not None and now - cached[0] <= max_age_s:
        return cached[1]
    used = _tree_bytes(key)
    with _usage_lock:
        _usage_cache[key] = (now, used)
    return used


#: The uploaded robot's options kept with it (``app.jobs.tasks.robot_from_spec``).
_OPTION_KEYS = (
    "shoulder_joint",
    "elbow_joint",
    "locks",
    "base_link",
    "tip_link",
    "urdf_member",
    "mjcf_member",
    "sidecar_member",
)


def uploaded_robot(row: RobotRecord) -> dict[str, object]:
    """The JSON form of an uploaded robot (``app.api.schemas.RobotInfo``)."""
    out = dict(row.description)
    out.update(
        name=row.name,
        builtin=False,
        payload=row.payload if row.payload is not None else out.get("payload"),
        has_mjcf=row.mjcf_sha256 is not None or bool((row.options or {}).get("mjcf_member")),
        urdf_name=row.urdf_name,
        mjcf_name=row.mjcf_name,
    )
    return out


#: Largest lock value accepted [deg or m]; anything larger is a typing error.
_LOCK_LIMIT = 1e6


def parse_locks(entries: list[str]) -> dict[str, float]:
    """``NAME=VALUE`` entries (degrees, or metres for prismatic joints) as a dict.

    Raises:
        ServiceError: an entry without ``=``, a value that is not a finite number, a repeat.
    """
    import math

    out: dict[str, float] = {}
    for entry in entries:
        name, sep, value = entry.partition("=")
        name = name.strip()
        if not sep or not name:
            raise ServiceError(f"lock {entry!r}: expected NAME=VALUE", field="lock")
        try:
            number = float(value)
        except ValueError:
            raise ServiceError(
                f"lock {entry!r}: expected a number after '='", field="lock"
            ) from None
        if not math.isfinite(number) or abs(number) > _LOCK_LIMIT:
            raise ServiceError(f"lock {entry!r}: expected a finite number", field="lock")
        if name in out:
            raise ServiceError(f"lock {name!r} is given twice", field="lock")
        out[name] = number
    return out


def _field_of(message: str) -> str | None:
    """The upload field a robot loader's message is about."""
    for needle, name in (
        ("shoulder joint '", "shoulder_joint"),
        ("elbow joint '", "elbow_joint"),
        ("shoulder and elbow", "elbow_joint"),
        ("base_link", "base_link"),
        ("tip_link", "base_link"),
        ("lock", "lock"),
        ("robot.yaml", "sidecar"),
        ("sidecar", "sidecar"),
        ("member", "package"),
        ("archive", "package"),
        ("zip", "package"),
    ):
        if needle in message:
            return name
    return None


def _load_error(main: str, exc: BioPlanError, sidecar: tuple[str, bytes] | None) -> ServiceError:
    """The 422 of a model that cannot be loaded: a fault of the uploaded sidecar names the
    sidecar's file (it is kept as ``robot.yaml``), anything else the model file."""
    message = str(exc)
    prefix = f"{tasks.UPLOAD_NAMES['sidecar']}: "
    if sidecar is not None and message.startswith(prefix):
        name = sidecar[0]
        return ServiceError(f"{name}: {message[len(prefix) :]}", file=name, field="sidecar")
    return ServiceError(
        f"{main}: cannot load the robot model: {message}", file=main, field=_field_of(message)
    )


class RobotCatalog:
    """Built-in and uploaded robots: descriptions, specs for jobs, uploads and deletions.

    Args:
        blobs: the file store that keeps uploaded models.
    """

    def __init__(self, *, blobs: BlobStore, files_dir: Path | None = None) -> None:
        self.blobs = blobs
        #: where uploaded robots' folders are kept (meshes for the viewer); in the data folder.
        self.files_dir = files_dir if files_dir is not None else blobs.root.parent / "robots"
        self._described: dict[str, dict[str, object]] = {}
        self._lock = threading.Lock()

    @functools.cached_property
    def builtin(self) -> list[str]:
        """Names of the built-in robots."""
        return tasks.builtin_robots()

    def describe_builtin(self, name: str) -> dict[str, object]:
        """Joints and limits of a built-in robot (loaded once, then cached)."""
        with self._lock:
            cached = self._described.get(name)
        if cached is None:
            cached = {**tasks.describe_robot({"name": name}), "builtin": True}
            with self._lock:
                self._described[name] = cached
        return dict(cached)

    def all(self, session: Session) -> list[dict[str, object]]:
        """Built-in robots first, then uploaded ones."""
        out = [self.describe_builtin(name) for name in self.builtin]
        return out + [uploaded_robot(r) for r in crud.list_robots(session=session)]

    def describe(self, session: Session, name: str) -> dict[str, object]:
        """One robot's description.

        Raises:
            NotFoundError: no such robot.
        """
        if name in self.builtin:
            return self.describe_builtin(name)
        return uploaded_robot(found(crud.get_robot(session=session, name=name), f"robot {name!r}"))

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
            names = self.describe_builtin(name)["joint_names"]
            return [str(n) for n in names] if isinstance(names, list) else []
        row = crud.get_robot(session=session, name=name)
        if row is None:
            raise self._unknown(session, name)
        return list(row.description.get("joint_names", []))

    def spec(self, session: Session, name: str) -> RobotSpec:
        """The plain-data robot spec for a job: a built-in name, or the uploaded files.

        Raises:
            UnknownRobotError: no such robot.
        """
        if name in self.builtin:
            return {"name": name}
        row = crud.get_robot(session=session, name=name)
        if row is None:
            raise self._unknown(session, name)
        options = row.options or {}

        def blob(sha: str | None) -> bytes | None:
            return None if sha is None else self.blobs.get(sha)

        return {
            "name": row.name,
            "urdf": blob(row.urdf_sha256),
            "urdf_name": row.urdf_name,
            "mjcf": blob(row.mjcf_sha256),
            "mjcf_name": row.mjcf_name,
            "package": blob(row.package_sha256),
            "sidecar": blob(row.sidecar_sha256),
            "payload": row.payload,
            **robot_options(options),
        }

    def folder(self, spec: RobotSpec) -> Path | None:
        """The kept folder of an uploaded robot's files (None for a built-in robot).

        Named by a digest of the files and options, so the same upload reuses it and a
        different one never sees stale files.
        """
        import hashlib
        import json

        if all(spec.get(k) is None for k in ("urdf", "mjcf", "package")):
            return None
        digest = hashlib.sha256()
        files = (spec.get("urdf"), spec.get("mjcf"), spec.get("package"), spec.get("sidecar"))
        for key, data in zip(("urdf", "mjcf", "package", "sidecar"), files, strict=True):
            digest.update(key.encode() + hashlib.sha256(data or b"").digest())
        options = {k: spec.get(k) for k in _OPTION_KEYS}
        digest.update(json.dumps(options, sort_keys=True).encode())
        self.files_dir.mkdir(parents=True, exist_ok=True)
        return self.files_dir / digest.hexdigest()[:24]

    def upload(
        self,
        session: Session,
        *,
        name: str,
        urdf: tuple[str, bytes] | None,
        mjcf: tuple[str, bytes] | None,
        payload: float | None,
        package: tuple[str, bytes] | None = None,
        sidecar: tuple[str, bytes] | None = None,
        options: dict[str, object] | None = None,
        limits: UploadLimits | None = None,
    ) -> dict[str, object]:
        """Store a robot model after checking that the planning package can load it.

        Args:
            name: the name requests will use.
            urdf, mjcf, package, sidecar: (the user's file name, the bytes) or None; a
                package is a zip of the robot's folder (model files, meshes, a sidecar).
            payload: default payload [kg], or None for the sidecar's or the model's own.
            options: ``shoulder_joint``, ``elbow_joint`` (names), ``locks`` (name -> degrees,
                or metres for prismatic joints), ``urdf_member``, ``mjcf_member``,
                ``sidecar_member`` (files inside the package).
            limits: caps on a package's meshes and unpacked size, and the data directory's
                quota (default: the library's mesh caps, no quota).

        Raises:
            ConflictError: a robot of that name exists.
            ServiceError: no model, or the model cannot be loaded, or a package's mesh or
                unpacked size past its cap: the message names the file (the member) and the
                joint or the limit, ``field`` the request field.
            DataQuotaError: storing it would take the data directory past its quota (413).
        """
        if name in self.builtin or crud.get_robot(session=session, name=name) is not None:
            raise ConflictError(f"a robot named {name!r} already exists", field="name")
        opts = {k: v for k, v in (options or {}).items() if k in _OPTION_KEYS and v}
        if package is not None:
            opts = self._package_members(package, opts, urdf is None, mjcf is None)
        elif urdf is None and mjcf is None:
            raise ServiceError("give a urdf, an mjcf or a package (zip)", field="urdf")
        spec: RobotSpec = {
            "name": name,
            "urdf": None if urdf is None else urdf[1],
            "urdf_name": None if urdf is None else urdf[0],
            "mjcf": None if mjcf is None else mjcf[1],
            "mjcf_name": None if mjcf is None else mjcf[0],
            "package": None if package is None else package[1],
            "sidecar": None if sidecar is None else sidecar[1],
            "payload": payload,
            **robot_options(opts),
        }
        main = next(f for f in (urdf, mjcf, package) if f is not None)[0]
        limits = limits if limits is not None else UploadLimits()
        unpacked = 0 if package is None else self._check_package(package, limits)
        singles = sum(len(f[1]) for f in (urdf, mjcf, sidecar) if f is not None)
        stored = singles + (0 if package is None else len(package[1]))
        self._check_quota(main, limits, stored + singles + unpacked)  # blobs + kept folder
        try:
            describe = functools.partial(tasks.describe_robot, folder=self.folder(spec))
            description = read_untrusted(describe, spec, what=main)
        except ParseLimitError:
            raise  # a 413 naming the limit, not a model the planner cannot load
        except BioPlanError as exc:
            raise _load_error(main, exc, sidecar) from None
        if package is not None:
            description["files"] = tasks.package_members(package[1])
        row = crud.create_robot(
            session=session,
            blobs=self.blobs,
            name=name,
            urdf=urdf,
            mjcf=mjcf,
            package=package,
            sidecar=sidecar,
            options=opts,
            payload=payload,
            description=description,
        )
        return uploaded_robot(row)

    @staticmethod
    def _check_package(package: tuple[str, bytes], limits: UploadLimits) -> int:
        """Check a package's meshes and unpacked total against ``limits`` (in the parse
        sandbox: compressed members are read); what it unpacks to [bytes].

        Raises:
            ServiceError: a mesh or the total past a cap (422 naming the member, the cap and
                its setting), or a zip that is not one.
        """
        from app.planning.robots import MeshLimitError, check_package_zip

        name = package[0]
        check = functools.partial(check_package_zip, name=name, limits=limits.mesh)
        try:
            return read_untrusted(check, package[1], what=name)
        except MeshLimitError as exc:
            raise ServiceError(
                f"{exc} (the server's {_SETTING_OF.get(exc.limit, 'limit')})",
                file=name,
                field="package",
            ) from None
        except ParseLimitError:
            raise
        except BioPlanError as exc:
            raise ServiceError(str(exc), file=name, field="package") from None

    @staticmethod
    def _check_quota(main: str, limits: UploadLimits, needed: int) -> None:
        """Refuse a robot of ``needed`` bytes (its stored files and its kept folder, a
        package unpacked) that the data directory's quota cannot hold (DataQuotaError)."""
        check_data_quota(
            limits.data_dir,
            limits.quota_bytes,
            main,
            needed,
            what="this robot (its files unpacked)",
        )

    @staticmethod
    def _package_members(
        package: tuple[str, bytes], opts: dict[str, object], need_urdf: bool, need_mjcf: bool
    ) -> dict[str, object]:
        """The package's model and sidecar members: named ones, else its only URDF/MJCF/YAML."""
        import zipfile

        try:
            members = tasks.package_members(package[1])
        except (zipfile.BadZipFile, OSError) as exc:
            raise ServiceError(
                f"{package[0]}: not a readable zip archive ({exc})", file=package[0],
                field="package",
            ) from None  # fmt: skip
        out = dict(opts)
        urdfs = [m["path"] for m in members if m["role"] == "urdf"]
        mjcfs = [
            m["path"]
            for m in members
            if m["role"] == "mjcf" and m["path"].rsplit("/", 1)[-1] != "package.xml"
        ]
        if need_urdf and "urdf_member" not in out and len(urdfs) > 1:
            raise ServiceError(
                f"{package[0]} holds {len(urdfs)} URDF files {urdfs}: name one in urdf_member",
                field="urdf_member",
            )
        if need_urdf and "urdf_member" not in out and urdfs:
            out["urdf_member"] = urdfs[0]
        # An MJCF is only guessed for an MJCF-only package; a sidecar is never guessed (a ROS
        # package holds other YAML files).
        if need_urdf and need_mjcf and not urdfs and "mjcf_member" not in out:
            if len(mjcfs) != 1:
                raise ServiceError(
                    f"{package[0]} holds no URDF and {len(mjcfs)} MJCF files {mjcfs}: expected "
                    "one robot model (name it in urdf_member or mjcf_member)",
                    file=package[0],
                    field="package",
                )
            out["mjcf_member"] = mjcfs[0]
        return out

    def delete(self, session: Session, name: str) -> None:
        """Delete an uploaded robot.

        Raises:
            ConflictError: the robot is built in.
            NotFoundError: no such robot.
        """
        if name in self.builtin:
            raise ConflictError(f"{name!r} is built in and cannot be deleted")
        row = crud.get_robot(session=session, name=name)
        folder = None if row is None else self.folder(self.spec(session, name))
        if not crud.delete_robot(session=session, blobs=self.blobs, name=name):
            raise NotFoundError(f"robot {name!r} does not exist")
        if folder is not None and folder.exists():
            import shutil

            shutil.rmtree(folder, ignore_errors=True)
