# BioPlan: two commands do all set-up.  `make run` and `make test` (see README.md).
#
# Each environment target below is one rule: a stamp file that is remade when pyproject.toml or
# the lock file changes. scripts/install.sh creates the virtual environment and installs into it
# with uv (pip as the fallback), saying what it does, at the versions pinned in
# requirements/lock.txt. `make lock` refreshes the pins (scripts/lock.sh says how).
PYTHON ?= python3
VENV   := .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed
TSTAMP := $(VENV)/.installed-test
# TypeScript for the dashboard's JavaScript type check (package.json, pinned in package-lock.json).
NODE_STAMP := node_modules/.installed

export PYTHON

.PHONY: run test install install-test browser lint typecheck pytest bench clean pose-env \
	pose-env-or-warn lock

LOCK      := requirements/lock.txt
POSE_LOCK := requirements/pose.txt

# Video to pose runs MediaPipe 0.10.21 in its own environment (it needs numpy<2; BioPlan needs
# numpy 2). `bioplan pose-env` creates it, with the uv scripts/uv.sh finds and the pins of
# requirements/pose.txt; BioPlan finds it through BIOPLAN_POSE_PYTHON.
POSE_ENV   ?= .venv-pose
POSE_STAMP := $(POSE_ENV)/.installed
export BIOPLAN_POSE_PYTHON ?= $(abspath $(POSE_ENV))/bin/python

# ---- environments ---------------------------------------------------------------------------

$(STAMP): pyproject.toml $(LOCK) scripts/install.sh
	@scripts/install.sh $(VENV) '.'
	@touch $@

$(TSTAMP): $(STAMP) pyproject.toml $(LOCK)
	@scripts/install.sh $(VENV) '.[test]'
	@touch $@

install: $(STAMP)
install-test: $(TSTAMP) $(POSE_STAMP) $(NODE_STAMP)

# `npm ci` installs exactly package-lock.json's TypeScript into node_modules/ (remade when the
# lock changes). Node and npm come from Debian, installed here when missing, like the browser.
$(NODE_STAMP): package.json package-lock.json
	@command -v npm >/dev/null || { \
	  echo "==> installing Debian's nodejs and npm for the JavaScript type check (make lint)"; \
	  apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq nodejs npm; }
	@echo "==> installing TypeScript from package-lock.json (npm ci)"
	@npm ci --no-audit --no-fund
	@touch $@

# Remade when its pins change (the main environment only has to exist: its bioplan makes it).
$(POSE_STAMP): $(POSE_LOCK) | $(STAMP)
	@echo "==> creating the pose environment $(POSE_ENV) (MediaPipe 0.10.21, for videos)"
	@base="$$(command -v "$(PYTHON)" || echo "$(PYTHON)")"; \
	  uvdir="$$(scripts/uv.sh)" || uvdir=""; \
	  PATH="$${uvdir:+$$uvdir:}$$PATH" UV_CONSTRAINT="$(CURDIR)/$(POSE_LOCK)" \
	  PIP_CONSTRAINT="$(CURDIR)/$(POSE_LOCK)" \
	  $(VENV)/bin/bioplan pose-env $(POSE_ENV) --python "$$base"
	@touch $@

pose-env: $(POSE_STAMP)

# `make run` goes on without the pose environment (e.g. on Python 3.13, for which MediaPipe
# 0.10.21 has no wheel): the step says why it failed, and the dashboard and the API say what a
# video needs. `make test` still requires it.
pose-env-or-warn: $(STAMP)
	@$(MAKE) --no-print-directory -o $(STAMP) pose-env || { \
	  echo "==> continuing without the pose environment: everything but video works;" \
	       "videos need it (see above; 'make pose-env PYTHON=python3.12' to retry)"; }

# Refresh requirements/lock.txt and requirements/pose.txt (UPGRADE=1: newest allowed versions).
lock:
	@scripts/lock.sh

# Browser tests drive Debian's Chromium (never a downloaded browser build).
browser:
	@test -x /usr/bin/chromium || { \
	  echo "==> installing Debian's chromium for the browser tests"; \
	  apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq chromium; }

# ---- run ------------------------------------------------------------------------------------

# The dashboard on the embedded defaults (SQLite in ./data, local job runner), with a demo
# recording session and a finished comparison already stored. Prints the URL once it answers;
# BIOPLAN_PORT (or `.venv/bin/bioplan serve --port N --demo`) picks another port.
run: $(STAMP) pose-env-or-warn
	@$(VENV)/bin/bioplan serve --demo

# ---- checks ---------------------------------------------------------------------------------

# ruff on the Python; tsc --checkJs on the dashboard's JavaScript (tsconfig.json, docs/dashboard.md).
lint: $(TSTAMP) $(NODE_STAMP)
	$(VENV)/bin/ruff check app tests benchmarks
	$(VENV)/bin/ruff format --check app tests benchmarks
	node node_modules/typescript/bin/tsc -p tsconfig.json

typecheck: $(TSTAMP)
	$(VENV)/bin/mypy app

# The suite runs on one worker more than the cores it may use (at most 4; PYTEST_WORKERS=0
# runs it in one process): about a third of its time waits on browsers, servers and CLI
# processes, so a spare worker keeps the cores busy (2 cores: 19.1 min on 2 workers). Each test
# file stays on one worker, in order (the README's examples build on each other), the longest
# files first (tests/conftest.py LONGEST_FIRST); the 25 slowest tests are listed.
PYTEST_WORKERS ?= $(shell python3 -c "import os; print(min(4, len(os.sched_getaffinity(0)) + 1))")
pytest: $(TSTAMP) $(POSE_STAMP) $(NODE_STAMP) browser
	$(VENV)/bin/pytest -n $(PYTEST_WORKERS) --maxprocesses 4 --dist loadfile \
	  --no-loadscope-reorder --durations 25

test: $(POSE_STAMP) lint typecheck pytest

bench: $(TSTAMP) $(POSE_STAMP)
	$(PY) benchmarks/run_all.py

clean:
	rm -rf $(VENV) $(POSE_ENV) .tools .mypy_cache .pytest_cache .ruff_cache node_modules
