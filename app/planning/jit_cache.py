"""A cache on disk of the C objects CasADi's JIT compiles, shared by every process of this user.

CasADi's shell JIT writes a function's C source and runs ``<compiler> -O1 -fPIC -c SOURCE.c -o
OBJECT.o`` before linking it. :func:`compiler_command` names this file, run as a script, as that
compiler: it hashes the source, the flags and the real compiler's identity, copies the cached
object when there is one, and otherwise compiles and keeps the object. CasADi generates the same
source for a function in every process (its names included), so a chain's dynamics and their
derivatives are compiled once per machine, not once per process (benchmarks/RESULTS.md,
"Compiled dynamics cached on disk").

Where: ``jit`` in BioPlan's cache folder (``$BIOPLAN_CACHE_DIR``, else
``$XDG_CACHE_HOME/bioplan``, else ``~/.cache/bioplan``), a folder of this user's only (mode
0700); ``BIOPLAN_JIT_CACHE=off`` turns the cache off. Objects are written under a temporary name
and renamed, so processes compiling the same source at once never read half a file, and the least
recently used are removed beyond :data:`MAX_BYTES`. A failing cache (an unwritable folder, a
damaged entry) falls back to compiling, never to an error of its own. The part run as the
compiler imports the standard library only: a fresh interpreter starts for every compile.
"""

from __future__ import annotations

import hashlib
import os
import stat
import sys
from pathlib import Path

#: Environment variable that turns the cache off (``off``).
CACHE_ENV = "BIOPLAN_JIT_CACHE"
#: The cache is trimmed to this size, least recently used objects first [bytes].
MAX_BYTES = 256 * 1024**2
#: Bumped when the key's recipe changes, so that old entries are never read.
_KEY_VERSION = b"bioplan-jit-cache-1"


def cache_folder() -> Path | None:
    """This user's JIT cache folder (created with mode 0700), or None when the cache is off or
    the folder cannot be made, is not this user's, or others may write to it."""
    if os.environ.get(CACHE_ENV, "").strip().lower() == "off":
        return None
    from app.planning.robots import cache_root  # the parent process only: not in the script

    folder = cache_root() / "jit"
    try:
        folder.mkdir(mode=0o700, parents=True, exist_ok=True)
        info = folder.lstat()
    except OSError:
        return None
    # Objects from here are loaded into the process: only a folder no one else can write to.
    private = info.st_uid == os.getuid() and not info.st_mode & (stat.S_IWGRP | stat.S_IWOTH)
    return folder if stat.S_ISDIR(info.st_mode) and private else None


def compiler_command(compiler: str = "gcc") -> str | None:
    """The command CasADi's shell JIT should run as its compiler (this file under the running
    interpreter, with the cache folder and the real compiler), or None when the cache is off
    or ``compiler`` is not found (CasADi then runs the compiler itself)."""
    import shlex
    import shutil

    folder = cache_folder()
    real = shutil.which(compiler)
    if folder is None or real is None:
        return None
    parts = [sys.executable, "-I", "-S", os.path.abspath(__file__), str(folder), real, "--"]
    return " ".join(shlex.quote(p) for p in parts)


# The compiler side: run once per compile in a fresh interpreter, so it imports little (a cache
# hit takes about 15 ms, most of it the interpreter's start).


def _key(real_compiler: str, flags: list[str], source: str) -> str:
    """The object's name: a hash of the source, the flags and the compiler binary's identity."""
    digest = hashlib.sha256(_KEY_VERSION)
    info = os.stat(real_compiler)
    digest.update(f"{os.path.realpath(real_compiler)}|{info.st_size}|{info.st_mtime_ns}".encode())
    for flag in flags:
        digest.update(b"\0" + flag.encode())
    with open(source, "rb") as handle:
        digest.update(b"\0" + handle.read())
    return digest.hexdigest()


def _split(args: list[str]) -> tuple[str, str, list[str]] | None:
    """(source, object, the flags without either) of ``... -c SOURCE.c -o OBJECT ...``, or None
    for any other command line (passed through uncached)."""
    sources = [a for a in args if a.endswith(".c")]
    if "-c" not in args or "-o" not in args or len(sources) != 1:
        return None
    out_at = args.index("-o")
    if out_at + 1 >= len(args):
        return None
    flags = [a for i, a in enumerate(args) if a not in sources and i not in (out_at, out_at + 1)]
    return sources[0], args[out_at + 1], flags


def _copy(source: str, target: str) -> None:
    with open(source, "rb") as src, open(target, "wb") as dst:
        dst.write(src.read())


def _trim(folder: str) -> None:
    """Remove the least recently used objects until the folder is within :data:`MAX_BYTES`."""
    entries = []
    for entry in os.scandir(folder):
        if entry.name.endswith(".o"):
            try:
                info = entry.stat()
            except OSError:
                continue
            entries.append((info.st_mtime, info.st_size, entry.path))
    total = sum(size for _, size, _ in entries)
    for _, size, path in sorted(entries):
        if total <= MAX_BYTES:
            break
        try:
            os.unlink(path)
        except OSError:
            continue
        total -= size


def _compile(real_compiler: str, args: list[str]) -> int:
    import subprocess

    return subprocess.call([real_compiler, *args])


def compile_cached(folder: str, real_compiler: str, args: list[str]) -> int:
    """Run ``real_compiler args`` through the cache in ``folder``; the compiler's exit status."""
    parts = _split(args)
    if parts is None:
        return _compile(real_compiler, args)
    source, obj, flags = parts
    try:
        cached = os.path.join(folder, _key(real_compiler, flags, source) + ".o")
        if os.path.isfile(cached):
            _copy(cached, obj)
            os.utime(cached)  # recently used: trimmed last
            return 0
    except OSError:
        return _compile(real_compiler, args)
    status = _compile(real_compiler, args)
    if status == 0:
        partial = f"{cached}.{os.getpid()}.tmp"
        try:
            _copy(obj, partial)
            os.replace(partial, cached)  # atomic: no reader sees half an object
            _trim(folder)
        except OSError:  # a cache that cannot be written is only slower
            if os.path.exists(partial):
                os.unlink(partial)
    return status


def main(argv: list[str]) -> int:
    """``jit_cache.py FOLDER COMPILER -- ARGS...``: compile through the cache."""
    if len(argv) < 3 or argv[2] != "--":
        print("usage: jit_cache.py FOLDER COMPILER -- COMPILER_ARGS...", file=sys.stderr)
        return 2
    return compile_cached(argv[0], argv[1], argv[3:])


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
