#!/usr/bin/env bash
# Create the virtual environment and install BioPlan into it, saying what it does.
#
#   scripts/install.sh .venv '.'          # the app          (make install, make run)
#   scripts/install.sh .venv '.[test]'    # and test tools   (make install-test, make test)
#
# uv installs the wheels in seconds where pip takes minutes; it is bootstrapped with
# `pip install --user uv` when it is not on PATH, and pip is the fallback when uv cannot be had.
# PYTHON (default python3) is the interpreter the environment is made from.
set -euo pipefail

venv="${1:-.venv}"
spec="${2:-.}"
python="${PYTHON:-python3}"
export UV_PYTHON_DOWNLOADS=never  # use this machine's Python, never download one

say() { printf '==> %s\n' "$*"; }

find_uv() {
    command -v uv 2>/dev/null && return
    local user_base
    user_base="$("$python" -m site --user-base 2>/dev/null || true)"
    if [ -n "$user_base" ] && [ -x "$user_base/bin/uv" ]; then
        echo "$user_base/bin/uv"
    fi
}

uv="$(find_uv || true)"
if [ -z "$uv" ]; then
    say "uv not found: installing it for this user (pip install --user uv)"
    "$python" -m pip install --user --quiet uv 2>/dev/null \
        || "$python" -m pip install --user --quiet --break-system-packages uv 2>/dev/null \
        || true
    uv="$(find_uv || true)"
fi

if [ -n "$uv" ]; then
    if [ ! -x "$venv/bin/python" ]; then
        say "creating $venv from $("$python" --version 2>&1) (uv venv)"
        "$uv" venv --quiet --python "$python" "$venv"
    fi
    say "installing bioplan $spec and its dependencies into $venv with uv"
    "$uv" pip install --python "$venv/bin/python" -e "$spec"
else
    say "uv could not be installed: falling back to pip (several minutes on a first install)"
    if [ ! -x "$venv/bin/python" ]; then
        say "creating $venv from $("$python" --version 2>&1) (python -m venv)"
        "$python" -m venv "$venv"
    fi
    "$venv/bin/python" -m pip install --upgrade pip
    "$venv/bin/python" -m pip install --progress-bar on -e "$spec"
fi
say "done: run the command line as $venv/bin/bioplan, or after 'source $venv/bin/activate' as bioplan"
