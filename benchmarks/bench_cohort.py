"""A 30-recording cohort: ``cohort_statistics`` on 15 subjects x 2 conditions, each recording
10 minutes of synthetic surface EMG at 2 kHz (issue 29: target <= 60 s for the whole cohort).

Run:  .venv/bin/python benchmarks/bench_cohort.py [--recordings 30] [--minutes 10]
      [--muscles 2] [--repeats 3] [--json]

Each recording has ``--muscles`` EMG channels (biceps, forearm, deltoid, triceps: the first N)
of Gaussian noise whose amplitude rises in a burst per curl (one curl every 4.9 s, about 122 in
10 minutes; the second condition's bursts are 10 % longer and the forearm's onset 50 ms later),
built in memory before the clock starts. Timed, in one warm process, median of ``--repeats``:
the whole ``cohort_statistics`` call (every recording analysed by the pipeline, measured, the
groups summarised and tested). Also given in CPU seconds of this process
(``time.process_time``), which other processes' load does not inflate.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

RATE = 2000.0
CYCLE_S = 4.9
SITES = ("biceps", "forearm", "deltoid", "triceps")


def synthetic_recording(
    name: str, minutes: float, muscles: int, *, seed: int, stretch: float, lag: float
) -> Any:
    """One recording: ``muscles`` EMG channels [V] at 2 kHz with a burst per curl."""
    from app.recordings.types import Channel, Recording

    rng = np.random.default_rng(seed)
    n = int(minutes * 60.0 * RATE)
    t = np.arange(n) / RATE
    starts = np.arange(1.5, minutes * 60.0 - CYCLE_S, CYCLE_S)
    # One burst shape per curl, added on its window only (a full-length Gaussian per burst
    # would cost 122 passes over 1.2 M samples).
    width = 0.45 * stretch
    channels = {}
    for k, site in enumerate(SITES[:muscles]):
        gain = np.full(n, 0.05)
        shift = 0.6 + (lag if site == "forearm" else 0.0) - 0.05 * k
        for t0 in starts:
            i0, i1 = np.searchsorted(t, [t0, t0 + 2.5 * stretch])
            gain[i0:i1] += np.exp(-(((t[i0:i1] - t0 - shift * stretch) / width) ** 2))
        data = 1e-4 * gain * rng.standard_normal(n)
        channels[site] = Channel(site, data, RATE, "V", "emg", site=site)  # type: ignore[arg-type]
    return Recording(channels, source=name, format="synthetic")


def cohort(recordings: int, minutes: float, muscles: int) -> dict[str, list[Any]]:
    subjects = recordings // 2
    return {
        cond: [
            synthetic_recording(
                f"sub-{s:02d}_task-{cond}_emg.edf",
                minutes,
                muscles,
                seed=100 * s + c,
                stretch=1.0 + 0.1 * c,
                lag=0.05 * c,
            )
            for s in range(1, subjects + 1)
        ]
        for c, cond in enumerate(("neutral", "supinated"))
    }


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--recordings", type=int, default=30)
    parser.add_argument("--minutes", type=float, default=10.0)
    parser.add_argument("--muscles", type=int, default=2, choices=range(1, 5))
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    args, _ = parser.parse_known_args()

    from app.analysis.cohort import cohort_statistics

    load = os.getloadavg()[0]
    groups = cohort(args.recordings, args.minutes, args.muscles)
    # Warm imports and caches on one short cohort.
    cohort_statistics(cohort(4, 0.5, args.muscles))
    wall: list[float] = []
    cpu: list[float] = []
    result = None
    for _ in range(args.repeats):
        w0, c0 = time.perf_counter(), time.process_time()
        result = cohort_statistics(groups)
        wall.append(time.perf_counter() - w0)
        cpu.append(time.process_time() - c0)
    assert result is not None
    lifts = [r.values["n_lifts"] for r in result.recordings]
    tested = [t for t in result.tests if t.p is not None]
    out = {
        "recordings": args.recordings,
        "minutes": args.minutes,
        "rate_hz": RATE,
        "muscles": args.muscles,
        "repeats": args.repeats,
        "wall_s_median": statistics.median(wall),
        "wall_s": wall,
        "cpu_s_median": statistics.median(cpu),
        "per_recording_s": statistics.median(wall) / args.recordings,
        "lifts_per_recording": [min(lifts), max(lifts)],
        "design": result.pairings[0].design,
        "tests": len(tested),
        "load_average_start": load,
        "load_average_end": os.getloadavg()[0],
        "target_s": 60.0,
    }
    if args.json:
        print(json.dumps(out, indent=2))
        return 0
    print(
        f"cohort of {args.recordings} x {args.minutes:g} min at {RATE:g} Hz, {args.muscles} EMG"
        f" channel(s), {out['design']} design, {len(tested)} tests:"
        f" {out['wall_s_median']:.1f} s wall (median of {args.repeats}: "
        + ", ".join(f"{w:.1f}" for w in wall)
        + f"), {out['cpu_s_median']:.1f} s CPU; {out['per_recording_s']:.2f} s per recording;"
        f" lifts per recording {lifts and min(lifts):g}-{lifts and max(lifts):g}; target <= 60 s;"
        f" load average {load:.1f} -> {out['load_average_end']:.1f}"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
