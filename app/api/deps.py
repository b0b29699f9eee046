"""Dependencies shared by the routers: services, database session, settings, write access."""

from __future__ import annotations

import secrets
import threading
import time
from collections import OrderedDict
from collections.abc import Hashable, Iterator
from dataclasses import dataclass, field
from typing import Annotated, Any

from fastapi import Depends, Request
from fastapi.security import HTTPAuthorizationCredentials, HTTPBearer
from sqlalchemy import Engine
from sqlalchemy.orm import Session, sessionmaker

from app.api.errors import ApiError
from app.config import Settings
from app.db.blobs import BlobStore
from app.jobs.broker import JobBroker
from app.jobs.service import JobService


class ResponseCache:
    """Serialized responses of frequent list requests, dropped whenever the data changes.

    Exact because this process is the only writer of the database: every write route calls
    :meth:`invalidate` after its commit, and a response computed while a write happened is not
    stored (the version it was computed at is stale).
    """

    def __init__(self, maxsize: int = 512) -> None:
        self.maxsize = maxsize
        self.version = 0
        self._items: OrderedDict[Hashable, tuple[int, bytes]] = OrderedDict()
        self._lock = threading.Lock()

    def get(self, key: Hashable) -> bytes | None:
        with self._lock:
            hit = self._items.get(key)
            if hit is None or hit[0] != self.version:
                return None
            self._items.move_to_end(key)
            return hit[1]

    def put(self, key: Hashable, version: int, body: bytes) -> None:
        with self._lock:
            if version != self.version:
                return
            self._items[key] = (version, body)
            self._items.move_to_end(key)
            while len(self._items) > self.maxsize:
                self._items.popitem(last=False)

    def invalidate(self) -> None:
        with self._lock:
            self.version += 1
            self._items.clear()


@dataclass
class Services:
    """Everything the routes use, built once per app by ``app.main``."""

    settings: Settings
    engine: Engine
    sessions: sessionmaker[Session]
    blobs: BlobStore
    broker: JobBroker
    jobs: JobService
    started: float = field(default_factory=time.monotonic)
    #: the 3-D viewer's address, set by whoever starts it (dashboard issue).
    viewer: dict[str, Any] = field(default_factory=dict)
    #: cached ``GET /api/recordings`` pages.
    recordings_cache: ResponseCache = field(default_factory=ResponseCache)


def get_services(request: Request) -> Services:
    services: Services = request.app.state.services
    return services


ServicesDep = Annotated[Services, Depends(get_services)]


def get_db(services: ServicesDep) -> Iterator[Session]:
    with services.sessions() as session:
        yield session


def get_settings(services: ServicesDep) -> Settings:
    return services.settings


def get_jobs(services: ServicesDep) -> JobService:
    return services.jobs


SessionDep = Annotated[Session, Depends(get_db)]
SettingsDep = Annotated[Settings, Depends(get_settings)]
RunnerDep = Annotated[JobService, Depends(get_jobs)]

_bearer = HTTPBearer(auto_error=False, description="BIOPLAN_API_TOKEN, required for writes")


def require_token(
    settings: SettingsDep,
    credentials: Annotated[HTTPAuthorizationCredentials | None, Depends(_bearer)],
) -> None:
    """Writes need ``Authorization: Bearer <BIOPLAN_API_TOKEN>`` when a token is set."""
    expected = settings.token
    if expected is None:
        return
    if credentials is None:
        raise ApiError(
            401,
            "this server requires an API token for writes: send 'Authorization: Bearer <token>'",
            headers={"WWW-Authenticate": "Bearer"},
        )
    if not secrets.compare_digest(credentials.credentials.encode(), expected.encode()):
        raise ApiError(401, "the API token is wrong", headers={"WWW-Authenticate": "Bearer"})


WriteAccess = Depends(require_token)
