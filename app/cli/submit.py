"""``bioplan submit``: run one job on a running server and print its result.

A small HTTP client (standard library only) for scripted use of a running server: upload
recordings, submit a job with the CLI's options, wait for it, print the result in the CLI's JSON
shape.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
import urllib.error
import urllib.parse
import urllib.request
import uuid
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from app.cli._common import (
    DURATION_HELP,
    EXIT_BAD_INPUT,
    EXIT_FAILED,
    EXIT_OK,
    add_options,
    options_from_args,
    write_out,
)
from app.cli.front import FRONT_DURATION_HELP, add_front_args, check_front_args
from app.names import TERMINAL_JOB_STATES
from app.options import Options
from app.planning.options import MethodOptions
from app.simulation.options import SweepGrid


class ServiceError(Exception):
    """The server answered with a problem (or could not be reached)."""

    def __init__(self, status: int, detail: str) -> None:
        super().__init__(detail)
        self.status = status


class Client:
    """A minimal JSON client of the BioPlan API (urllib only).

    Args:
        server: base URL, e.g. ``http://127.0.0.1:8000``.
        token: API token for writes, when the server has one.
        timeout: seconds per HTTP request.
    """

    def __init__(self, server: str, *, token: str | None = None, timeout: float = 60.0) -> None:
        self.server = server.rstrip("/")
        self.token = token
        self.timeout = timeout

    def request(
        self,
        method: str,
        path: str,
        *,
        json_body: Any = None,
        data: bytes | None = None,
        content_type: str | None = None,
        params: dict[str, Any] | None = None,
    ) -> Any:
        url = self.server + path
        if params:
            url += "?" + urllib.parse.urlencode(params, doseq=True)
        headers = {"Accept": "application/json"}
        if json_body is not None:
            data = json.dumps(json_body).encode()
            content_type = "application/json"
        if content_type:
            headers["Content-Type"] = content_type
        if self.token:
            headers["Authorization"] = f"Bearer {self.token}"
        req = urllib.request.Request(url, data=data, method=method, headers=headers)
        try:
            with urllib.request.urlopen(req, timeout=self.timeout) as resp:
                body = resp.read()
        except urllib.error.HTTPError as exc:
            text = exc.read().decode("utf-8", "replace")
            try:
                problem = json.loads(text)
                detail = problem.get("detail") or problem.get("title") or text
                for key in ("field", "file"):
                    if problem.get(key):
                        detail = f"{detail} ({key}: {problem[key]})"
            except json.JSONDecodeError:
                detail = text or exc.reason
            raise ServiceError(exc.code, f"{method} {path}: {exc.code} {detail}") from None
        except urllib.error.URLError as exc:
            raise ServiceError(0, f"cannot reach {self.server}: {exc.reason}") from None
        return json.loads(body) if body else None

    def upload(self, paths: Sequence[Path], fields: dict[str, str]) -> dict[str, Any]:
        """POST /api/recordings with the files and form fields; returns the recording."""
        boundary = f"bioplan-{uuid.uuid4().hex}"
        parts: list[bytes] = []
        for name, value in fields.items():
            parts.append(
                f'--{boundary}\r\nContent-Disposition: form-data; name="{name}"\r\n\r\n'
                f"{value}\r\n".encode()
            )
        for path in paths:
            quoted = path.name.replace('"', "'")
            parts.append(
                f'--{boundary}\r\nContent-Disposition: form-data; name="files"; '
                f'filename="{quoted}"\r\nContent-Type: application/octet-stream\r\n\r\n'.encode()
                + path.read_bytes()
                + b"\r\n"
            )
        parts.append(f"--{boundary}--\r\n".encode())
        out: dict[str, Any] = self.request(
            "POST",
            "/api/recordings",
            data=b"".join(parts),
            content_type=f"multipart/form-data; boundary={boundary}",
        )
        return out

    def wait(
        self, job_id: int, *, timeout: float = 3600.0, on_progress: Any = None
    ) -> dict[str, Any]:
        """Poll a job until it ends; returns the final job."""
        deadline = time.monotonic() + timeout
        delay = 0.2
        while True:
            job: dict[str, Any] = self.request("GET", f"/api/jobs/{job_id}")
            if on_progress is not None:
                on_progress(job)
            if job["state"] in TERMINAL_JOB_STATES:
                return job
            if time.monotonic() > deadline:
                raise ServiceError(0, f"job {job_id} still {job['state']} after {timeout:.0f} s")
            time.sleep(delay)
            delay = min(delay * 1.5, 2.0)


def _floats(text: str | None) -> list[float] | None:
    if text is None:
        return None
    return [float(v) for v in text.replace(",", " ").split()]


#: The options ``submit plan``/``submit simulate`` send (``MethodOptions``' fields) ...
TASK_OPTIONS = ("objective", "seed", "particles", "iterations", "peak_angle_deg")
#: ... and ``submit sweep`` (``SweepGrid``'s).
SWEEP_OPTIONS = ("durations", "payloads", "objectives", "seed")


def _sent(cls: type[Options], args: argparse.Namespace, names: Sequence[str]) -> dict[str, Any]:
    """Options ``names`` of ``cls`` from the flags, checked here (a CliError naming the flag)
    before anything is sent; by the API's names."""
    options = options_from_args(cls, args).to_dict()
    return {name: options[name] for name in names}


def _task_body(args: argparse.Namespace) -> dict[str, Any]:
    """The task's start and goal and the template of a plan, simulation or front request."""
    body: dict[str, Any] = {
        "start_deg": _floats(args.start_deg),
        "goal_deg": _floats(args.goal_deg),
    }
    if args.template:
        body["template"] = json.loads(Path(args.template).read_text(encoding="utf-8"))
    return body


def _job_body(args: argparse.Namespace) -> tuple[str, dict[str, Any]]:
    """The endpoint and request body for ``bioplan submit <kind>`` (CLI names -> API names)."""
    if args.kind in ("plan", "simulate"):
        body: dict[str, Any] = {
            "robot": args.robot,
            "duration": args.duration,
            "payload": args.payload,
            **_sent(MethodOptions, args, TASK_OPTIONS),
            **_task_body(args),
        }
        path = "/api/plans" if args.kind == "plan" else "/api/simulations"
        return path, {k: v for k, v in body.items() if v is not None}
    if args.kind == "sweep":
        return "/api/sweeps", {"robot": args.robot, **_sent(SweepGrid, args, SWEEP_OPTIONS)}
    if args.kind == "front":
        # `bioplan front`'s own checks first: bad input is refused naming the option, as there,
        # before anything is sent.
        a, b = check_front_args(args)
        body = {
            "robot": args.robot,
            "payload_mass": args.payload,
            "objectives": [a, b],
            "duration": args.duration,
            "max_duration": args.max_duration,
            "points": args.points,
            "method": args.method,
            "intervals": args.intervals,
            "tolerance": args.tolerance,
            "allow_reversal": args.allow_reversal,
            **_task_body(args),
        }
        return "/api/fronts", {k: v for k, v in body.items() if v is not None}
    raise ValueError(f"unknown kind {args.kind}")


def _progress_shower(quiet: bool) -> Any:
    """A callback that draws a job's progress on stderr (or nothing when ``quiet``)."""

    def show(job: dict[str, Any]) -> None:
        if not quiet:
            bar = "#" * int(30 * job["progress"])
            print(
                f"\r[{bar:<30}] {job['state']:<9} {job['message'][:50]:<50}",
                end="",
                file=sys.stderr,
            )

    return show


def _request_of(client: Client, args: argparse.Namespace) -> tuple[str, dict[str, Any]]:
    """The endpoint and body of the job; ``analyze`` uploads its files first."""
    if args.kind != "analyze":
        return _job_body(args)
    fields = {
        k: str(v)
        for k, v in (("subject", args.subject), ("task", args.task),
                     ("load_kg", args.load_kg), ("emg_rate", args.emg_rate))
        if v is not None
    }  # fmt: skip
    if args.muscle:
        fields["muscle_map"] = json.dumps(dict(m.split("=", 1) for m in args.muscle))
    rec = client.upload([Path(f) for f in args.files], fields)
    print(f"uploaded recording {rec['id']}", file=sys.stderr)
    return "/api/analyses", {"recording_id": rec["id"]}


def _run_job(client: Client, args: argparse.Namespace) -> tuple[dict[str, Any], Any]:
    """Submit, wait, fetch: (the final job, its result resource or None when it did not
    succeed or ``--no-wait``)."""
    path, body = _request_of(client, args)
    job = client.request("POST", path, json_body=body)
    print(f"job {job['id']} ({job['kind']}) queued: {args.server}{job['result_url']}",
          file=sys.stderr)  # fmt: skip
    if args.no_wait:
        return job, None
    quiet = args.json or not sys.stderr.isatty()
    job = client.wait(job["id"], timeout=args.timeout, on_progress=_progress_shower(quiet))
    if not quiet:
        print(file=sys.stderr)
    if job["state"] != "succeeded":
        return job, None
    return job, client.request("GET", job["result_url"])


def submit(args: argparse.Namespace) -> int:
    """``bioplan submit``: run one job on a server and print its result.

    Returns:
        0 when the job succeeded, 1 when it failed or was cancelled, 2 for bad input.
    """
    client = Client(args.server, token=args.token, timeout=args.http_timeout)
    try:
        job, out = _run_job(client, args)
    except ServiceError as exc:
        print(f"bioplan submit: error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT if 400 <= exc.status < 500 else EXIT_FAILED
    except (OSError, ValueError) as exc:  # unreadable files, malformed --template JSON
        print(f"bioplan submit: error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    if args.no_wait:
        print(json.dumps(job, indent=2))
        return EXIT_OK
    if out is None:
        print(f"bioplan submit: job {job['id']} {job['state']}: {job['error'] or ''}",
              file=sys.stderr)  # fmt: skip
        return EXIT_FAILED
    result = out.get("result")
    if args.out:
        # Like `bioplan analyze --out`: the template; otherwise the result JSON.
        payload = out.get("template") if args.kind == "analyze" else result
        write_out(args.out, json.dumps(payload, indent=2) + "\n")
    if args.json:
        print(json.dumps(result, indent=2))
    else:
        print(f"job {job['id']} succeeded in {job['run_seconds']:.2f} s; "
              f"result: {args.server}{job['result_url']}")  # fmt: skip
    return EXIT_OK


def register(sub: Any) -> None:
    """Add ``submit`` to the ``bioplan`` subcommands."""
    p = sub.add_parser(
        "submit", help="run a job on a running server (upload, submit, wait, print the result)"
    )
    p.add_argument(
        "--server",
        default=os.environ.get("BIOPLAN_SERVER", "http://127.0.0.1:8000"),
        help="server URL (default $BIOPLAN_SERVER or http://127.0.0.1:8000)",
    )
    p.add_argument(
        "--token", default=os.environ.get("BIOPLAN_API_TOKEN"), help="API token for writes"
    )
    p.add_argument("--no-wait", action="store_true", help="print the queued job and return")
    p.add_argument("--timeout", type=float, default=3600.0, help="seconds to wait for the job")
    p.add_argument("--http-timeout", type=float, default=120.0, help=argparse.SUPPRESS)
    p.add_argument("--json", action="store_true", help="print the result as one JSON object")
    p.add_argument("--out", default=None, help="write the result (analyze: the template) here")
    kinds = p.add_subparsers(dest="kind", required=True)

    def task_args(q: argparse.ArgumentParser) -> None:
        q.add_argument("--robot", default="curtain_wall_6dof", help="built-in or uploaded robot")
        q.add_argument("--duration", type=float, default=1.0, help=DURATION_HELP)
        q.add_argument("--payload", type=float, default=None, help="payload [kg]")
        add_options(q, MethodOptions, only=TASK_OPTIONS)
        q.add_argument("--start-deg", default=None, help="start joint angles, comma-separated")
        q.add_argument("--goal-deg", default=None, help="goal joint angles, comma-separated")
        q.add_argument("--template", default=None, help="HumanTemplate JSON file")

    task_args(kinds.add_parser("plan", help="bioplan plan, on the server"))
    task_args(kinds.add_parser("simulate", help="bioplan simulate, on the server"))
    q = kinds.add_parser("sweep", help="bioplan sweep, on the server")
    q.add_argument("--robot", default="curtain_wall_6dof", help="built-in or uploaded robot")
    add_options(q, SweepGrid, only=SWEEP_OPTIONS)
    q = kinds.add_parser("front", help="bioplan front, on the server (with its references)")
    q.add_argument("--robot", default="curtain_wall_6dof", help="built-in or uploaded robot")
    q.add_argument("--duration", type=float, default=None, help=FRONT_DURATION_HELP)
    q.add_argument(
        "--payload", type=float, default=None, help="payload [kg] (default: the robot's)"
    )
    q.add_argument("--start-deg", default=None, help="start joint angles, comma-separated")
    q.add_argument("--goal-deg", default=None, help="goal joint angles, comma-separated")
    add_front_args(q)
    q = kinds.add_parser("analyze", help="upload recordings and analyse them on the server")
    q.add_argument("files", nargs="+", help="recording files of one session")
    q.add_argument("--subject", default=None, help="who lifted")
    q.add_argument("--task", default=None, help="what was lifted, how")
    q.add_argument("--load-kg", type=float, default=None, help="load lifted [kg]")
    q.add_argument("--emg-rate", type=float, default=None, help="override the EMG rate [Hz]")
    q.add_argument(
        "--muscle", action="append", default=None, metavar="LABEL=SITE", help="map a channel"
    )
    p.set_defaults(handler=submit)
