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
    # Services are the only door to storage, jobs and the viewer.
    "api": ("app.db", "app.jobs", "app.viewer", "app.main", "app.cli"),
    # The CLI runs the science packages itself or talks to a server over HTTP.
    "cli": ("app.api", "app.db", "app.jobs", "app.viewer", "app.main", "fastapi", "sqlalchemy"),
}
#: file -> the forbidden modules it may still import, and why.
EXCEPTIONS = {
    # ``bioplan serve`` is the server's composition root: it locks the data directory and
    # the database, migrates, and runs ``app.main``'s application with its HTTP protocol.
    "app/cli/serve.py": {"app.db.lock", "app.db.session", "app.main", "app.api.http_protocol",
                         "sqlalchemy.engine", "sqlalchemy.exc"},
}  # fmt: skip
#: What a route module may import from the app: its version, the API's own modules (no other
#: router), the services, and the kernel every layer shares.
ROUTE_IMPORTS = (
    "app",
    "app.api.deps",
    "app.api.errors",
    "app.api.schemas",
    "app.api.checks",
    "app.api.routes._common",
    "app.api.routes._results",
    "app.services",
    "app.errors",
    "app.names",
    "app.config",
    "app.jsonsafe",
    "app.progress",
)
KERNEL = ("app.errors", "app.names", "app.config", "app.jsonsafe", "app.progress")


def imports(path: Path) -> set[str]:
    """Every module an ``import`` or ``from ... import`` in the file names (absolute)."""
    return imports_of_source(path.read_text(encoding="utf-8"), path)


def imports_of_source(source: str, path: Path) -> set[str]:
    """Every module ``source`` (the text of the file at ``path``) imports (absolute)."""
    found: set[str] = set()
    package = ".".join(path.relative_to(REPO_ROOT).with_suffix("").parts[:-1])
    for node in ast.walk(ast.parse(source)):
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
        if _under(name, FORBIDDEN[package])
        and name not in EXCEPTIONS.get(str(path.relative_to(REPO_ROOT)), ())
    }
    assert not bad, sorted(bad)


def _under(name: str, prefixes: tuple[str, ...]) -> bool:
    """Whether module ``name`` is one of ``prefixes`` or inside one (``"app"``: itself only,
    for the routes' allowance, as every module of the app is inside it)."""
    return any(name == p or (p != "app" and name.startswith(f"{p}.")) for p in prefixes)


def _in_app(name: str) -> bool:
    return name == "app" or name.startswith("app.")


def test_routes_reach_the_app_only_through_the_services() -> None:
    """No router reads storage, runs science or imports another router itself."""
    files = sorted((APP / "api" / "routes").glob("*.py"))
    assert len(files) > 10
    bad = {
        f"{path.relative_to(REPO_ROOT)}: {name}"
        for path in files
        for name in imports(path)
        if _in_app(name) and not _under(name, ROUTE_IMPORTS)
    }
    assert not bad, sorted(bad)


def test_the_kernel_imports_no_other_layer() -> None:
    """The modules every layer may import depend on nothing of the app but each other."""
    for module in KERNEL:
        path = APP / f"{module.removeprefix('app.')}.py"
        others = {n for n in imports(path) if _in_app(n) and not _under(n, KERNEL)}
        assert not others, (module, sorted(others))


@pytest.mark.parametrize(
    ("source", "forbidden"),
    [
        ("from app.db import crud\n", "app.db"),
        ("def f():\n    from app.viewer.export import report_html\n", "app.viewer"),
        ("from .plans import check_task\n", "app.api.routes.plans"),
    ],
)
def test_every_kind_of_import_is_seen(tmp_path: Path, source: str, forbidden: str) -> None:
    """Module-level, function-level and relative imports all count."""
    path = REPO_ROOT / "app" / "api" / "routes" / "_probe.py"
    seen = imports_of_source(source, path)
    assert any(_under(n, (forbidden,)) for n in seen), seen
    assert not all(_under(n, ROUTE_IMPORTS) for n in seen if _in_app(n))
