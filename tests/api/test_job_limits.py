"""The job caps (``app.services.limits``): each is set by its ``BIOPLAN_MAX_*`` variable, and a
request over it is refused naming the field, the limit and that variable."""

from __future__ import annotations

import pytest

from app.config import Settings
from app.services.errors import ServiceError
from app.services.limits import JobLimits

#: Each cap and the variable an operator sets it with (as the README and the errors name them).
VARIABLES = {
    "particles": "BIOPLAN_MAX_PARTICLES",
    "iterations": "BIOPLAN_MAX_ITERATIONS",
    "n_samples": "BIOPLAN_MAX_SAMPLES",
    "workers": "BIOPLAN_MAX_WORKERS",
    "cells": "BIOPLAN_MAX_SWEEP_CELLS",
}


@pytest.mark.parametrize(("cap", "variable"), sorted(VARIABLES.items()))
def test_each_cap_is_set_by_its_variable_and_named_when_passed(
    cap: str, variable: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv(variable, "20")
    limits = JobLimits.from_settings(Settings())
    assert getattr(limits, cap) == 20
    others = {name: getattr(limits, name) for name in VARIABLES if name != cap}
    assert 20 not in others.values()  # only this variable changed this cap
    if cap == "cells":  # 21 durations x 1 payload x 1 objective
        request: dict[str, object] = {
            "durations": [1.0] * 21, "payloads": [0.0], "objectives": ["abs_work"]
        }  # fmt: skip
    else:
        request = {cap: 21}
    with pytest.raises(ServiceError, match=rf"^{cap} 21 exceeds the limit 20 \({variable}\)$"):
        limits.check(request)
    limits.check({cap: 20} if cap != "cells" else {**request, "durations": [1.0] * 20})
