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
    # Storage keeps plain rows: no science (results arrive as JSON and arrays).
    "db": (
        "app.api",
        "app.services",
        "app.jobs",
        "app.viewer",
        "app.main",
        *(f"app.{name}" for name in SCIENCE),
    ),
    "services": ("app.api", "app.main", "fastapi", "starlette"),
    # Services are the only door to storage, jobs and the viewer.
    "api": ("app.db", "app.jobs", "app.viewer", "app.main", "app.cli"),
    # The CLI runs the science packages itself or talks to a server over HTTP.
    "cli": ("app.api", "app.db", "app.jobs", "app.viewer", "app.main", "fastapi", "sqlalchemy"),
}
#: file -> the forbidden modules it may still import, and why.
EXCEPTIONS = {
    # The sweep's optional executor: ``run_sweep(executor="dask://...")`` runs its cells on a
    # Dask cluster (imported only then; a plain import, so this rule sees it).
    "app/simulation/sweep.py": {"distributed"},
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
    "app.api.result_models",
    "app.api.checks",
    "app.api.routes._common",
    "app.api.routes._results",
    "app.services",
    "app.errors",
    "app.names",
    "app.config",
    "app.jsonsafe",
    "app.progress",
    "app.kinds",
)
KERNEL = (
    "app.errors",
    "app.names",
    "app.config",
    "app.jsonsafe",
    "app.progress",
    "app.kinds",
    "app.options",
)


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


# ------------------------------------------------------------------------- string imports

#: Calls that import a module named by a string: invisible to the rules above and typed ``Any``.
STRING_IMPORTS = ("import_module", "__import__", "_entry")
#: file -> why it may import by a computed name.
STRING_IMPORT_EXCEPTIONS = {
    # PEP 562 lazy exports: ``from app.planning import plan`` imports the submodule on first
    # use; the names are listed (and typed) in its TYPE_CHECKING block.
    "app/planning/__init__.py": "lazy public names of app.planning",
}


def string_imports(source: str) -> list[str]:
    """The calls of ``source`` that import a module by its name as a string."""
    found = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Call):
            func = node.func
            name = func.attr if isinstance(func, ast.Attribute) else getattr(func, "id", "")
            if name in STRING_IMPORTS:
                found.append(f"line {node.lineno}: {ast.unparse(node)}")
    return found


def test_no_module_is_imported_by_a_string() -> None:
    """Every import is an import statement (``importlib.import_module("app.x")``, ``__import__``
    and ``_entry("module", "name")`` hide a dependency from this test and from mypy)."""
    bad = {
        f"{path.relative_to(REPO_ROOT)} {call}"
        for path in sorted(APP.rglob("*.py"))
        if str(path.relative_to(REPO_ROOT)) not in STRING_IMPORT_EXCEPTIONS
        for call in string_imports(path.read_text(encoding="utf-8"))
    }
    assert not bad, sorted(bad)


@pytest.mark.parametrize(
    "source",
    [
        "import importlib\nx = importlib.import_module('app.planning')\n",
        "from importlib import import_module\ndef f():\n    return import_module('app.db')\n",
        "np = __import__('numpy')\n",
        "def f():\n    return _entry('app.planning', 'plan')\n",
    ],
)
def test_every_kind_of_string_import_is_seen(source: str) -> None:
    assert string_imports(source)


# ------------------------------------------------------------------------ private modules


def module_name(path: Path) -> str:
    """The dotted name of the module in ``path`` (a package's ``__init__``: the package)."""
    parts = path.relative_to(REPO_ROOT).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


#: Every module of the app, by name.
MODULES = {module_name(p): p for p in APP.rglob("*.py")}


def private_owner(name: str) -> str | None:
    """The package whose private module ``name`` is (``app.jobs._lifeline`` -> ``app.jobs``),
    or None when no part of it is private."""
    parts = name.split(".")
    for i, part in enumerate(parts):
        if part.startswith("_") and not part.startswith("__"):
            return ".".join(parts[:i])
    return None


def imported_modules(path: Path) -> set[str]:
    """What the file imports, with ``from package import module`` as the module itself."""
    found = set(imports(path))
    package = (
        module_name(path) if path.name == "__init__.py" else module_name(path).rpartition(".")[0]
    )
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.ImportFrom):
            base = _from_module(node, package)
            found.update(f"{base}.{a.name}" for a in node.names if f"{base}.{a.name}" in MODULES)
    return found


def _from_module(node: ast.ImportFrom, package: str) -> str:
    """The absolute module a ``from ... import`` names (relative ones against ``package``)."""
    if not node.level:
        return node.module or ""
    base = package.rsplit(".", node.level - 1)[0] if node.level > 1 else package
    return f"{base}.{node.module}" if node.module else base


def test_private_modules_are_imported_only_inside_their_package() -> None:
    """A module whose name starts with ``_`` is its package's business: others import the
    names the package exports (``from app.planning.robots import load_robot_files``, never
    ``app.planning.robots._package``)."""
    bad = set()
    for path in sorted(APP.rglob("*.py")):
        me = module_name(path)
        for name in imported_modules(path):
            owner = private_owner(name)
            if (
                owner is not None
                and _in_app(name)
                and not (me == owner or me.startswith(f"{owner}."))
            ):
                bad.add(f"{path.relative_to(REPO_ROOT)}: {name}")
    assert not bad, sorted(bad)


def test_a_private_module_is_recognised() -> None:
    assert private_owner("app.planning.robots._package") == "app.planning.robots"
    assert private_owner("app.jobs._lifeline") == "app.jobs"
    assert private_owner("app.planning.robots") is None
    assert private_owner("app.planning.robots.__main__") is None


# --------------------------------------------------------------------------------- cycles


def _type_checking(test: ast.expr) -> bool:
    return (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING") or (
        isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING"
    )


def app_imports(source: str, path: Path, *, functions: bool) -> set[str]:
    """The app modules ``source`` (the file at ``path``) imports when it runs: at module level
    (class bodies included), and with ``functions`` also inside functions; never the imports
    under ``if TYPE_CHECKING:``, which do not run."""
    me = module_name(path)
    package = me if path.name == "__init__.py" else me.rpartition(".")[0]
    found: set[str] = set()

    def visit(node: ast.AST) -> None:
        for child in ast.iter_child_nodes(node):
            if isinstance(child, ast.If) and _type_checking(child.test):
                for stmt in child.orelse:
                    visit_one(stmt)
            else:
                visit_one(child)

    def visit_one(node: ast.AST) -> None:
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef | ast.Lambda) and not functions:
            return
        if isinstance(node, ast.Import):
            found.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = _from_module(node, package)
            for a in node.names:
                full = f"{base}.{a.name}"
                found.add(full if full in MODULES else base)
        visit(node)

    visit(ast.parse(source))
    return {m for m in found if m in MODULES and m != me}


def import_cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected groups of more than one module (Tarjan), each sorted."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    groups: list[list[str]] = []

    def connect(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        for w in sorted(graph.get(v, ())):
            if w not in index:
                connect(w)
                low[v] = min(low[v], low[w])
            elif w in stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            group = []
            while True:
                w = stack.pop()
                group.append(w)
                if w == v:
                    break
            if len(group) > 1:
                groups.append(sorted(group))

    for v in sorted(graph):
        if v not in index:
            connect(v)
    return sorted(groups)


def _graph(*, functions: bool) -> dict[str, set[str]]:
    return {
        name: app_imports(path.read_text(encoding="utf-8"), path, functions=functions)
        for name, path in MODULES.items()
    }


def test_no_module_level_import_cycle() -> None:
    """No two modules of the app need each other to load (a cycle works only by the order
    modules happen to be imported in)."""
    assert import_cycles(_graph(functions=False)) == []


#: The cycles closed by an import inside a function that are left, and why.
KNOWN_CYCLES = {
    # H5 (issue 25) owns these modules this round: the optimum's shortest duration and back.
    ("app.planning.optimal", "app.planning.shortest_duration"),
    # A bag's reader hands its messages to the robot-log reader, which opens bags with it.
    ("app.recordings._ros2_bag", "app.recordings.robot_logs"),
}


def test_no_new_import_cycle_through_functions() -> None:
    """Counting the imports inside functions too, only the known cycles are left (those of the
    robot and its engines, the robot loaders, the sidecar and the actuators, and the job
    service and the recordings were removed)."""
    cycles = {tuple(c) for c in import_cycles(_graph(functions=True))}
    assert cycles <= KNOWN_CYCLES, sorted(cycles - KNOWN_CYCLES)


def test_cycles_are_found_through_functions_only_when_asked(tmp_path: Path) -> None:
    a = APP / "planning" / "dynamics.py"
    source = "def f():\n    from app.planning.robots import _types\n"
    assert app_imports(source, a, functions=False) == set()
    assert app_imports(source, a, functions=True) == {"app.planning.robots._types"}
    hidden = "from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    import app.db\n"
    assert app_imports(hidden, a, functions=True) == set()
    graph = {"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}
    assert import_cycles(graph) == [["a", "b", "c"]]
