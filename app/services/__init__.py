"""The service layer's orchestration: the one place that joins the database, the jobs and the
science packages.

``start_services(settings)`` builds a :class:`Services` (database migrated and open, file store,
job service with its runner, robot catalogue, recording overlays, comparisons for the viewer);
the API's routes call these and stay thin. Bad requests found here raise
:class:`~app.services.errors.ServiceError` (a ``BioPlanError``).
"""

from app.services.broker import ALL_JOBS, JobBroker, Subscription
from app.services.cache import ResponseCache
from app.services.comparisons import ComparisonLoader, load_robot_spec
from app.services.core import Services, start_services, stop_services
from app.services.demo import (
    DEMO_MUSCLES,
    DEMO_NAME,
    seed_demo,
    seed_into,
    synthetic_curls,
    synthetic_curls_csv,
)
from app.services.errors import (
    AnalysisPending,
    ConflictError,
    NotFoundError,
    ServiceError,
    UnknownRobotError,
)
from app.services.jobs import KIND_PATHS, JobService, job_summary, job_to_dict
from app.services.kinds import KINDS, JobKind
from app.services.overlays import RecordingOverlays
from app.services.recordings import parse_upload, store_recording
from app.services.robots import RobotCatalog, check_data_quota

__all__ = [
    "ALL_JOBS",
    "DEMO_MUSCLES",
    "DEMO_NAME",
    "KINDS",
    "KIND_PATHS",
    "AnalysisPending",
    "ComparisonLoader",
    "ConflictError",
    "JobBroker",
    "JobKind",
    "JobService",
    "NotFoundError",
    "RecordingOverlays",
    "ResponseCache",
    "RobotCatalog",
    "ServiceError",
    "Services",
    "Subscription",
    "UnknownRobotError",
    "check_data_quota",
    "job_summary",
    "job_to_dict",
    "load_robot_spec",
    "parse_upload",
    "seed_demo",
    "seed_into",
    "start_services",
    "stop_services",
    "store_recording",
    "synthetic_curls",
    "synthetic_curls_csv",
]
