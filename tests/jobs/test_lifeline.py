"""The two links that make job processes die with the server (``app.jobs._lifeline``), each on
its own: this test is the child subreaper, so it receives the orphans and reads how they ended."""

from __future__ import annotations

import subprocess
import sys
import textwrap
import time

from tests.utils.reaper import reap, subreaper

SLEEPER = [sys.executable, "-c", "import time; time.sleep(600)"]


def _run(code: str) -> list[int]:
    """Run ``code`` in a new Python process; the pids it prints, once it has exited."""
    proc = subprocess.run(
        [sys.executable, "-c", textwrap.dedent(code)],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert proc.returncode == 0, proc.stderr
    return [int(p) for p in proc.stdout.split()]


def test_the_group_reaper_kills_what_an_ended_job_left_behind() -> None:
    """A job process that started a helper (a sweep's pool worker) and then ended: the reaper
    it forked kills the helper and itself, by SIGKILL."""
    code = f"""
        import os, subprocess
        from app.jobs._lifeline import reap_group_on_exit
        os.setsid()
        reaper = reap_group_on_exit()
        helper = subprocess.Popen({SLEEPER!r})
        print(reaper, helper.pid, flush=True)
        os._exit(0)  # the job process ends however it ends; its helper is left behind
    """
    with subreaper():
        pids = _run(code)
        endings = reap(pids, time.monotonic(), timeout=120)
    assert set(endings) == set(pids)
    assert all(e.killed for e in endings.values()), endings


def test_a_process_dies_with_its_parent() -> None:
    """``die_with_parent``: when its parent exits, the kernel sends it SIGKILL."""
    code = f"""
        import os, subprocess
        child = subprocess.Popen([
            *{SLEEPER[:2]!r},
            "import os, time; from app.jobs._lifeline import die_with_parent; "
            "die_with_parent(os.getppid()); print('armed', flush=True); time.sleep(600)",
        ], stdout=subprocess.PIPE, text=True)
        assert child.stdout.readline().strip() == "armed"
        print(child.pid, flush=True)
        os._exit(0)  # the parent dies without waiting for its child
    """
    with subreaper():
        (pid,) = _run(code)
        endings = reap([pid], time.monotonic(), timeout=120)
    assert endings[pid].killed, endings
