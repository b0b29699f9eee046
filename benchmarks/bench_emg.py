"""Read + EMG pipeline + onsets on 10 min of 4-channel 2 kHz EMG; NeuroKit2 side by side.

Run:  .venv/bin/python benchmarks/bench_emg.py [--repeats 5] [--out FILE.csv] [--json]
Targets: median of read + pipeline + onsets < 1.0 s for 4 x 1.2 M samples (a ~60 MB CSV);
on one minute of the same channels, >= 20x faster than ``neurokit2.emg_process`` per channel,
with envelopes that agree.

The synthetic recording (seeded, written once to a temporary folder): every 5 s one 2 s curl;
each muscle's activity is band-limited noise whose amplitude rises and falls smoothly, deltoid
first, then triceps and biceps, the forearm last and weakest, on a low resting floor; written
in mV with 6 decimals (about 55 MB). The timed pipeline is what ``analyze_recordings`` does per
EMG channel: DC removal, 20-450 Hz band-pass, full-wave rectification, 6 Hz zero-phase
envelope, peak normalisation, saturation flags and threshold onsets. The read uses
``app.recordings.read_recording`` when it exists, else ``pyarrow.csv``.

Envelope agreement is reported two ways: against NeuroKit2's ``signal_filter`` chain with
matched settings (the same cut-offs and order: the envelopes should be the same), and against
``emg_process``'s own ``EMG_Amplitude`` (a different definition: TKEO, then filters that assume
1000 Hz; a correlation, not equality, is expected).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import sys
import tempfile
import time
import warnings
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from app.analysis.emg import (
    detect_onsets,
    emg_process,
    normalize_amplitude,
    saturation_flags,
)

RATE = 2000.0
MUSCLES = ("deltoid", "triceps", "biceps", "forearm")
START_S = (0.40, 0.55, 0.55, 0.70)  # burst start within each 5 s cycle
PEAK_UV = (350.0, 250.0, 550.0, 120.0)


def make_emg(seconds: float, *, seed: int = 0) -> NDArray[np.float64]:
    """(N, 4) synthetic surface EMG [uV] at 2 kHz."""
    from scipy import signal

    rng = np.random.default_rng(seed)
    n = round(seconds * RATE)
    t = np.arange(n) / RATE
    sos = signal.butter(4, (20.0, 450.0), btype="bandpass", fs=RATE, output="sos")
    carrier = signal.sosfilt(sos, rng.standard_normal((4, n)), axis=-1)
    carrier /= carrier.std(axis=-1, keepdims=True)
    cycle = t % 5.0
    out = np.empty((n, 4))
    for j in range(4):
        u = np.clip((cycle - START_S[j]) / 2.0, 0.0, 1.0)
        bump = np.sin(np.pi * u) ** 2  # smooth rise and fall over the 2 s curl
        out[:, j] = carrier[j] * (4.0 + PEAK_UV[j] * bump)
    return out


def write_csv(path: Path, seconds: float) -> None:
    import pyarrow as pa
    import pyarrow.csv as pcsv

    emg = make_emg(seconds)
    cols: dict[str, Any] = {"time": np.round(np.arange(len(emg)) / RATE, 6)}
    for j, m in enumerate(MUSCLES):
        cols[f"{m} (mV)"] = np.round(emg[:, j] / 1000.0, 6)
    pcsv.write_csv(pa.table(cols), path, write_options=pcsv.WriteOptions(quoting_style="none"))


def read_pyarrow(path: Path) -> NDArray[np.float64]:
    """The bare pyarrow parse of the same file, for comparison with the project's reader."""
    import pyarrow.csv as pcsv

    table = pcsv.read_csv(path)
    return np.stack([table.column(i).to_numpy() for i in range(1, 5)]).T


def read(path: Path) -> tuple[NDArray[np.float64], float, str]:
    """(N, 4) EMG in the reader's unit, the rate, and which reader was used."""
    import app.recordings

    reader = getattr(app.recordings, "read_recording", None)
    if reader is not None:
        rec = reader(path)
        chans = rec.of_kind("emg")
        # Channels stacked as (C, N), used as the (N, C) transpose (what analyze_recordings
        # does): every channel stays contiguous.
        x = np.stack([c.data for c in chans]).T
        return x, float(chans[0].rate), "read_recording"
    return read_pyarrow(path), RATE, "pyarrow.csv"


def pipeline(x: NDArray[np.float64], rate: float) -> tuple[NDArray[np.float64], int]:
    """The per-channel EMG pipeline; returns the envelopes and the number of onsets found."""
    _, env = emg_process(x, rate)
    normalize_amplitude(env)
    saturation_flags(x)
    n_onsets = sum(len(detect_onsets(env[:, j], rate)) for j in range(env.shape[1]))
    return env, n_onsets


def neurokit_side_by_side(
    x: NDArray[np.float64], rate: float, repeats: int, nk_repeats: int
) -> dict[str, Any]:
    import neurokit2 as nk

    ours_times, nk_times = [], []
    for _ in range(repeats):
        start = time.perf_counter()
        env, _ = pipeline(x, rate)
        ours_times.append(time.perf_counter() - start)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for _ in range(nk_repeats):
            start = time.perf_counter()
            frames = [nk.emg_process(x[:, j], sampling_rate=int(rate))[0] for j in range(4)]
            nk_times.append(time.perf_counter() - start)
    corr_amp, corr_matched, nrms_matched = [], [], []
    for j in range(4):
        amp = frames[j]["EMG_Amplitude"].to_numpy()
        corr_amp.append(float(np.corrcoef(env[:, j], amp)[0, 1]))
        band = nk.signal_filter(
            x[:, j] - x[:, j].mean(), sampling_rate=rate, lowcut=20, highcut=450, order=4
        )
        ref = nk.signal_filter(np.abs(band), sampling_rate=rate, highcut=6, order=4)
        corr_matched.append(float(np.corrcoef(env[:, j], ref)[0, 1]))
        nrms_matched.append(float(np.sqrt(np.mean((env[:, j] - ref) ** 2)) / np.ptp(ref)))
    ours, theirs = statistics.median(ours_times), statistics.median(nk_times)
    return {
        "samples": int(x.size),
        "ours_median_s": round(ours, 4),
        "neurokit_emg_process_median_s": round(theirs, 4),
        "speedup": round(theirs / ours, 1),
        "envelope_vs_matched_signal_filter": {
            "min_correlation": round(min(corr_matched), 6),
            "max_normalised_rms_difference": float(f"{max(nrms_matched):.2e}"),
        },
        "envelope_vs_emg_process_amplitude_min_correlation": round(min(corr_amp), 3),
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=5, help="timed runs (median reported)")
    parser.add_argument("--minutes", type=float, default=10.0, help="length of the CSV")
    parser.add_argument("--out", type=Path, default=None, help="CSV path (default: temp dir)")
    parser.add_argument(
        "--nk-repeats", type=int, default=1, help="emg_process runs (it takes seconds per run)"
    )
    parser.add_argument(
        "--skip-neurokit", action="store_true", help="time only the read + pipeline part"
    )
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    args = parser.parse_args(argv)
    if args.repeats < 5:
        parser.error("--repeats must be >= 5")
    path = args.out or Path(tempfile.gettempdir()) / (
        f"bioplan_bench_emg_analysis_{args.minutes:g}min_mV.csv"
    )
    if not path.is_file():
        write_csv(path, args.minutes * 60.0)
    x, rate, reader = read(path)  # warm-up: imports, page cache
    pipeline(x[: round(10 * rate)], rate)
    totals, reads = [], []
    n_onsets = 0
    for _ in range(args.repeats):
        start = time.perf_counter()
        x, rate, reader = read(path)
        mid = time.perf_counter()
        _, n_onsets = pipeline(x, rate)
        end = time.perf_counter()
        totals.append(end - start)
        reads.append(mid - start)
    bare = []
    for _ in range(args.repeats):
        start = time.perf_counter()
        read_pyarrow(path)
        bare.append(time.perf_counter() - start)
    one_minute = x[: round(60 * rate)]
    side = (
        None
        if args.skip_neurokit
        else neurokit_side_by_side(one_minute, rate, args.repeats, max(1, args.nk_repeats))
    )
    result = {
        "benchmark": "emg_read_pipeline_onsets",
        "file_mb": round(path.stat().st_size / 1e6, 1),
        "channels": int(x.shape[1]),
        "samples": int(x.size),
        "reader": reader,
        "repeats": args.repeats,
        "total_median_s": round(statistics.median(totals), 3),
        "total_min_s": round(min(totals), 3),
        "read_median_s": round(statistics.median(reads), 3),
        "pipeline_median_s": round(statistics.median(np.subtract(totals, reads)), 3),
        "bare_pyarrow_read_median_s": round(statistics.median(bare), 3),
        "onsets_found": n_onsets,
        "expected_bursts": int(4 * (args.minutes * 60.0 // 5.0)),
        "target_total_s": 1.0,
        "neurokit_one_minute": side,
        "load_average_1min": round(os.getloadavg()[0], 2),
        "cpus": os.cpu_count(),
        "target_speedup": 20.0,
        "python": platform.python_version(),
        "numpy": np.__version__,
    }
    if args.json:
        print(json.dumps(result))
    else:
        for key, value in result.items():
            print(f"{key:>24}: {value}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
