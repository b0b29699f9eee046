#!/usr/bin/env bash
# Print the folder that holds the uv this project installs with, bootstrapping it when needed.
#
#   uvdir="$(scripts/uv.sh)" && "$uvdir/uv" --version
#
# In order: $UV (a uv executable you name), uv on PATH, or the project-local copy in
# .tools/uv (a small virtual environment holding uv $UV_VERSION from PyPI, created here on first
# use; nothing is written to ~/.local). Messages go to stderr; exit code 1 when no uv can be had
# (the callers then fall back to pip and say so).
set -euo pipefail

UV_VERSION="${UV_VERSION:-0.13.9}"
python="${PYTHON:-python3}"
root="$(cd "$(dirname "$0")/.." && pwd)"
tool_env="$root/.tools/uv"

say() { printf '==> %s\n' "$*" >&2; }

if [ -n "${UV:-}" ] && [ -x "$UV" ]; then
    dirname "$UV"
    exit 0
fi
if on_path="$(command -v uv 2>/dev/null)"; then
    dirname "$on_path"
    exit 0
fi
if [ -x "$tool_env/bin/uv" ]; then
    echo "$tool_env/bin"
    exit 0
fi
say "uv not found: installing uv $UV_VERSION into $tool_env (project-local; nothing in ~/.local)"
if "$python" -m venv "$tool_env" >&2 \
    && "$tool_env/bin/python" -m pip install --quiet --disable-pip-version-check \
        "uv==$UV_VERSION" >&2 \
    && [ -x "$tool_env/bin/uv" ]; then
    echo "$tool_env/bin"
    exit 0
fi
rm -rf "$tool_env"
say "uv could not be installed into $tool_env"
exit 1
