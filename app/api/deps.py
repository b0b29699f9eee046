"""Dependencies shared by the routers: services, database session, settings, write access.

Everything a request needs before its route runs lives here (the security issue adds origin
checks and caps beside ``require_token``), so there is one place to read what guards a route.
"""

from __future__ import annotations

import secrets
from collections.abc import Iterator
from typing import Annotated

from fastapi import Depends, Request
from fastapi.security import HTTPAuthorizationCredentials, HTTPBearer
from sqlalchemy.orm import Session

from app.api.errors import ApiError
from app.config import Settings
from app.services import JobService, RobotCatalog, Services


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


def get_robots(services: ServicesDep) -> RobotCatalog:
    return services.robots


SessionDep = Annotated[Session, Depends(get_db)]
SettingsDep = Annotated[Settings, Depends(get_settings)]
JobsDep = Annotated[JobService, Depends(get_jobs)]
RobotsDep = Annotated[RobotCatalog, Depends(get_robots)]

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
