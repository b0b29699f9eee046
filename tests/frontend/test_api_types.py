"""The dashboard's API types are generated from the server's response models: the checked-in
``app/frontend/js/api_types.d.ts`` is what ``scripts/js_types.py`` writes from the OpenAPI
document, and the pages' ``types.d.ts`` takes the results' shapes from it."""

from __future__ import annotations

import importlib.util
import re
import shutil
import subprocess
import sys
from pathlib import Path
from types import ModuleType
from typing import Any

import pytest

ROOT = Path(__file__).resolve().parents[2]
JS = ROOT / "app" / "frontend" / "js"


def _script() -> ModuleType:
    spec = importlib.util.spec_from_file_location("js_types", ROOT / "scripts" / "js_types.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules["js_types"] = module
    spec.loader.exec_module(module)
    return module


@pytest.fixture(scope="module")
def js_types() -> ModuleType:
    return _script()


@pytest.fixture(scope="module")
def openapi(js_types: ModuleType) -> dict[str, Any]:
    doc: dict[str, Any] = js_types.openapi_document()
    return doc


def test_the_checked_in_types_are_the_generated_ones(
    js_types: ModuleType, openapi: dict[str, Any]
) -> None:
    expected = js_types.render(openapi)
    current = (JS / "api_types.d.ts").read_text(encoding="utf-8")
    assert current == expected, "api_types.d.ts is stale: run .venv/bin/python scripts/js_types.py"


def test_a_changed_model_changes_the_types(js_types: ModuleType, openapi: dict[str, Any]) -> None:
    """The file follows the models: a field added to a result's schema appears, typed."""
    schemas = openapi["components"]["schemas"]
    before = js_types.render(openapi)
    schemas["PlanResult"]["properties"]["planted_field"] = {
        "type": "array",
        "items": {"anyOf": [{"type": "number"}, {"type": "null"}]},
        "description": "a planted field [W]",
    }
    try:
        after = js_types.render(openapi)
    finally:
        del schemas["PlanResult"]["properties"]["planted_field"]
    assert "planted_field" not in before
    assert "  /** a planted field [W] */\n  planted_field?: (number | null)[];" in after


def test_every_result_kind_and_the_comparison_are_declared() -> None:
    text = (JS / "api_types.d.ts").read_text(encoding="utf-8")
    declared = set(re.findall(r"^export (?:interface|type) (\w+)", text, re.M))
    from app.api.result_models import RESULT_OUT_MODELS

    wanted = {m.__name__ for m in RESULT_OUT_MODELS.values()} | {"ComparisonView", "MetaOut"}
    assert wanted <= declared, sorted(wanted - declared)
    # The derived curves are fields of the served curves, typed (T, n).
    block = text.split("export interface TrajectoryCurves {", 1)[1].split("}", 1)[0]
    assert "joint_power: (number | null)[][];" in block
    assert "joint_energy: (number | null)[][];" in block


def test_the_pages_read_the_generated_shapes() -> None:
    """``types.d.ts`` re-exports the results from the generated file instead of writing them."""
    text = (JS / "types.d.ts").read_text(encoding="utf-8")
    for name in ("PlanResult", "ComparisonView", "FrontResult", "SweepResult", "TrajectoryCurves"):
        assert re.search(rf"^\s*{name},$", text, re.M), name
        assert f"interface {name} " not in text, f"{name} written by hand again"
    assert 'from "./api_types";' in text


def _tsc(project: Path, *extra: str) -> subprocess.CompletedProcess[str]:
    """The pinned tsc on ``project``'s tsconfig.json (errors on stdout, one per line)."""
    node = shutil.which("node")
    tsc = ROOT / "node_modules" / "typescript" / "bin" / "tsc"
    if node is None or not tsc.is_file():
        pytest.skip("node or TypeScript missing (make install-test installs both)")
    return subprocess.run(
        [node, str(tsc), "-p", str(project / "tsconfig.json"), "--pretty", "false", *extra],
        cwd=project,
        capture_output=True,
        text=True,
        timeout=600,
        check=False,
    )


def test_every_page_has_no_implicit_any() -> None:
    """Every file of the dashboard is typed through ``noImplicitAny``: a parameter or variable
    left untyped in any of them fails here (also if the flag is turned off in tsconfig.json)."""
    pages = sorted(p.name for p in JS.iterdir() if p.suffix == ".js")
    assert {"compare.js", "recording.js", "plan.js", "front.js", "cohort.js"} <= set(pages)
    out = _tsc(ROOT, "--noImplicitAny")
    mine = [e for e in out.stdout.splitlines() if e.startswith("app/frontend/js/")]
    assert mine == [], "\n".join(mine)
    assert out.returncode == 0, out.stdout + out.stderr


def test_the_project_config_refuses_an_untyped_parameter(tmp_path: Path) -> None:
    """tsconfig.json itself has ``noImplicitAny`` on (``make lint`` and test_typecheck.py run it
    without the command-line flag): a page's function with an untyped parameter is an error."""
    shutil.copytree(JS, tmp_path / "app" / "frontend" / "js")
    shutil.copy(ROOT / "tsconfig.json", tmp_path / "tsconfig.json")
    target = tmp_path / "app" / "frontend" / "js" / "names.js"
    planted = "\nexport function planted(value) {\n  return value;\n}\n"
    target.write_text(target.read_text(encoding="utf-8") + planted, encoding="utf-8")
    out = _tsc(tmp_path)
    assert out.returncode != 0, out.stdout
    errors = [e for e in out.stdout.splitlines() if "error TS" in e]
    assert len(errors) == 1, out.stdout
    assert errors[0].startswith("app/frontend/js/names.js(")
    assert "TS7006" in errors[0] and "'value'" in errors[0]
