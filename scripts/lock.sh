#!/usr/bin/env bash
# Refresh the lock files (`make lock`; `make lock UPGRADE=1` moves every pin to the newest
# version pyproject.toml allows, otherwise pins change only where pyproject.toml now demands it):
#
#   requirements/lock.txt  every dependency of BioPlan and of all its extras (test, postgres),
#                          for CPython >= 3.11 on every platform; scripts/install.sh (make run,
#                          make test, CI) and the Dockerfile install with it as constraints.
#   requirements/pose.txt  the pose environment (app.recordings.video.POSE_REQUIREMENTS and
#                          MediaPipe 0.10.21, which needs numpy<2); `make pose-env` and the
#                          Dockerfile build it with these pins.
#
# Compiled with uv (scripts/uv.sh); needs the package index.
set -euo pipefail

root="$(cd "$(dirname "$0")/.." && pwd)"
cd "$root"
python="${PYTHON:-python3}"
uv="$(PYTHON="$python" scripts/uv.sh)/uv"
upgrade=()
if [ -n "${UPGRADE:-}" ]; then upgrade=(--upgrade); fi

say() { printf '==> %s\n' "$*"; }

mkdir -p requirements
say "compiling requirements/lock.txt from pyproject.toml (all extras, CPython >= 3.11)"
"$uv" pip compile --quiet pyproject.toml --all-extras --universal --python-version 3.11 \
    "${upgrade[@]}" --custom-compile-command "make lock" -o requirements/lock.txt

# The pose environment's requirements, read from the package without importing it (its
# __init__ pulls in numpy and the readers).
requirements="$("$python" - <<'EOF'
import ast, pathlib
tree = ast.parse(pathlib.Path("app/recordings/video.py").read_text(encoding="utf-8"))
values = {}
for node in tree.body:
    if isinstance(node, (ast.Assign, ast.AnnAssign)):
        target = node.targets[0] if isinstance(node, ast.Assign) else node.target
        if isinstance(target, ast.Name) and target.id in ("POSE_REQUIREMENTS", "MEDIAPIPE"):
            values[target.id] = ast.literal_eval(node.value)
print("\n".join([*values["POSE_REQUIREMENTS"], values["MEDIAPIPE"]]))
EOF
)"
say "compiling requirements/pose.txt (the pose environment: MediaPipe 0.10.21, numpy<2)"
# mediapipe is installed without its dependencies (their pins would pull numpy 2): compile the
# rest, then pin mediapipe itself.
mediapipe="$(grep '^mediapipe' <<<"$requirements")"
grep -v '^mediapipe' <<<"$requirements" \
    | "$uv" pip compile --quiet - --universal --python-version 3.11 "${upgrade[@]}" \
        --custom-compile-command "make lock" -o requirements/pose.txt
printf '%s\n    # installed with --no-deps (app.recordings.video.MEDIAPIPE)\n' "$mediapipe" \
    >>requirements/pose.txt
say "done: requirements/lock.txt and requirements/pose.txt (commit both)"
