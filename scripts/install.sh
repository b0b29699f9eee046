#!/usr/bin/env bash
# Create the virtual environment and install BioPlan into it, saying what it does.
#
#   scripts/install.sh .venv '.'          # the app          (make install, make run)
#   scripts/install.sh .venv '.[test]'    # and test tools   (make install-test, make test)
#
# Every dependency is installed at the version pinned in requirements/lock.txt (a constraints
# file compiled from pyproject.toml with every extra; `make lock` refreshes it), so a fresh clone
# gets the versions the tests last passed with. uv installs the wheels in seconds where pip takes
# minutes; scripts/uv.sh finds it (or installs it into the project's .tools/uv, never into
# ~/.local), and pip is the fallback when uv cannot be had.
# PYTHON (default python3) is the interpreter the environment is made from.
set -euo pipefail

venv="${1:-.venv}"
spec="${2:-.}"
python="${PYTHON:-python3}"
root="$(cd "$(dirname "$0")/.." && pwd)"
lock="$root/requirements/lock.txt"
export UV_PYTHON_DOWNLOADS=never  # use this machine's Python, never download one

say() { printf '==> %s\n' "$*"; }

uv=""
if uvdir="$(PYTHON="$python" "$root/scripts/uv.sh")"; then
    uv="$uvdir/uv"
fi

if [ -n "$uv" ]; then
    if [ ! -x "$venv/bin/python" ]; then
        say "creating $venv from $("$python" --version 2>&1) (uv venv)"
        "$uv" venv --quiet --python "$python" "$venv"
    fi
    say "installing bioplan $spec into $venv with $uv, versions pinned by requirements/lock.txt"
    # --compile-bytecode: with PYTHONDONTWRITEBYTECODE set (as in many containers and CI
    # images) nothing would ever write the .pyc files, and every process (each CLI call, job,
    # upload parse) would compile numpy, scipy, pandas... from source again: 2-3 s each.
    "$uv" pip install --compile-bytecode --python "$venv/bin/python" -c "$lock" -e "$spec"
else
    say "uv could not be installed: falling back to pip (several minutes on a first install)"
    if [ ! -x "$venv/bin/python" ]; then
        say "creating $venv from $("$python" --version 2>&1) (python -m venv)"
        "$python" -m venv "$venv"
    fi
    "$venv/bin/python" -m pip install --upgrade pip
    say "installing bioplan $spec into $venv with pip, versions pinned by requirements/lock.txt"
    "$venv/bin/python" -m pip install --progress-bar on -c "$lock" -e "$spec"
fi
# BioPlan's own modules too (an editable install imports them from the checkout).
"$venv/bin/python" -m compileall -q "$root/app" >/dev/null || true
say "done: run the command line as $venv/bin/bioplan, or after 'source $venv/bin/activate' as bioplan"
