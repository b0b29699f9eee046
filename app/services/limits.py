"""How much work one request may ask for: caps from the configuration, checked at submission.

Without them one request (``particles 1000, iterations 10000, n_samples 100000``) asked for
8.94 GiB, and ``workers: 64`` started 65 processes past ``BIOPLAN_MAX_WORKERS``. Each cap is a
``Settings`` field; a request over one is refused (422) naming the field, the limit and the
variable that sets it, before any job is queued.
"""

from __future__ import annotations

from collections.abc import Collection, Mapping
from dataclasses import dataclass
from typing import Any

from app.config import Settings
from app.services.errors import ServiceError


@dataclass(frozen=True)
class JobLimits:
    """Largest values a job's parameters may take (None: unlimited).

    Attributes:
        particles: PSO swarm size.
        iterations: PSO iterations.
        n_samples: optimiser grid points of the paper's method.
        workers: processes of a sweep on the local executor.
        cells: cells of a sweep (durations x payloads x objectives).
    """

    particles: int | None = None
    iterations: int | None = None
    n_samples: int | None = None
    workers: int | None = None
    cells: int | None = None

    @classmethod
    def from_settings(cls, settings: Settings) -> JobLimits:
        return cls(**{name: getattr(settings, field) for name, field in _SETTINGS.items()})

    def fit(
        self, params: Mapping[str, object], left_out: Collection[str] = ()
    ) -> dict[str, object]:
        """``params`` with each field the request ``left_out`` lowered to its cap (a server
        capped below a default still takes a request that does not ask for more), then
        checked.

        Raises:
            ServiceError: a field the request gave is above its cap (422 naming it).
        """
        out = dict(params)
        for name in REQUEST_FIELDS:
            limit, value = getattr(self, name), out.get(name)
            if name in left_out and limit is not None and isinstance(value, int) and value > limit:
                out[name] = limit
        self.check(out)
        return out

    def check(self, params: Mapping[str, object]) -> None:
        """Refuse ``params`` (a job's request) that ask for more than a cap.

        Raises:
            ServiceError: 422 naming the field, the limit and its variable.
        """
        for name, field in _SETTINGS.items():
            env = f"{_ENV_PREFIX}{field.upper()}"
            limit = getattr(self, name)
            value = _cells(params) if name == "cells" else params.get(name)
            if limit is not None and isinstance(value, int) and value > limit:
                raise ServiceError(f"{name} {value} exceeds the limit {limit} ({env})", field=name)


#: The caps that are one request field each (``cells`` is a product of three lists' lengths).
REQUEST_FIELDS = ("particles", "iterations", "n_samples", "workers")

#: The ``Settings`` field of each cap; the variable that sets it is the field's name in capitals
#: after the settings' prefix (``max_particles``: ``BIOPLAN_MAX_PARTICLES``).
_SETTINGS = {
    "particles": "max_particles",
    "iterations": "max_iterations",
    "n_samples": "max_samples",
    "workers": "max_workers",
    "cells": "max_sweep_cells",
}
_ENV_PREFIX = Settings.model_config.get("env_prefix", "")


def _cells(params: Mapping[str, object]) -> int | None:
    grid = [params.get(k) for k in ("durations", "payloads", "objectives")]
    if not all(isinstance(g, list) for g in grid):
        return None
    count = 1
    for g in grid:
        count *= len(g)  # type: ignore[arg-type]
    return count


#: The trajectory routes' query parameter whose schema maximum is ``BIOPLAN_MAX_EXPORT_SAMPLES``.
EXPORT_SAMPLES_PARAMETER = "samples"


def state_export_limit(schema: dict[str, Any], max_export_samples: int) -> None:
    """Every trajectory export's ``samples`` parameter goes no higher than this server's cap
    (``Settings.max_export_samples``), so a client learns it before it is refused."""
    for path in schema.get("paths", {}).values():
        for operation in path.values():
            for param in operation.get("parameters", []) if isinstance(operation, dict) else []:
                if param.get("name") != EXPORT_SAMPLES_PARAMETER or param.get("in") != "query":
                    continue
                for branch in param.get("schema", {}).get("anyOf", [param.get("schema", {})]):
                    if branch.get("type") == "integer":
                        branch["maximum"] = max_export_samples
