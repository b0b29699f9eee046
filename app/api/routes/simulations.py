"""Simulations: submit (202 + job), list, fetch, rename, arrays and the trajectory as a file
(the routes ``app.api.routes._results`` makes)."""

from __future__ import annotations

from fastapi import APIRouter

from app.api.routes._common import PROBLEM_RESPONSES
from app.api.routes._results import ResultRoutes, add_result_routes
from app.api.schemas import SimulationRequest

router = APIRouter(prefix="/api/simulations", tags=["simulations"], responses=PROBLEM_RESPONSES)

_SUBMIT_DOC = (
    "Queue a simulation (``bioplan simulate``); the result is the CLI's ``--json`` output."
)
add_result_routes(
    router, ResultRoutes.robot_task("simulation", SimulationRequest, submit=_SUBMIT_DOC)
)
