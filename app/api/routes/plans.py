"""Plans: submit (202 + job), list, fetch results and arrays, compare two plans."""

from __future__ import annotations

import math
from typing import Annotated, TypeGuard

from fastapi import APIRouter, Query

from app.api.deps import SessionDep
from app.api.routes._common import PROBLEM_RESPONSES
from app.api.routes._results import ResultRoutes, add_result_routes
from app.api.schemas import PlanComparison, PlanRequest
from app.services.job_views import not_finished
from app.services.results import get_result_row

router = APIRouter(prefix="/api/plans", tags=["plans"], responses=PROBLEM_RESPONSES)


def _diff(a: object, b: object) -> dict[str, object] | None:
    def number(x: object) -> TypeGuard[float]:
        return isinstance(x, int | float) and not isinstance(x, bool) and math.isfinite(x)

    def one(x: float, y: float) -> tuple[float, float | None]:
        return y - x, (100.0 * (y - x) / abs(x) if x != 0 else None)

    if number(a) and number(b):
        d, pct = one(a, b)
        return {"a": a, "b": b, "diff": d, "diff_pct": pct}
    if (
        isinstance(a, list)
        and isinstance(b, list)
        and len(a) == len(b)
        and all(number(x) for x in a + b)
    ):
        pairs = [one(x, y) for x, y in zip(a, b, strict=True)]
        return {"a": a, "b": b, "diff": [d for d, _ in pairs], "diff_pct": [p for _, p in pairs]}
    return None


def _compare_metrics(ma: dict[str, object], mb: dict[str, object]) -> dict[str, object]:
    out: dict[str, object] = {}
    for key in ma:
        if key in mb and (d := _diff(ma[key], mb[key])) is not None:
            out[key] = d
    return out


@router.get("/compare", response_model=PlanComparison)
def compare_plans(
    session: SessionDep,
    a: Annotated[int, Query(ge=1, le=2**31 - 1, description="first plan id")],
    b: Annotated[int, Query(ge=1, le=2**31 - 1, description="second plan id")],
) -> dict[str, object]:
    """Metric by metric, ``b - a`` and ``100 (b - a) / |a|`` for both trajectories."""
    results = []
    for pid in (a, b):
        row = get_result_row(session, "plan", pid)
        if row.result is None:
            raise not_finished(session, pid, f"plan {pid}")
        results.append(row.result)
    ra, rb = results
    return {
        "a": a,
        "b": b,
        "conditions": {"a": ra.get("conditions", {}), "b": rb.get("conditions", {})},
        "standard": _compare_metrics(ra.get("standard", {}), rb.get("standard", {})),
        "optimized": _compare_metrics(ra.get("optimized", {}), rb.get("optimized", {})),
        "improvement_pct": {"a": ra.get("improvement_pct", {}), "b": rb.get("improvement_pct", {})},
    }


_SUBMIT_DOC = "Queue a plan (``bioplan plan``); the result is the CLI's ``--json`` output."
_ARRAYS_DOC = "Time grid and, per trajectory, q, qd, qdd, tau [SI], power [W], energy [J]."
add_result_routes(
    router, ResultRoutes.robot_task("plan", PlanRequest, submit=_SUBMIT_DOC, arrays=_ARRAYS_DOC)
)
