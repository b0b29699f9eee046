"""The job kinds: one record per kind, the part every layer may read.

A job kind is an operation the service runs in the background (an analysis, a plan, a sweep...).
Each layer adds its own part to the kind's record, keyed by the names here, so a new kind is
written in one place per layer and a test checks that every kind has every part:

- here (the kernel): its name and the URL segment its results are served under
  (``/api/<path>/<id>``);
- ``app.jobs.tasks.TASKS``: its task function (plain data in, plain data out);
- ``app.db.models.RESULT_MODELS``: its result table;
- ``app.services.kinds``: the full record (payload builder, result storage) the job service,
  the runner and the routers read.

Plain data only: no imports beyond the standard library.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal, get_args

#: The name of a job kind (also the API's ``JobKind`` enum).
KindName = Literal[
    "analysis", "pose", "plan", "simulation", "sweep", "profiles", "cohort", "identify", "front"
]


@dataclass(frozen=True)
class JobKindInfo:
    """What every layer knows of a job kind.

    Attributes:
        name: the kind, as stored in a job row (``"plan"``).
        path: the URL segment its results are served under (``/api/plans/<id>``).
        robot: its request names a robot (the payload carries the robot's spec).
        template: its request may name an analysis whose human template it uses.
    """

    name: KindName
    path: str
    robot: bool = False
    template: bool = False


#: Every job kind, by name, in the order lists show them.
JOB_KINDS: dict[str, JobKindInfo] = {
    k.name: k
    for k in (
        JobKindInfo("analysis", "analyses"),
        JobKindInfo("pose", "poses"),
        JobKindInfo("plan", "plans", robot=True, template=True),
        JobKindInfo("simulation", "simulations", robot=True, template=True),
        JobKindInfo("sweep", "sweeps", robot=True),
        JobKindInfo("profiles", "profiles", robot=True),
        JobKindInfo("cohort", "cohorts"),
        JobKindInfo("identify", "identifications"),
        JobKindInfo("front", "fronts", robot=True, template=True),
    )
}
#: The kinds' names (the ``KindName`` literal's values, in its order).
KIND_NAMES: tuple[str, ...] = get_args(KindName)
#: Where each kind's results are served: kind -> URL segment under ``/api/``.
KIND_PATHS: dict[str, str] = {k.name: k.path for k in JOB_KINDS.values()}


def result_url(kind: str, result_id: int) -> str:
    """The URL of a job's result (``/api/plans/7``); an unknown kind is served under its name."""
    return f"/api/{KIND_PATHS.get(kind, kind)}/{int(result_id)}"
