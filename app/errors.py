"""The one error base for bad input, shared by every package.

Readers, analysis, planning, simulation and the services raise ``BioPlanError`` (or a subclass:
``RecordingError``, ``RobotError``, ``PlanningError``, ``SimulationError``...) when the *input*
is wrong: a file that cannot be read, a task that cannot be planned, an option out of range. The
message names the file, line, channel, joint or field and says what was expected, in one line.

The CLI prints these as one line with exit code 2; the API answers them with a 4xx. Anything
else that escapes is a bug: the CLI shows its traceback and the API logs it and answers 500.
``BioPlanError`` subclasses ``ValueError`` so that code written against the standard library's
convention ("bad value -> ValueError") keeps working.
"""

from __future__ import annotations

import re

__all__ = ["BioPlanError", "one_line", "without_paths"]

#: Longest message shown for one error [characters].
MAX_MESSAGE = 1000


def one_line(text: str, limit: int = MAX_MESSAGE) -> str:
    """A message as one printable line: control characters escaped (a corrupt file's bytes
    quoted in a message must not break a terminal or a log line), whitespace runs as one
    space, at most ``limit`` characters."""
    shown = "".join(
        c if c.isprintable() or c == " " else (" " if c in "\n\r\t" else repr(c)[1:-1])
        for c in text
    )
    shown = " ".join(shown.split())
    return shown if len(shown) <= limit else shown[: limit - 1] + "…"


class BioPlanError(ValueError):
    """Bad input: what is wrong, where (file, line, channel, joint or field), what was expected."""


def storage_problem(exc: BaseException) -> str | None:
    """``"full"`` when ``exc`` (or an exception it wraps) is a full disk or an exceeded quota,
    ``"read-only"`` when the data directory cannot be written, else None.

    Neither is bad input nor a bug: the API answers 507 and the job service keeps the events it
    could not write until it can write again.
    """
    import errno

    seen: BaseException | None = exc
    for _ in range(10):  # the chain is short; never loop on a cycle
        if seen is None:
            return None
        if isinstance(seen, OSError) and seen.errno in (errno.ENOSPC, errno.EDQUOT):
            return "full"
        if isinstance(seen, OSError) and seen.errno == errno.EROFS:
            return "read-only"
        text = str(seen)
        if "database or disk is full" in text:  # SQLite's SQLITE_FULL
            return "full"
        if "readonly database" in text:  # SQLite's SQLITE_READONLY
            return "read-only"
        seen = getattr(seen, "orig", None) or seen.__cause__ or seen.__context__
    return None


#: An absolute path (POSIX ``/a/b``, ``~/a``, Windows ``C:\\a``): folders, then a last part.
_PATH = re.compile(
    r"(?<![\w.~\-/])(?:~|[A-Za-z]:)?[/\\](?:[^\s/\\:'\"<>|,;()]+[/\\])+([^\s/\\:'\"<>|,;()]*)"
)


def without_paths(text: object) -> str:
    """``text`` with every absolute path cut to its last part (``/srv/bioplan/data/robots/
    ab12/arm.urdf`` -> ``arm.urdf``): what an answer says about a file without the server's
    folders (data directory, caches, temporary folders)."""
    return _PATH.sub(lambda m: m.group(1) or "(a folder)", str(text))
