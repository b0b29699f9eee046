"""Synthetic 4-channel EMG CSV for the read + EMG pipeline benchmark, and a read timing.

``write_emg_csv`` writes 10 minutes of 4-channel surface EMG at 2 kHz (1.2 M rows, 4.8 M
samples, about 55 MB): a time column [s] and deltoid/triceps/biceps/forearm in uV with 3
decimals. Each 5 s cycle holds one 2 s "curl": band-limited (20-450 Hz) noise whose amplitude
rises and falls like a parabola, deltoid first, triceps and biceps together, forearm last and
weakest (the order the paper reports), on a 5 uV resting floor. Same seed, same bytes.

Run ``python benchmarks/bench_read.py [--out FILE] [--repeat N]`` to write the file (if
missing) and print the median ``read_recording`` time as one JSON object.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

SITES = ("deltoid", "triceps", "biceps", "forearm")
ONSET_S = {"deltoid": 0.50, "triceps": 0.62, "biceps": 0.62, "forearm": 0.75}
PEAK_UV = {"deltoid": 400.0, "triceps": 300.0, "biceps": 600.0, "forearm": 150.0}


def synthetic_emg(
    *, seconds: float = 600.0, rate: float = 2000.0, seed: int = 0
) -> tuple[np.ndarray, np.ndarray]:
    """(time (N,) [s], EMG (N, 4) [uV]) for the four sites, reproducible from ``seed``."""
    from scipy.signal import butter, sosfiltfilt

    rng = np.random.default_rng(seed)
    n = round(seconds * rate)
    t = np.arange(n) / rate
    sos = butter(4, [20.0, 450.0], btype="bandpass", fs=rate, output="sos")
    noise = sosfiltfilt(sos, rng.standard_normal((n, len(SITES))), axis=0)
    noise /= noise.std(axis=0)
    phase = t % 5.0
    emg = np.empty((n, len(SITES)))
    for j, site in enumerate(SITES):
        u = (phase - ONSET_S[site]) / 2.0
        envelope = np.where((u > 0) & (u < 1), 4.0 * u * (1.0 - u), 0.0)
        emg[:, j] = noise[:, j] * (5.0 + PEAK_UV[site] * envelope)
    return t, emg


def write_emg_csv(
    path: str | Path, *, seconds: float = 600.0, rate: float = 2000.0, seed: int = 0
) -> Path:
    """Write the synthetic recording as ``time,deltoid (uV),...`` CSV and return its path."""
    import pyarrow as pa
    import pyarrow.csv as pcsv

    t, emg = synthetic_emg(seconds=seconds, rate=rate, seed=seed)
    columns = {"time": np.round(t, 6)}
    for j, site in enumerate(SITES):
        columns[f"{site} (uV)"] = np.round(emg[:, j], 3)
    out = Path(path)
    pcsv.write_csv(pa.table(columns), out, write_options=pcsv.WriteOptions(quoting_style="none"))
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=None, help="CSV path (default: temp dir)")
    parser.add_argument("--repeat", type=int, default=5)
    args = parser.parse_args(argv)
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
    from app.recordings import read_recording

    path = args.out or Path(tempfile.gettempdir()) / "bioplan_bench_emg_4ch_2khz_10min.csv"
    if not path.is_file():
        write_emg_csv(path)
    read_recording(path)  # warm-up: imports and page cache, as in a running service
    times, cpu = [], []
    for _ in range(args.repeat):
        start, start_cpu = time.perf_counter(), time.process_time()
        rec = read_recording(path)
        times.append(time.perf_counter() - start)
        cpu.append(time.process_time() - start_cpu)
    result = {
        "file": str(path),
        "megabytes": round(path.stat().st_size / 1e6, 1),
        "channels": len(rec.channels),
        "samples": int(sum(c.n_samples for c in rec.channels.values())),
        "read_median_s": round(statistics.median(times), 3),
        "read_min_s": round(min(times), 3),
        "read_cpu_median_s": round(statistics.median(cpu), 3),  # all threads
        "load_average_1min": round(os.getloadavg()[0], 2),
        "cpus": os.cpu_count(),
    }
    print(json.dumps(result))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
