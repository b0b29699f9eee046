"""The types every job function shares.

A job function is ``fn(payload, progress) -> output``: plain data in and out (numbers, strings,
bytes, lists, dicts and NumPy arrays; nothing of the database or the web), so it can run in a
forked process or on a Dask worker and its output can be pickled back.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from app.progress import ProgressFn

#: A job's input, built by the service layer from the stored request (each task's docstring
#: lists its keys).
Payload = dict[str, Any]
#: A job's output: ``"result"`` (JSON-safe dict) and, by kind, ``"arrays"`` (name -> float64
#: array), ``"template"``, ``"landmarks"``, ``"skeletons"``, ``"sidecar"``, ``"description"``.
JobResult = dict[str, Any]
#: A robot's spec in a payload: ``{"name"}`` for a built-in robot, or an uploaded one's
#: (``app.planning.robots.write_robot_files``).
RobotSpec = dict[str, Any]
#: A job function.
TaskFn = Callable[[Payload, ProgressFn], JobResult]
