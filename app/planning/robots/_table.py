"""Rows of the robots' parameter tables (``curtain_wall_parameters``, ``human_arm_parameters``)."""

from __future__ import annotations


def parameter_row(name: str, value: object, unit: str, source: str) -> dict[str, object]:
    """One parameter of a table: its name, value in ``unit`` and where it comes from."""
    return {"name": name, "value": value, "unit": unit, "source": source}
