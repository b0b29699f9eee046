"""Dependencies shared by the routers: services, database session, settings, write access."""

from __future__ import annotations

import secrets
import time
from collections.abc import Iterator
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
