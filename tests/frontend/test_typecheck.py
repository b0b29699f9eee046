"""The dashboard's JavaScript is type-checked: TypeScript's ``tsc --checkJs`` (tsconfig.json)
reads ``app/frontend/js`` with its JSDoc types, ``globals.d.ts`` and the API shapes of
``types.d.ts``. ``make lint`` runs the same check; ``make install-test`` installs TypeScript
from package-lock.json (``npm ci``). Without it (or without node) these tests skip, saying so.
"""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
TSC = ROOT / "node_modules" / "typescript" / "bin" / "tsc"
JS = Path("app") / "frontend" / "js"


def _tsc(project: Path) -> subprocess.CompletedProcess[str]:
    """Run the pinned tsc on ``project``'s tsconfig.json (errors on stdout, one per line)."""
    node = shutil.which("node")
    if node is None:
        pytest.skip("node not found (make install-test installs Debian's nodejs and npm)")
    if not TSC.is_file():
        pytest.skip(f"TypeScript not installed at {TSC} (make install-test runs npm ci)")
    return subprocess.run(
        [node, str(TSC), "-p", str(project / "tsconfig.json"), "--pretty", "false"],
        cwd=project,
        capture_output=True,
        text=True,
        timeout=600,
        check=False,
    )


def test_dashboard_javascript_type_checks() -> None:
    out = _tsc(ROOT)
    assert out.returncode == 0, f"tsc reported errors (make lint):\n{out.stdout}{out.stderr}"


# Bugs the check exists to catch, each planted in a copy of the pages' code: the error code
# tsc must report and the file it must name.
PLANTS = {
    "undefined name": (
        "plots.js",
        "export function planted() {\n  return colors();\n}\n",
        "TS2552",  # "Cannot find name 'colors'. Did you mean 'colours'?"
    ),
    "wrong argument count": (
        "recording.js",
        "export function planted() {\n  return draw(document.body);\n}\n",
        "TS2554",  # "Expected 3-4 arguments, but got 1."
    ),
    "misspelled field of an API result": (
        "compare.js",
        '/** @param {import("./types").Safety} s */\n'
        "export function planted(s) {\n  return s.min_clearence;\n}\n",
        "TS2551",  # "Property 'min_clearence' does not exist on type 'Safety'."
    ),
    "null misuse": (
        "ui.js",
        'export function planted() {\n  return document.getElementById("app").id;\n}\n',
        "TS2531",  # "Object is possibly 'null'."
    ),
}


@pytest.mark.parametrize("plant", sorted(PLANTS))
def test_a_planted_type_error_fails_the_check(plant: str, tmp_path: Path) -> None:
    shutil.copytree(ROOT / JS, tmp_path / JS)
    shutil.copy(ROOT / "tsconfig.json", tmp_path / "tsconfig.json")
    name, code, expected = PLANTS[plant]
    target = tmp_path / JS / name
    before = target.read_text(encoding="utf-8")
    target.write_text(before + "\n" + code, encoding="utf-8")

    out = _tsc(tmp_path)

    assert out.returncode != 0, f"tsc accepted the planted {plant}:\n{out.stdout}"
    planted = [e for e in out.stdout.splitlines() if e.startswith(f"{JS.as_posix()}/{name}(")]
    assert any(f"error {expected}:" in e for e in planted), out.stdout
    # Only the planted lines are wrong: the file's own code stays clean.
    rows = {int(e.split("(")[1].split(",")[0]) for e in planted}
    assert min(rows) > before.count("\n"), out.stdout
