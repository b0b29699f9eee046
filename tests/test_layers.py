"""The layers import only downwards (DESIGN.md): read from every import statement, including
the ones inside functions."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

from tests.utils.data import REPO_ROOT

APP = REPO_ROOT / "app"
SCIENCE = ("recordings", "analysis", "planning", "simulation")
WEB = ("fastapi", "starlette", "sqlalchemy", "alembic", "viser", "uvicorn", "distributed")

#: package -> modules it must never import (prefixes).
FORBIDDEN = {
    **{
        name: (*WEB, "app.api", "app.services", "app.db", "app.jobs", "app.viewer", "app.main")
        for name in SCIENCE
    },
    "viewer": ("app.api", "app.main", "app.services", "app.db", "app.jobs", "fastapi"),
    "jobs": ("app.db", "app.api", "app.services", "app.viewer", "app.main", "sqlalchemy"),
    "db": ("app.api", "app.services", "app.jobs", "app.viewer", "app.main"),
    "services": ("app.api", "app.main", "fastapi", "starlette"),
}


def imports(path: Path) -> set[str]:
    """Every module an ``import`` or ``from ... import`` in the file names (absolute)."""
    found: set[str] = set()
    package = ".".join(path.relative_to(REPO_ROOT).with_suffix("").parts[:-1])
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            found.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:  # relative: resolve against this file's package
                base = package.rsplit(".", node.level - 1)[0] if node.level > 1 else package
                found.add(f"{base}.{node.module}" if node.module else base)
            elif node.module:
                found.add(node.module)
    return found


@pytest.mark.parametrize("package", sorted(FORBIDDEN))
def test_a_layer_imports_nothing_above_it(package: str) -> None:
    files = sorted((APP / package).rglob("*.py"))
    assert files, package
    bad = {
        f"{path.relative_to(REPO_ROOT)}: {name}"
        for path in files
        for name in imports(path)
        if any(name == f or name.startswith(f"{f}.") for f in FORBIDDEN[package])
    }
    assert not bad, sorted(bad)
