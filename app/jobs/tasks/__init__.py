"""Job functions: plain data in, plain data out, no database, no web framework.

One module per domain: ``recordings`` (parse an upload, analyse a session, video to pose),
``cohorts``, ``robots`` (a job's robot from its spec, uploaded robots described), ``planning``
(plan, simulate, sweep, profiles), ``fronts`` and ``robot_logs`` (validate, identify). They are
the only places where the service layer calls the science packages, and they import the heavy
ones inside the functions, so the API process starts without loading them and a Dask worker
only needs ``app`` on its path. Every job function has the signature
``fn(payload, progress) -> JobResult``, its payload its kind's ``TypedDict`` (``types``; the
registry holds them as ``types.TaskFn``); ``progress`` takes a structured
``app.progress.Progress`` and may raise to stop the job (cancellation on Dask).

:data:`TASKS` is the jobs' part of the job-kind registry (``app.kinds``): kind -> function.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import TypeVar, cast

from app.jobs.tasks.cohorts import cohort
from app.jobs.tasks.fronts import front
from app.jobs.tasks.planning import plan, profiles, simulate, sweep
from app.jobs.tasks.recordings import analyse, extract_pose_job, parse_recording
from app.jobs.tasks.robot_logs import identify_robot, validate_log
from app.jobs.tasks.robots import (
    UPLOAD_NAMES,
    builtin_robots,
    default_task_safety,
    describe_robot,
    package_members,
    robot_from_spec,
)
from app.jobs.tasks.types import JobResult, Payload, RobotSpec, TaskFn, robot_options
from app.progress import ProgressFn

__all__ = [
    "TASKS",
    "UPLOAD_NAMES",
    "JobResult",
    "Payload",
    "RobotSpec",
    "TaskFn",
    "analyse",
    "builtin_robots",
    "cohort",
    "default_task_safety",
    "describe_robot",
    "extract_pose_job",
    "front",
    "identify_robot",
    "package_members",
    "parse_recording",
    "plan",
    "preload",
    "profiles",
    "robot_from_spec",
    "robot_options",
    "run_task",
    "simulate",
    "sweep",
    "validate_log",
]

_P = TypeVar("_P", bound=Mapping[str, object])


def _task(fn: Callable[[_P, ProgressFn], JobResult]) -> TaskFn:
    """A job function under the registry's common type. Each function takes its kind's
    ``*Payload``; the registry holds them as taking any payload (a cast: the service builds the
    payload of the job's kind, ``app.services.kinds``, so kind and payload type agree)."""
    return cast("TaskFn", fn)


#: Job kind -> its function (every kind of ``app.kinds.JOB_KINDS``; a test checks both ways).
TASKS: dict[str, TaskFn] = {
    "analysis": _task(analyse),
    "pose": _task(extract_pose_job),
    "plan": _task(plan),
    "simulation": _task(simulate),
    "sweep": _task(sweep),
    "profiles": _task(profiles),
    "cohort": _task(cohort),
    "identify": _task(identify_robot),
    "front": _task(front),
}


def run_task(kind: str, payload: Payload, progress: ProgressFn) -> JobResult:
    """Run the job function of ``kind`` (the runners' single entry point)."""
    try:
        fn = TASKS[kind]
    except KeyError:
        raise ValueError(f"unknown job kind {kind!r} (expected one of {sorted(TASKS)})") from None
    return fn(payload, progress)


def preload() -> None:
    """Import the science packages and what the readers import when they first meet a format
    (used by the local runner's fork server, Dask workers and the upload sandbox).

    Job processes are forked from a server that already ran this, so a job starts in
    milliseconds instead of importing NumPy, SciPy and Pinocchio each time; a sandboxed read
    finds the readers' libraries (CSV tables, MAT 7.3, EDF, robot sidecars) imported before it
    limits its memory, so a limit refuses a file's data, never a library's code
    (``app.services.sandbox``).
    """
    import xml.etree.ElementTree  # noqa: F401

    import h5py  # noqa: F401
    import mujoco  # noqa: F401
    import pinocchio  # noqa: F401
    import pyarrow
    import pyarrow.compute
    import pyarrow.csv  # noqa: F401
    import pyedflib  # noqa: F401
    import scipy.signal  # noqa: F401
    import yaml  # noqa: F401

    import app.analysis
    import app.planning.dynamics
    import app.planning.planner
    import app.planning.robots
    import app.recordings
    import app.simulation  # noqa: F401
