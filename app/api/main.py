"""The API router: includes one router per resource, nothing else."""

from __future__ import annotations

from fastapi import APIRouter

from app.api.routes import (
    analyses,
    cohorts,
    dashboard,
    fronts,
    jobs,
    meta,
    plans,
    poses,
    profiles,
    recordings,
    robot_logs,
    robots,
    simulations,
    sweeps,
)

api_router = APIRouter()
api_router.include_router(meta.router)
api_router.include_router(recordings.router)
api_router.include_router(analyses.router)
api_router.include_router(poses.router)
api_router.include_router(plans.router)
api_router.include_router(simulations.router)
api_router.include_router(sweeps.router)
api_router.include_router(fronts.router)
api_router.include_router(profiles.router)
api_router.include_router(cohorts.router)
api_router.include_router(jobs.router)
api_router.include_router(jobs.events_router)
api_router.include_router(robots.router)
api_router.include_router(robot_logs.router)
api_router.include_router(robot_logs.identifications)
api_router.include_router(dashboard.router)
