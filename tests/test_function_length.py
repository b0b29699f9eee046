"""No function or method in ``app/`` is longer than 80 lines (``def`` line to its last line,
docstring included, decorators not), unless it is listed below with the reason it may be.

A long function is split into named steps (STYLE.md: "functions short enough to read at
once"); the list only shrinks. An entry whose function is gone or now short is an error too,
so the list never hides a new long function under an old name.
"""

from __future__ import annotations

import ast
from pathlib import Path

from tests.utils.data import REPO_ROOT

APP = REPO_ROOT / "app"
MAX_LINES = 80

#: ``path:qualname`` -> why it may stay over MAX_LINES.
ALLOWED: dict[str, str] = {
    # A migration is history: the schema it makes never changes (a new revision changes it;
    # tests/db/test_migration_schemas.py holds every revision's schema), so its table list
    # stays one readable block rather than being cut into arbitrary pieces.
    "app/db/migrations/versions/0001_initial_schema.py:upgrade": "migration history: one "
    "block per revision, its schema pinned by test_migration_schemas",
}


def function_lengths(source: str) -> dict[str, int]:
    """``qualname`` -> lines from ``def`` to the last line, for every function in ``source``
    (methods as ``Class.name``, nested functions as ``outer.<locals>.inner``)."""
    out: dict[str, int] = {}

    def walk(node: ast.AST, prefix: str) -> None:
        for child in ast.iter_child_nodes(node):
            if isinstance(child, ast.FunctionDef | ast.AsyncFunctionDef):
                name = prefix + child.name
                assert child.end_lineno is not None
                out[name] = child.end_lineno - child.lineno + 1
                walk(child, name + ".<locals>.")
            elif isinstance(child, ast.ClassDef):
                walk(child, prefix + child.name + ".")
            else:
                walk(child, prefix)

    walk(ast.parse(source), "")
    return out


def app_function_lengths() -> dict[str, int]:
    """``path:qualname`` -> length, for every function under ``app/``."""
    lengths: dict[str, int] = {}
    for path in sorted(APP.rglob("*.py")):
        rel = path.relative_to(REPO_ROOT).as_posix()
        for name, n in function_lengths(path.read_text(encoding="utf-8")).items():
            lengths[f"{rel}:{name}"] = n
    return lengths


def test_counter_measures_functions_methods_and_nested_ones() -> None:
    body = "\n".join(f"    x{i} = {i}" for i in range(79))
    source = (
        "import functools\n\n"
        "@functools.cache\n"  # decorators are not counted
        f"def long_one():\n{body}\n    return 0\n\n"
        "class C:\n"
        "    def method(self):\n"
        '        """Doc."""\n\n'
        "        def inner():\n"
        "            return 1\n"
        "        return inner()\n"
    )
    lengths = function_lengths(source)
    assert lengths == {
        "long_one": 81,
        "C.method": 6,
        "C.method.<locals>.inner": 2,
    }
    assert [name for name, n in lengths.items() if n > MAX_LINES] == ["long_one"]


def test_no_function_in_app_is_over_80_lines_unless_listed() -> None:
    lengths = app_function_lengths()
    assert len(lengths) > 1000  # the walk saw the whole package
    too_long = {
        name: n for name, n in sorted(lengths.items()) if n > MAX_LINES and name not in ALLOWED
    }
    assert not too_long, (
        f"functions over {MAX_LINES} lines (split them into named steps, or list them in "
        f"ALLOWED with a reason): {too_long}"
    )


def test_every_allowed_function_exists_and_is_still_long() -> None:
    lengths = app_function_lengths()
    stale = {name: lengths.get(name) for name in ALLOWED if lengths.get(name, 0) <= MAX_LINES}
    assert not stale, f"remove these from ALLOWED (gone: None, or now short): {stale}"
    assert all(reason.strip() for reason in ALLOWED.values())


def test_allowed_paths_are_files_of_app() -> None:
    for name in ALLOWED:
        path = name.split(":", 1)[0]
        assert path.startswith("app/") and (REPO_ROOT / Path(path)).is_file(), name
