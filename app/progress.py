"""Structured progress of long computations (PSO, optimal control, simulation, sweeps, analysis).

Long functions take ``progress: ProgressFn | None`` and call it with a :class:`Progress`: which
stage runs, how many of its units are done, the overall fraction, the best objective so far when
there is one, and a human line. The CLI draws a bar from it; jobs send it to the server as plain
data (``Progress.to_dict``) and the dashboard reads the fields, never the message text.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import asdict, dataclass
from typing import Any

__all__ = ["Progress", "ProgressFn", "no_progress", "report", "within"]


@dataclass(frozen=True)
class Progress:
    """Where a long computation is.

    Attributes:
        stage: what runs now, a short identifier (``read``, ``analyse``, ``pso``,
            ``optimal_control``, ``simulate``, ``sweep``, ``pose``, ``report``, ``done``).
        done: units of this stage finished (iterations, cells, frames, files), >= 0.
        of: units this stage has in all, >= 1.
        fraction: fraction of the whole computation done, in [0, 1].
        best: best objective value so far (PSO, IPOPT), or None.
        message: one line for people.
    """

    stage: str
    done: int
    of: int
    fraction: float
    best: float | None = None
    message: str = ""

    def __post_init__(self) -> None:
        frac = float(self.fraction)
        object.__setattr__(self, "fraction", min(max(frac, 0.0), 1.0) if frac == frac else 0.0)
        object.__setattr__(self, "of", max(int(self.of), 1))
        object.__setattr__(self, "done", min(max(int(self.done), 0), self.of))
        if self.best is not None and not math.isfinite(float(self.best)):
            object.__setattr__(self, "best", None)

    def to_dict(self) -> dict[str, Any]:
        """Plain JSON-ready data (what jobs send and the API serves)."""
        return asdict(self)

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> Progress:
        return cls(
            stage=str(data.get("stage", "")),
            done=int(data.get("done", 0)),
            of=int(data.get("of", 1)),
            fraction=float(data.get("fraction", 0.0)),
            best=None if data.get("best") is None else float(data["best"]),
            message=str(data.get("message", "")),
        )


ProgressFn = Callable[[Progress], None]


def no_progress(update: Progress) -> None:
    """A progress callback that ignores every update."""
    del update


def report(
    progress: ProgressFn | None,
    stage: str,
    done: int,
    of: int,
    *,
    fraction: float | None = None,
    best: float | None = None,
    message: str = "",
) -> None:
    """Call ``progress`` (when given) with one update; ``fraction`` defaults to done / of."""
    if progress is None:
        return
    frac = done / max(of, 1) if fraction is None else fraction
    progress(Progress(stage, done, of, frac, best, message))


def within(progress: ProgressFn | None, lo: float, hi: float) -> ProgressFn | None:
    """A callback for a sub-computation that maps its fraction into [lo, hi] of the parent's.

    Args:
        progress: the parent's callback (None gives None).
        lo, hi: the share of the parent's fraction the sub-computation covers, 0 <= lo <= hi <= 1.
    """
    if progress is None:
        return None
    parent = progress

    def scaled(update: Progress) -> None:
        parent(
            Progress(
                update.stage,
                update.done,
                update.of,
                lo + (hi - lo) * update.fraction,
                update.best,
                update.message,
            )
        )

    return scaled
