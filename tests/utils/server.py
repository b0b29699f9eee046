"""A real ``bioplan serve`` in its own process group, on free loopback ports."""

from __future__ import annotations

import contextlib
import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import httpx
import psutil


def free_port() -> int:
    """A TCP port nobody listens on right now (loopback)."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


class Server:
    """``python -m app.cli serve`` on a data folder, started from another folder.

    Args:
        data_dir: the server's data folder (``--data-dir``).
        demo: seed the demo session and comparison first (``--demo``).
        viewer: start the 3-D viewer (on a free port).
        env: more environment variables.
    """

    def __init__(
        self, data_dir: Path, *, demo: bool = False, viewer: bool = False, **env: str
    ) -> None:
        self.data_dir = data_dir
        self.port = free_port()
        self.url = f"http://127.0.0.1:{self.port}"
        self.viewer = viewer
        self.env = {
            **os.environ,
            "BIOPLAN_LOG_LEVEL": "warning",
            "BIOPLAN_VIEWER": "1" if viewer else "0",
            "BIOPLAN_VIEWER_PORT": str(free_port()),
            **env,
        }
        self.env.pop("BIOPLAN_API_TOKEN", None)
        self.args = [sys.executable, "-m", "app.cli", "serve", "--port", str(self.port)]
        self.args += ["--data-dir", str(data_dir)] + (["--demo"] if demo else [])
        self.log = data_dir.parent / f"server-{self.port}.log"
        self.proc: subprocess.Popen[bytes] | None = None

    def start(self, timeout: float = 300.0) -> Server:
        """Start and wait (generously: the demo and a busy machine take time) until it answers."""
        self.data_dir.parent.mkdir(parents=True, exist_ok=True)
        with self.log.open("wb") as log:
            self.proc = subprocess.Popen(
                self.args,
                cwd=self.data_dir.parent,  # not the repository: the package brings its pages
                env=self.env,
                stdout=log,
                stderr=subprocess.STDOUT,
                start_new_session=True,  # its own process group: cleanup kills only ours
            )
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if self.proc.poll() is not None:
                raise RuntimeError(f"the server exited: {self.log.read_text()[-3000:]}")
            with contextlib.suppress(httpx.HTTPError):
                if self._answers():
                    return self
            time.sleep(0.2)
        raise TimeoutError(f"the server did not start in {timeout} s: {self.log.read_text()}")

    def _answers(self) -> bool:
        if self.viewer and not httpx.get(self.url + "/api/viewer", timeout=2).json()["enabled"]:
            return False
        return httpx.get(self.url + "/api/health", timeout=2).status_code == 200

    @property
    def pid(self) -> int:
        assert self.proc is not None
        return self.proc.pid

    def descendants(self) -> list[psutil.Process]:
        return psutil.Process(self.pid).children(recursive=True)

    def sigkill(self) -> float:
        """SIGKILL the server process only (not its children); returns when it died [monotonic]."""
        assert self.proc is not None
        self.proc.send_signal(signal.SIGKILL)
        self.proc.wait(timeout=30)
        return time.monotonic()

    def stop(self) -> None:
        """Stop gracefully (SIGINT, uvicorn's shutdown), then kill what is left of its group."""
        if self.proc is None:
            return
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGINT)
            with contextlib.suppress(subprocess.TimeoutExpired):
                self.proc.wait(timeout=30)
        self.cleanup()

    def cleanup(self) -> None:
        if self.proc is not None:
            with contextlib.suppress(ProcessLookupError):
                os.killpg(self.proc.pid, signal.SIGKILL)
            self.proc.wait(timeout=30)

    def get(self, path: str, **kw: Any) -> Any:
        return httpx.get(self.url + path, timeout=60, **kw).json()

    def post(self, path: str, **kw: Any) -> httpx.Response:
        return httpx.post(self.url + path, timeout=60, **kw)

    def active_jobs(self) -> list[dict[str, Any]]:
        """The queued and running jobs (what a new job may wait behind)."""
        jobs: list[dict[str, Any]] = []
        for state in ("queued", "running"):
            jobs += self.get(f"/api/jobs?state={state}&limit=500")["items"]
        return jobs
