"""The demo for ``bioplan serve --demo`` (``make run``): a recording and a finished comparison.

``seed_demo(settings)`` stores, when the database has no recordings yet, one synthetic but
realistic curl session (four EMG sites and the elbow and shoulder angles, written as the CSV a
lab exports) through the same parse, store and job path as an upload, then runs its analysis and
a plan and a simulation that use the recorded human template. The shared data folder is not
needed: the recording is generated here, from a seed.
"""

from __future__ import annotations

import io
import json
import logging
import time
from collections.abc import Callable
from typing import TypedDict, Unpack

import numpy as np
from numpy.typing import NDArray

from app.config import Settings
from app.db import crud
from app.names import DEFAULT_OBJECTIVE, PHASE_BOUNDS_DEG, STANDARD_METHODS, TERMINAL_JOB_STATES
from app.services.core import Services, start_services, stop_services
from app.services.recordings import store_recording

logger = logging.getLogger(__name__)

FloatArray = NDArray[np.float64]

DEMO_NAME = "demo_curls_12kg.csv"
DEMO_SUBJECT = "demo subject"
DEMO_TASK = "dumbbell curl, 12 kg (synthetic demo)"
#: EMG column -> site, the mapping a user would give in the upload form.
DEMO_MUSCLES = {
    "Deltoid anterior": "deltoid",
    "Triceps brachii": "triceps",
    "Biceps brachii": "biceps",
    "Brachioradialis": "forearm",
}
# Onset of each muscle relative to the start of the lift [s] and its peak amplitude [uV]: the
# deltoid first, triceps and biceps together, the forearm muscle last and weakest (PAPER.md).
_EMG_TIMING = {
    "Deltoid anterior": (-0.22, 180.0),
    "Triceps brachii": (-0.10, 120.0),
    "Biceps brachii": (-0.10, 420.0),
    "Brachioradialis": (0.05, 90.0),
}


def _curl_profile(s: FloatArray, peak_fraction: float) -> FloatArray:
    """A rest-to-rest stroke 0 -> 1 over s in [0, 1] whose speed peaks at ``peak_fraction``.

    A minimum-jerk stroke of a warped time: w(s) = s^a with a chosen so that the warped speed
    peaks near ``peak_fraction`` of the lift (humans accelerate early and coast through B).
    """
    a = np.log(0.5) / np.log(peak_fraction)
    w = np.clip(s, 0.0, 1.0) ** a
    return np.asarray(10 * w**3 - 15 * w**4 + 6 * w**5, dtype=np.float64)


class CurlOptions(TypedDict, total=False):
    """Keywords of :func:`synthetic_curls`."""

    lifts: int
    rate: float
    seed: int
    rest: float
    up: float
    hold: float
    down: float


def synthetic_curls(
    *,
    lifts: int = 4,
    rate: float = 1000.0,
    seed: int = 0,
    rest: float = 1.6,
    up: float = 1.3,
    hold: float = 0.5,
    down: float = 1.5,
) -> dict[str, FloatArray]:
    """A synthetic curl session: EMG of the four sites and elbow/shoulder flexion.

    Args:
        lifts: number of curls.
        rate: sampling rate [Hz].
        seed: noise seed (the same seed gives the same bytes).
        rest, up, hold, down: durations of the rest before each lift, the concentric part, the
            hold at the top and the eccentric part [s].

    Returns:
        ``"t"`` (N,) [s], one (N,) array per EMG column [uV], ``"elbow_flexion"`` and
        ``"shoulder_flexion"`` (N,) [deg].
    """
    rng = np.random.default_rng(seed)
    period = rest + up + hold + down
    total = lifts * period + rest
    t = np.arange(round(total * rate)) / rate
    elbow = np.full(t.shape, 8.0)
    shoulder = np.full(t.shape, 2.0)
    activation = {name: np.zeros(t.shape) for name in _EMG_TIMING}
    for k in range(lifts):
        t0 = rest + k * period
        top = 140.0 + 6.0 * rng.standard_normal()
        rise = _curl_profile((t - t0) / up, 0.38 + 0.03 * rng.standard_normal())
        fall = _curl_profile((t - t0 - up - hold) / down, 0.5)
        stroke = np.where(t < t0 + up + hold, rise, 1.0 - fall)
        inside = (t >= t0) & (t <= t0 + up + hold + down)
        elbow = np.where(inside, 8.0 + (top - 8.0) * stroke, elbow)
        shoulder = np.where(inside, 2.0 + 14.0 * stroke, shoulder)
        for name, (onset, amplitude) in _EMG_TIMING.items():
            # Roughly parabolic activity while lifting, a lower plateau while lowering.
            s = (t - (t0 + onset)) / (up - onset + 0.1)
            burst = np.clip(4.0 * s * (1.0 - s), 0.0, None)
            ecc = (t > t0 + up) & (t < t0 + up + hold + down)
            level = np.where(ecc, 0.35, 0.0) * (amplitude / 420.0) ** 0.5
            activation[name] += amplitude * np.maximum(burst, level * 1.0)
    out: dict[str, FloatArray] = {"t": t}
    for name, act in activation.items():
        # Surface EMG: zero-mean noise whose spread follows the activation, plus 4 uV baseline.
        out[name] = (act + 4.0) * rng.standard_normal(t.shape)
    out["elbow_flexion"] = elbow + 0.03 * rng.standard_normal(t.shape)
    out["shoulder_flexion"] = shoulder + 0.02 * rng.standard_normal(t.shape)
    return out


def synthetic_curls_csv(**kwargs: Unpack[CurlOptions]) -> bytes:
    """:func:`synthetic_curls` as the CSV a lab exports (time, EMG in uV, angles in deg)."""
    data = synthetic_curls(**kwargs)
    emg = [name for name in _EMG_TIMING]
    header = ["time (s)", *(f"{name} (uV)" for name in emg), "elbow_flexion (deg)"]
    header.append("shoulder_flexion (deg)")
    columns = [data["t"], *(data[name] for name in emg), data["elbow_flexion"]]
    columns.append(data["shoulder_flexion"])
    table = np.column_stack(columns)
    buf = io.StringIO()
    buf.write(",".join(header) + "\n")
    np.savetxt(buf, table, fmt=["%.4f"] + ["%.3f"] * (len(header) - 1), delimiter=",")
    return buf.getvalue().encode()


#: What the demo plans and simulates with the recorded template (a small swarm: it runs at
#: every first start of ``make run``), with every method, as a plan from the page has.
DEMO_TASK_PARAMS: dict[str, object] = {
    "robot": "curtain_wall_6dof",
    "methods": list(STANDARD_METHODS),
    "duration": 1.0,
    "payload": 4.0,
    "objective": DEFAULT_OBJECTIVE,
    "seed": 0,
    "particles": 30,
    "iterations": 60,
}

Say = Callable[[str], None]


def _quiet(line: str) -> None:
    logger.info("%s", line)


def _wait(services: Services, job_id: int, timeout: float, say: Say) -> dict[str, object]:
    """Wait for a demo job, telling ``say`` each time its stage changes."""
    deadline = time.monotonic() + timeout
    shown = ""
    while time.monotonic() < deadline:
        job = services.jobs.get(job_id)
        if job["state"] in TERMINAL_JOB_STATES:
            if job["state"] != "succeeded":
                raise RuntimeError(
                    f"demo {job['kind']} job {job_id} {job['state']}: {job['error']}"
                )
            say(f"  {job['kind']} #{job_id} done in {job['run_seconds']:.1f} s")
            return job
        line = f"  {job['kind']} #{job_id}: {job['state']} {job['stage']} ".rstrip()
        if job["state"] == "running" and line != shown:
            say(line)
            shown = line
        time.sleep(0.1)
    raise TimeoutError(f"demo job {job_id} did not finish within {timeout:g} s")


def _store_demo_recording(services: Services) -> int:
    """Store the synthetic session through the upload path; returns the recording id."""
    options = {"muscle_map": dict(DEMO_MUSCLES)}
    meta = {
        "subject": DEMO_SUBJECT,
        "task": DEMO_TASK,
        "load_kg": 12.0,
        "notes": "Generated by bioplan serve --demo: four curls, four EMG sites, elbow and "
        "shoulder goniometers, 1 kHz. Mapping: " + json.dumps(DEMO_MUSCLES),
    }
    with services.sessions() as session:
        rec = store_recording(
            session=session,
            blobs=services.blobs,
            files=[(DEMO_NAME, synthetic_curls_csv())],
            meta=meta,
            options=options,
        )
        return rec.id


def seed_into(
    services: Services, *, timeout: float = 300.0, say: Say = _quiet
) -> dict[str, int] | None:
    """Seed running services (see :func:`seed_demo`).

    Args:
        services: the running services.
        timeout: seconds each demo job may take.
        say: called with a line for people at each step.

    Returns:
        The ids of the new recording, analysis, plan and simulation; None when the database
        already had recordings (nothing is added).
    """
    with services.sessions() as session:
        _, total = crud.list_recordings(session=session, limit=1)
    if total:
        return None
    say("demo: storing a synthetic session of four curls")
    recording_id = _store_demo_recording(services)
    jobs = services.jobs
    analysis = jobs.submit(
        kind="analysis",
        params={
            "recording_id": recording_id,
            "phase_bounds_deg": list(PHASE_BOUNDS_DEG),
            "body_mass": 75.0,
            "body_height": 1.75,
        },
        resource={"recording_id": recording_id},
    )
    say("demo: analysing it (lifts, phases, the human template)")
    _wait(services, analysis["id"], timeout, say)
    task = {**DEMO_TASK_PARAMS, "template_analysis_id": analysis["id"]}
    robot = {"robot": str(task["robot"])}
    plan = jobs.submit(kind="plan", params={**task, "n_samples": 100}, resource=robot)
    simulation = jobs.submit(kind="simulation", params=task, resource=robot)
    say(f"demo: planning and simulating {task['robot']} with its template (PSO)")
    for job in (plan, simulation):
        _wait(services, job["id"], timeout, say)
    ids = {
        "recording": recording_id,
        "analysis": analysis["id"],
        "plan": plan["id"],
        "simulation": simulation["id"],
    }
    logger.info("demo data seeded: %s", ids)
    return ids


def seed_demo(settings: Settings, *, say: Say = _quiet) -> dict[str, int] | None:
    """Store a demo recording, its analysis, a plan and a simulation if there are no recordings.

    Starts the service's database and job runner (migrating first), runs the jobs to the end
    and stops them again; call it before the server starts.
    """
    services = start_services(settings)
    try:
        return seed_into(services, say=say)
    finally:
        stop_services(services)
