"""The on-disk cache of the compiled per-point dynamics (:mod:`app.planning.jit_cache`).

A fake compiler (a script that counts its runs and writes a recognisable object) checks the
cache's own logic; a real plan in two fresh interpreters checks that the second compiles
nothing and reaches the same optimum; the policy (compiled at every mesh with the cache, from
:data:`optimal.COMPILE_FROM_POINTS` points without it) is checked on a solve.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from app.planning import jit_cache, optimal
from app.planning.evaluation import PlanTask
from app.planning.optimal import HumanSpec, solve_optimal
from app.planning.robots import load_robot


@pytest.fixture
def fake_compiler(tmp_path: Path) -> tuple[Path, Path]:
    """(compiler, its log): writes ``object of <source text>`` to the ``-o`` file, logs a line
    per run and fails on a source containing ``error``."""
    log = tmp_path / "runs.log"
    script = tmp_path / "fakecc"
    script.write_text(
        textwrap.dedent(f"""\
        #!{sys.executable}
        import sys
        args = sys.argv[1:]
        src = next(a for a in args if a.endswith(".c"))
        text = open(src).read()
        open({str(log)!r}, "a").write(" ".join(args) + "\\n")
        if "error" in text:
            sys.exit(1)
        open(args[args.index("-o") + 1], "w").write("object of " + text)
        """)
    )
    script.chmod(0o755)
    return script, log


def _compile(folder: Path, compiler: Path, source: Path, obj: Path, *flags: str) -> int:
    return jit_cache.compile_cached(
        str(folder), str(compiler), [*flags, "-fPIC", "-c", str(source), "-o", str(obj)]
    )


@pytest.fixture
def folder(tmp_path: Path) -> Path:
    """An empty cache folder."""
    path = tmp_path / "cache"
    path.mkdir()
    return path


def _source(tmp_path: Path, text: str, name: str = "a.c") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def _runs(log: Path) -> int:
    return len(log.read_text().splitlines()) if log.exists() else 0


def test_a_second_compile_of_the_same_source_is_copied_from_the_cache(
    tmp_path: Path, folder: Path, fake_compiler: tuple[Path, Path]
) -> None:
    compiler, log = fake_compiler
    source = _source(tmp_path, "int f(void) { return 1; }")
    assert _compile(folder, compiler, source, tmp_path / "1.o", "-O1") == 0
    assert _compile(folder, compiler, source, tmp_path / "2.o", "-O1") == 0
    assert _runs(log) == 1
    assert (tmp_path / "2.o").read_text() == "object of int f(void) { return 1; }"
    # Other flags or another source are other objects.
    assert _compile(folder, compiler, source, tmp_path / "3.o", "-O2") == 0
    source.write_text("int f(void) { return 2; }")
    assert _compile(folder, compiler, source, tmp_path / "4.o", "-O1") == 0
    assert _runs(log) == 3
    assert (tmp_path / "4.o").read_text().endswith("return 2; }")
    assert len(list(folder.glob("*.o"))) == 3
    assert not list(folder.glob("*.tmp"))


def test_a_failed_compile_is_not_cached_and_keeps_its_status(
    tmp_path: Path, folder: Path, fake_compiler: tuple[Path, Path]
) -> None:
    compiler, log = fake_compiler
    source = _source(tmp_path, "error", "bad.c")
    assert _compile(folder, compiler, source, tmp_path / "1.o") == 1
    assert _compile(folder, compiler, source, tmp_path / "2.o") == 1
    assert _runs(log) == 2
    assert not list(folder.iterdir())


def test_an_unwritable_or_missing_cache_only_compiles(
    tmp_path: Path, fake_compiler: tuple[Path, Path]
) -> None:
    compiler, log = fake_compiler
    source = _source(tmp_path, "int x;")
    missing = tmp_path / "nowhere"
    assert _compile(missing, compiler, source, tmp_path / "1.o") == 0
    assert _compile(missing, compiler, source, tmp_path / "2.o") == 0
    assert _runs(log) == 2
    assert (tmp_path / "2.o").read_text() == "object of int x;"


def test_other_command_lines_pass_through(tmp_path: Path, fake_compiler: tuple[Path, Path]) -> None:
    """A link or any line without exactly one ``-c SOURCE.c -o OBJECT`` is run as is."""
    compiler, log = fake_compiler
    source = _source(tmp_path, "int x;")
    status = jit_cache.compile_cached(
        str(tmp_path), str(compiler), [str(source), "-o", str(tmp_path / "a.so")]
    )
    assert status == 0
    assert _runs(log) == 1
    assert not list(tmp_path.glob("*.o"))


def test_the_least_recently_used_objects_go_beyond_the_size_limit(
    tmp_path: Path, folder: Path, fake_compiler: tuple[Path, Path], monkeypatch: pytest.MonkeyPatch
) -> None:
    compiler, _ = fake_compiler
    monkeypatch.setattr(jit_cache, "MAX_BYTES", 70)
    for k in range(3):  # three objects of 34 bytes each: two fit
        source = _source(tmp_path, f"int source_number_{k}_pad;", f"s{k}.c")
        assert _compile(folder, compiler, source, tmp_path / f"{k}.o") == 0
        stamp = 1_000_000 + k  # compiled in this order, oldest first
        for obj in folder.glob("*.o"):
            if obj.stat().st_mtime > 2_000_000:
                os.utime(obj, (stamp, stamp))
    kept = sorted(obj.read_text() for obj in folder.glob("*.o"))
    assert kept == [f"object of int source_number_{k}_pad;" for k in (1, 2)]


def test_off_or_an_unsafe_folder_turns_the_cache_off(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("BIOPLAN_CACHE_DIR", str(tmp_path / "root"))
    monkeypatch.delenv(jit_cache.CACHE_ENV, raising=False)
    folder = jit_cache.cache_folder()
    assert folder == tmp_path / "root" / "jit"
    assert folder.stat().st_mode & 0o777 == 0o700
    command = jit_cache.compiler_command()
    assert command is not None and str(folder) in command
    assert jit_cache.compiler_command("no-such-compiler-anywhere") is None
    monkeypatch.setenv(jit_cache.CACHE_ENV, "off")
    assert jit_cache.cache_folder() is None and jit_cache.compiler_command() is None
    monkeypatch.delenv(jit_cache.CACHE_ENV)
    folder.chmod(0o777)  # others could plant objects the process would load
    assert jit_cache.cache_folder() is None
    folder.chmod(0o700)
    assert jit_cache.cache_folder() == folder
    (tmp_path / "file").write_text("")
    monkeypatch.setenv("BIOPLAN_CACHE_DIR", str(tmp_path / "file"))  # not a folder
    assert jit_cache.cache_folder() is None


def test_the_script_runs_as_casadis_compiler(
    tmp_path: Path, folder: Path, fake_compiler: tuple[Path, Path]
) -> None:
    """Run as CasADi runs it: a fresh interpreter on this file with ``FOLDER COMPILER --``."""
    compiler, log = fake_compiler
    source = _source(tmp_path, "int y;")
    script = jit_cache.__file__
    for k in range(2):
        out = tmp_path / f"{k}.o"
        args = [sys.executable, "-I", "-S", script, str(folder), str(compiler), "--"]
        subprocess.run([*args, "-O1", "-c", str(source), "-o", str(out)], check=True)
        assert out.read_text() == "object of int y;"
    assert _runs(log) == 1
    bad = subprocess.run([sys.executable, script, str(folder)], capture_output=True, text=True)
    assert bad.returncode == 2 and "usage" in bad.stderr


_PLAN = """
import json, resource
from app.planning import optimal
from app.planning.evaluation import PlanTask
from app.planning.optimal import HumanSpec, solve_optimal
from app.planning.robots import load_robot
arm = load_robot("human_arm_2dof")
task = PlanTask.default(arm)
res = solve_optimal(arm, task.start, task.goal, 1.0, objective="tau_sq",
                    human=HumanSpec("none", arm.elbow_joint), n_intervals=16)
names = sorted({f.name() for f in optimal._COMPILED.values() if f is not None})
print(json.dumps({"objective": res.solver.objective, "compiled": names}))
"""


@pytest.mark.skipif(shutil.which("gcc") is None, reason="no C compiler (gcc) on this machine")
def test_a_second_process_compiles_nothing_and_solves_alike(tmp_path: Path) -> None:
    """Two fresh interpreters plan the same chain: the first compiles the dynamics (even on 16
    intervals: the cache is on), the second finds every object cached."""
    env = {**os.environ, "BIOPLAN_CACHE_DIR": str(tmp_path / "root")}
    env.pop(jit_cache.CACHE_ENV, None)
    folder = tmp_path / "root" / "jit"
    results, counts = [], []
    for _ in range(2):
        run = subprocess.run(
            [sys.executable, "-c", _PLAN], env=env, capture_output=True, text=True, check=True
        )
        results.append(json.loads(run.stdout.strip().splitlines()[-1]))
        counts.append(sorted(p.name for p in folder.glob("*.o")))
    assert results[0]["compiled"] == ["reduced_dynamics_c"]
    assert results[0]["objective"] == pytest.approx(results[1]["objective"], rel=1e-12)
    assert counts[0] and counts[0] == counts[1]  # nothing new: every compile was a hit
    off = subprocess.run(
        [sys.executable, "-c", _PLAN], env={**env, jit_cache.CACHE_ENV: "off"},
        capture_output=True, text=True, check=True,
    )  # fmt: skip
    result_off = json.loads(off.stdout.strip().splitlines()[-1])
    assert result_off["compiled"] == []  # 16 intervals: below COMPILE_FROM_POINTS
    assert result_off["objective"] == pytest.approx(results[0]["objective"], rel=1e-9)


def test_without_the_cache_the_threshold_decides(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("BIOPLAN_CACHE_DIR", str(tmp_path))
    monkeypatch.setenv(jit_cache.CACHE_ENV, "off")
    assert optimal._compile_from_points() == optimal.COMPILE_FROM_POINTS
    monkeypatch.delenv(jit_cache.CACHE_ENV)
    assert optimal._compile_from_points() == 0
    arm = load_robot("human_arm_2dof")
    task = PlanTask.default(arm)
    monkeypatch.setenv(jit_cache.CACHE_ENV, "off")
    monkeypatch.setattr(optimal, "_COMPILED", {})
    optimal._SOLVERS.clear()
    solve_optimal(
        arm, task.start, task.goal, 1.0, objective="tau_sq",
        human=HumanSpec("none", arm.elbow_joint), n_intervals=16,
    )  # fmt: skip
    optimal._SOLVERS.clear()
    assert optimal._COMPILED == {}
