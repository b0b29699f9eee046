"""Service settings: one ``Settings`` object read from ``BIOPLAN_*`` environment variables.

The science packages never read these; only the service layer (``app.main``, ``app.api``,
``app.services``, ``app.db``, ``app.jobs``) and the ``serve``/``submit`` commands do.
"""

from __future__ import annotations

import ipaddress
import re
from importlib.resources import files
from pathlib import Path
from typing import Annotated, Any, Literal

from pydantic import Field, SecretStr, field_validator, model_validator
from pydantic_settings import BaseSettings, NoDecode, SettingsConfigDict

from app.names import MAX_VIDEO_SECONDS

_DASK_ADDRESS = re.compile(r"^(dask|tcp|tls)://[^\s/:]+:\d{1,5}$")

#: The dashboard's pages as shipped inside the installed package (``app/frontend``).
PACKAGED_PAGES = Path(str(files("app") / "frontend"))


def is_loopback(host: str) -> bool:
    """True for ``localhost`` and loopback IP literals (127.0.0.0/8, ::1)."""
    if host.strip().lower() == "localhost":
        return True
    try:
        return ipaddress.ip_address(host.strip("[]")).is_loopback
    except ValueError:
        return False


class Settings(BaseSettings):
    """Service configuration (environment variables ``BIOPLAN_<NAME>``).

    Attributes:
        data_dir: folder for the SQLite database and the content-addressed file store.
        database_url: SQLAlchemy URL; defaults to SQLite ``<data_dir>/bioplan.db``. PostgreSQL
            works with the same code: ``postgresql+psycopg://user:pass@host:5432/db``.
        executor: ``"local"`` (a process per job, on this machine) or a Dask scheduler address
            ``dask://HOST:PORT`` (``tcp://`` is accepted too).
        max_workers: jobs that run at the same time on the local executor.
        job_max_attempts: how many times a job may be started in all; a job found running after
            a crash or restart is run again while it has attempts left, else marked failed.
        api_token: when set, every write (POST, PUT, DELETE) needs
            ``Authorization: Bearer <token>``.
        host, port: where ``bioplan serve`` binds; a non-loopback host needs ``api_token``.
        max_upload_mb: largest request body accepted [MB], enforced while it streams in.
        max_json_kb: largest body of a request that is not an upload (JSON) [KiB].
        max_parallel_parses: uploads (recordings, robots) parsed at once; more wait their turn.
        parse_memory_mb, parse_seconds: memory [MB] and time [s] one uploaded file (recording
            or robot model) may take to read, in a child process; past either it is refused
            with 413 and the server is unaffected.
        head_timeout_s: seconds a client has to send a complete request head (request line and
            headers) after connecting or after the previous response; then it is disconnected.
        cors_origins: origins allowed by CORS (none by default: CORS closed); they may also
            write across sites.
        allowed_hosts: names the server answers to in the ``Host`` header besides the loopback
            names and ``host`` (DNS rebinding: a page on another site that resolves its own name
            to 127.0.0.1 is refused); a wildcard bind (0.0.0.0) with none listed answers any.
        protect_reads: with ``api_token`` set, reads of ``/api`` need the token too (only
            ``/api/health`` and ``/api/meta`` stay open).
        viewer: start the 3-D viewer with the server.
        viewer_host, viewer_port: where the viewer binds (viser takes the next free port when
            this one is busy; ``GET /api/viewer`` reports the real one).
        viewer_token_ttl_s: seconds a viewer capability (the token in the Compare page's iframe
            address, one per comparison) stays valid after the API last handed it out.
        viewer_max_connections, viewer_max_per_token: viewer connections at once, in all and
            per capability (the excess is refused at the handshake).
        frontend_dir: the dashboard's pages (default: those shipped inside the package).
        max_video_seconds: longest uploaded video turned into pose [s] (refused at upload when
            its container states a longer duration; the pose job stops at it otherwise).
        max_particles, max_iterations, max_samples, max_sweep_cells: the most PSO particles,
            iterations, optimiser grid points and sweep cells one request may ask for (422
            above; a sweep's ``workers`` is capped by ``max_workers`` the same way).
        max_export_samples: the most samples one trajectory export may hold for a robot of up
            to six free joints (fewer for more joints: samples x joints stays within six times
            this); a ``rate`` or ``samples`` asking for more is refused (422).
        job_time_limit_s: wall-clock seconds a job may run on the local executor before it is
            stopped and failed with "time limit" (unset: no limit).
        min_free_mb: free disk space [MB] under which ``/api/health`` says "degraded".
        max_mesh_mb, max_mesh_triangles: the largest mesh [MB, decoded] and the most triangles
            of one mesh in an uploaded robot package (422 at upload; the viewer skips a
            stored mesh past either instead of parsing it).
        max_robot_unpacked_mb: what one robot package may unpack to in all [MB] (422 past it).
        data_quota_mb: disk space [MB] the data directory may take in all; an upload that
            would pass it (its unpacked files counted) is refused with 413.
        max_streams, max_streams_per_client: open event streams (``/api/events/jobs``,
            ``/api/jobs/{id}/events``) at once, in all and per client address; more are
            refused with 429 and ``Retry-After``.
        stream_idle_s: seconds an event stream stays open without a change to report
            (keep-alive comments do not count); then it ends and the browser reconnects.
        job_memory_mb: memory [MB] a local job process may take beyond what it starts with
            (``RLIMIT_AS``; unset: no limit); past it the job fails with "ran out of memory".
        max_queued: jobs waiting to run at once; a submission beyond it is refused with 429
            and nothing is stored.
        result_inline_kb: a job result's JSON larger than this [KiB] is kept in the file
            store, the database holding a reference (read back transparently).
        log_level: the server's log level.
    """

    model_config = SettingsConfigDict(env_prefix="BIOPLAN_", extra="ignore")

    data_dir: Path = Path("data")
    database_url: str | None = None
    executor: str = "local"
    max_workers: int = Field(default=2, ge=1, le=256)
    job_max_attempts: int = Field(default=2, ge=1, le=10)
    api_token: SecretStr | None = None
    host: str = "127.0.0.1"
    port: int = Field(default=8000, ge=1, le=65535)
    max_upload_mb: float = Field(default=200.0, gt=0)
    max_json_kb: float = Field(default=256.0, gt=0)
    max_parallel_parses: int = Field(default=2, ge=1, le=64)
    parse_memory_mb: float = Field(default=2048.0, ge=16)
    parse_seconds: float = Field(default=120.0, gt=0)
    head_timeout_s: float = Field(default=10.0, gt=0, le=3600)
    cors_origins: Annotated[list[str], NoDecode] = Field(default_factory=list)
    allowed_hosts: Annotated[list[str], NoDecode] = Field(default_factory=list)
    protect_reads: bool = False
    viewer: bool = True
    viewer_host: str = "127.0.0.1"
    viewer_port: int = Field(default=8080, ge=1, le=65535)
    viewer_token_ttl_s: float = Field(default=3600.0, gt=0, le=7 * 86400)
    viewer_max_connections: int = Field(default=32, ge=1, le=10000)
    viewer_max_per_token: int = Field(default=4, ge=1, le=1000)
    frontend_dir: Path | None = None
    max_video_seconds: float = Field(default=MAX_VIDEO_SECONDS, gt=0, le=86400)  # F2: videos
    max_particles: int = Field(default=400, ge=2)
    max_iterations: int = Field(default=2000, ge=1)
    max_samples: int = Field(default=2000, ge=10)
    max_sweep_cells: int = Field(default=400, ge=1)
    max_export_samples: int = Field(default=200_000, ge=2)
    job_time_limit_s: float | None = Field(default=3600.0, gt=0)
    min_free_mb: float = Field(default=200.0, ge=0)
    max_mesh_mb: float = Field(default=64.0, gt=0, le=1024)
    max_mesh_triangles: int = Field(default=2_000_000, ge=1)
    max_robot_unpacked_mb: float = Field(default=256.0, gt=0, le=1024)
    data_quota_mb: float = Field(default=20480.0, gt=0)
    max_streams: int = Field(default=64, ge=1, le=100000)
    max_streams_per_client: int = Field(default=8, ge=1, le=100000)
    stream_idle_s: float = Field(default=300.0, gt=0, le=86400)
    job_memory_mb: float | None = Field(default=4096.0, ge=16)
    max_queued: int = Field(default=100, ge=1, le=1000000)
    result_inline_kb: float = Field(default=1024.0, ge=0)
    log_level: Literal["debug", "info", "warning", "error"] = "info"

    @field_validator("cors_origins", "allowed_hosts", mode="before")
    @classmethod
    def _split_origins(cls, value: Any) -> Any:
        # Environment variables carry a comma-separated list; JSON lists are accepted too.
        if isinstance(value, str):
            text = value.strip()
            if text.startswith("["):
                import json

                return json.loads(text)
            return [v.strip() for v in text.split(",") if v.strip()]
        return value

    @field_validator("api_token", mode="before")
    @classmethod
    def _empty_token_is_none(cls, value: Any) -> Any:
        if isinstance(value, str) and not value.strip():
            return None
        return value

    @field_validator("job_memory_mb", mode="before")
    @classmethod
    def _no_memory_limit(cls, value: Any) -> Any:
        # BIOPLAN_JOB_MEMORY_MB= (empty) or "none": jobs run without a memory limit.
        if isinstance(value, str) and value.strip().lower() in ("", "none"):
            return None
        return value

    @field_validator("executor")
    @classmethod
    def _check_executor(cls, value: str) -> str:
        value = value.strip()
        if value == "local" or _DASK_ADDRESS.match(value):
            return value
        raise ValueError(f"executor must be 'local' or 'dask://HOST:PORT', got {value!r}")

    @field_validator("database_url")
    @classmethod
    def _check_url(cls, value: str | None) -> str | None:
        if value is None or not value.strip():
            return None
        if "://" not in value:
            raise ValueError(
                "database_url must be an SQLAlchemy URL such as 'sqlite:///path/bioplan.db' or "
                f"'postgresql+psycopg://user@host/db', got {value!r}"
            )
        return value.strip()

    @model_validator(mode="after")
    def _refuse_open_bind(self) -> Settings:
        # The viewer streams every plan's poses: it is as open as the API, so the same rule.
        for name, host in (("BIOPLAN_HOST", self.host), ("BIOPLAN_VIEWER_HOST", self.viewer_host)):
            if not is_loopback(host) and self.api_token is None:
                raise ValueError(
                    f"refusing to bind to non-loopback host {host!r} ({name}) without an API "
                    "token: set BIOPLAN_API_TOKEN (or bind to 127.0.0.1)"
                )
        return self

    @property
    def db_url(self) -> str:
        """The database URL in use (explicit, or SQLite in ``data_dir``)."""
        if self.database_url:
            return self.database_url
        return f"sqlite:///{(self.data_dir / 'bioplan.db').resolve()}"

    @property
    def pages_dir(self) -> Path:
        """The folder of the dashboard's pages in use (``frontend_dir`` or the packaged one)."""
        return self.frontend_dir if self.frontend_dir is not None else PACKAGED_PAGES

    @property
    def blob_dir(self) -> Path:
        """Folder of uploaded files, stored by SHA-256 (never by the user's file name)."""
        return self.data_dir / "blobs"

    @property
    def max_upload_bytes(self) -> int:
        return int(self.max_upload_mb * 1024 * 1024)

    @property
    def dask_address(self) -> str | None:
        """``tcp://HOST:PORT`` of the Dask scheduler, or None for the local executor."""
        if self.executor == "local":
            return None
        return re.sub(r"^dask://", "tcp://", self.executor)

    @property
    def token(self) -> str | None:
        return None if self.api_token is None else self.api_token.get_secret_value()
