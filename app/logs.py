"""BioPlan's log: one named logger per science package, all under ``bioplan``.

``bioplan.planning``, ``bioplan.analysis``, ``bioplan.recordings`` and ``bioplan.simulation``
say what the science decided: the methods planned with their solve times and convergence, a
method's failure, mesh refinement, the PSO budget and seed, the EMG channels and filters, the
repetitions found, the pose source, the sweep's cells. INFO is that story in a few lines per
operation; DEBUG adds each step; WARNING is a result made with less than was asked for.

As any library, BioPlan prints nothing of its own below WARNING until asked to (Python's
last-resort handler shows warnings on stderr). A library user calls :func:`set_log_level`; the
``bioplan`` command does it for ``-v`` (INFO), ``-vv`` (DEBUG) and ``--quiet`` (errors only);
a job of the service keeps its records (:class:`LogTail`) and the API serves them
(``GET /api/jobs/{id}/log``).
"""

from __future__ import annotations

import logging
import sys
from collections import deque
from collections.abc import Iterator
from contextlib import contextmanager

from app.errors import BioPlanError, one_line

__all__ = [
    "PACKAGES",
    "ROOT",
    "LogTail",
    "capture",
    "get_logger",
    "set_log_level",
]

#: The logger every science package's logger is under.
ROOT = "bioplan"
#: The science packages, each with its logger ``bioplan.<package>``.
PACKAGES = ("planning", "analysis", "recordings", "simulation")
#: Levels by name (``set_log_level`` and the CLI).
LEVELS = {
    "DEBUG": logging.DEBUG,
    "INFO": logging.INFO,
    "WARNING": logging.WARNING,
    "ERROR": logging.ERROR,
    "CRITICAL": logging.CRITICAL,
}
#: One record as one line: ``INFO bioplan.planning: paper: PSO ...``.
LINE_FORMAT = "%(levelname)s %(name)s: %(message)s"

#: A job's log keeps its last this many lines ...
MAX_LINES = 500
#: ... and at most this many bytes of them (UTF-8) [B].
MAX_BYTES = 64 * 1024
#: Longest line kept [characters] (a longer message is cut, as ``one_line`` does).
MAX_LINE = 1000


def get_logger(package: str) -> logging.Logger:
    """The logger of a science package (``"planning"`` -> ``bioplan.planning``)."""
    if package not in PACKAGES:
        raise BioPlanError(f"unknown package {package!r}: expected one of {', '.join(PACKAGES)}")
    return logging.getLogger(f"{ROOT}.{package}")


def _level(level: int | str) -> int:
    if isinstance(level, bool) or not isinstance(level, int | str):
        raise BioPlanError(f"log level {level!r}: expected one of {', '.join(LEVELS)} or an int")
    if isinstance(level, int):
        return level
    try:
        return LEVELS[level.strip().upper()]
    except KeyError:
        raise BioPlanError(
            f"unknown log level {level!r}: expected one of {', '.join(LEVELS)}"
        ) from None


class _StderrHandler(logging.StreamHandler):  # type: ignore[type-arg]
    """Writes to whatever ``sys.stderr`` is when a record comes (a test or a tool that
    replaces it sees the records)."""

    def emit(self, record: logging.LogRecord) -> None:
        self.setStream(sys.stderr)
        super().emit(record)


def set_log_level(level: int | str, *, handler: bool = True) -> int:
    """Show BioPlan's records at ``level`` and above; returns the level it had before.

    Args:
        level: ``"DEBUG"``, ``"INFO"``, ``"WARNING"``, ``"ERROR"``, ``"CRITICAL"`` (any case)
            or a ``logging`` level number.
        handler: print the records on stderr, one line each (``LINE_FORMAT``), and not also
            through the application's own logging set-up; False: no handler of BioPlan's, the
            records go to the application's handlers (``logging.basicConfig`` and the like).

    Raises:
        BioPlanError: an unknown level name.
    """
    logger = logging.getLogger(ROOT)
    before = logger.level
    logger.setLevel(_level(level))
    ours = [h for h in logger.handlers if isinstance(h, _StderrHandler)]
    if handler and not ours:
        stderr = _StderrHandler(sys.stderr)
        stderr.setFormatter(logging.Formatter(LINE_FORMAT))
        logger.addHandler(stderr)
    elif not handler:
        for h in ours:
            logger.removeHandler(h)
    logger.propagate = not handler
    return before


class LogTail(logging.Handler):
    """The last records of a job as lines: at most ``max_lines`` lines and ``max_bytes`` bytes
    (the oldest go first; the first line then says how many were left out).

    A handler for ``bioplan`` (see :func:`capture`); :meth:`take` hands over the lines not
    taken yet (what a job process sends with its progress), :meth:`extend` adds lines taken
    elsewhere (what the runner collects), :meth:`lines` is the log.
    """

    def __init__(
        self, level: int = logging.INFO, *, max_lines: int = MAX_LINES, max_bytes: int = MAX_BYTES
    ) -> None:
        super().__init__(level)
        self.max_lines, self.max_bytes = max_lines, max_bytes
        self._lines: deque[str] = deque()
        self._bytes = 0
        self.dropped = 0
        self._new: list[str] = []
        self.setFormatter(logging.Formatter("%(asctime)s " + LINE_FORMAT, "%H:%M:%S"))

    def emit(self, record: logging.LogRecord) -> None:
        try:
            line = one_line(self.format(record), MAX_LINE)
        except Exception:  # a record that cannot be formatted must not stop the job
            self.handleError(record)
            return
        self._new.append(line)
        self.extend([line])

    def extend(self, lines: list[str]) -> None:
        """Add lines (kept in order, the bounds enforced)."""
        for line in lines:
            self._lines.append(line)
            self._bytes += len(line.encode()) + 1
            while len(self._lines) > self.max_lines or (
                self._bytes > self.max_bytes and len(self._lines) > 1
            ):
                self._bytes -= len(self._lines.popleft().encode()) + 1
                self.dropped += 1
        # Lines not yet taken are only ever the newest ones: keep at most what the log keeps.
        del self._new[: max(len(self._new) - len(self._lines), 0)]

    def take(self) -> list[str]:
        """The lines recorded since the last call."""
        new, self._new = self._new, []
        return new

    def lines(self) -> list[str]:
        """The log: the kept lines, after one saying how many earlier ones were left out."""
        head = []
        if self.dropped:
            head = [
                f"... {self.dropped} earlier line(s) left out (a job's log keeps its last "
                f"{self.max_lines} lines, at most {self.max_bytes // 1024} kB)"
            ]
        return head + list(self._lines)


@contextmanager
def capture(tail: LogTail, level: int = logging.INFO) -> Iterator[LogTail]:
    """Record BioPlan's records at ``level`` and above into ``tail`` while inside (the
    ``bioplan`` logger's level is lowered to ``level`` meanwhile if it is higher)."""
    logger = logging.getLogger(ROOT)
    before = logger.level
    if before == logging.NOTSET or before > level:
        logger.setLevel(level)
    tail.setLevel(level)
    logger.addHandler(tail)
    try:
        yield tail
    finally:
        logger.removeHandler(tail)
        logger.setLevel(before)
