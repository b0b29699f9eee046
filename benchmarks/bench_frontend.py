"""Dashboard benchmarks in a real browser (Debian's Chromium, headless, SwiftShader WebGL).

1. First page load on loopback, cold cache: navigation to the Recordings page until its list is
   filled in (target < 1 s), and the DOM ``load`` event.
2. Recording detail of a 10-minute 2 kHz session (four EMG sites and two goniometers, 1.2 M
   samples per channel), once its analysis job has run (the job stores the overlays): time from
   navigation until the EMG plot is drawn, and until the page is complete with the analysis
   overlays (envelopes, onsets, angles and velocities, the lifts table) (target < 2 s); median
   of ``--repeat`` fresh tabs. The analysis job's own run time is reported too.
3. Viewer playback measured in the browser: pose updates per second that reach the page over
   viser's websocket while a comparison plays (target >= 30), and the WebGL canvas's
   ``requestAnimationFrame`` rate inside the viewer.

    .venv/bin/python benchmarks/bench_frontend.py [--minutes 10] [--json]

The server is ``tests/frontend/serve.py`` (create_app + attach_dashboard) with the demo data.
Numbers depend on the machine: the script prints its CPU count and load with them.
"""

from __future__ import annotations

import argparse
import itertools
import json
import os
import statistics
import sys
import tempfile
import time
import urllib.request
import uuid
from pathlib import Path
from typing import Any

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from tests.frontend.conftest import CHROMIUM, CHROMIUM_ARGS, LiveServer  # noqa: E402


def upload_csv(url: str, name: str, data: bytes, muscles: dict[str, str]) -> int:
    boundary = uuid.uuid4().hex
    parts = [
        f'--{boundary}\r\nContent-Disposition: form-data; name="files"; filename="{name}"'
        "\r\nContent-Type: text/csv\r\n\r\n".encode()
        + data
        + b"\r\n",
        f'--{boundary}\r\nContent-Disposition: form-data; name="muscle_map"\r\n\r\n'
        f"{json.dumps(muscles)}\r\n".encode(),
        f"--{boundary}--\r\n".encode(),
    ]
    request = urllib.request.Request(
        f"{url}/api/recordings",
        data=b"".join(parts),
        headers={"Content-Type": f"multipart/form-data; boundary={boundary}"},
    )
    with urllib.request.urlopen(request, timeout=600) as response:
        return int(json.load(response)["id"])


def first_load(browser: Any, url: str, repeat: int) -> dict[str, Any]:
    ready, loads = [], []
    for _ in range(repeat):
        context = browser.new_context(viewport={"width": 1280, "height": 800})
        page = context.new_page()
        start = time.perf_counter()
        page.goto(f"{url}/#/recordings")
        page.wait_for_selector("#recordings-body tr[data-id]")
        ready.append(time.perf_counter() - start)
        loads.append(
            page.evaluate("performance.getEntriesByType('navigation')[0].loadEventEnd / 1000")
        )
        context.close()
    return {
        "repeat": repeat,
        "ready_s_median": statistics.median(ready),
        "ready_s_max": max(ready),
        "load_event_s_median": statistics.median(loads),
    }


def analyse(url: str, recording_id: int) -> dict[str, Any]:
    """Submit the recording's analysis job and wait for it (what an upload from the page does)."""
    request = urllib.request.Request(
        f"{url}/api/analyses",
        data=json.dumps({"recording_id": recording_id}).encode(),
        headers={"Content-Type": "application/json"},
    )
    start = time.perf_counter()
    with urllib.request.urlopen(request, timeout=30) as response:
        job = json.load(response)
    while job["state"] not in ("succeeded", "failed", "cancelled"):
        time.sleep(0.1)
        with urllib.request.urlopen(f"{url}/api/jobs/{job['id']}", timeout=30) as response:
            job = json.load(response)
    if job["state"] != "succeeded":
        raise RuntimeError(f"analysis job {job['id']} {job['state']}: {job['error']}")
    return {"job_wall_s": time.perf_counter() - start, "job_run_s": job["run_seconds"]}


def detail_page(browser: Any, url: str, recording_id: int, repeat: int) -> dict[str, Any]:
    emg, complete, lifts = [], [], 0
    for _ in range(repeat):
        context = browser.new_context(viewport={"width": 1280, "height": 800})
        page = context.new_page()
        page.goto(f"{url}/#/recordings")  # warm the shell and Plotly's script cache first
        page.wait_for_selector("#recordings-body tr[data-id]")
        page.evaluate("import('/js/plots.js').then(m => m.plotly())")
        start = time.perf_counter()
        page.goto(f"{url}/#/recordings/{recording_id}")
        page.wait_for_function(
            "(() => { const d = document.getElementById('emg-plot');"
            " return d && d.data && d.data.filter(t => t.name.endsWith(' raw')).length >= 4"
            " && d.querySelector('.main-svg'); })()",
            timeout=120_000,
        )
        emg.append(time.perf_counter() - start)
        # Complete: the lifts table and the angle plot with its four series are drawn.
        page.wait_for_selector("#lifts-table tbody tr", timeout=120_000)
        page.wait_for_function(
            "(() => { const d = document.getElementById('angle-plot');"
            " return d && d.data && d.data.some(t => t.name === 'shoulder velocity')"
            " && d.querySelector('.main-svg'); })()",
            timeout=120_000,
        )
        complete.append(time.perf_counter() - start)
        lifts = page.locator("#lifts-table tbody tr").count()
        context.close()
    return {
        "repeat": repeat,
        "emg_plot_s": statistics.median(emg),
        "complete_s": statistics.median(complete),
        "complete_s_max": max(complete),
        "lifts": lifts,
    }


def playback(browser: Any, url: str, kind: str, rid: int, seconds: float) -> dict[str, Any]:
    context = browser.new_context(viewport={"width": 1280, "height": 800})
    page = context.new_page()
    frames: list[float] = []

    def on_socket(ws: Any) -> None:
        if "/bioplan/" in ws.url:
            ws.on("framereceived", lambda _: frames.append(time.perf_counter()))

    page.on("websocket", on_socket)
    page.goto(f"{url}/#/compare/{kind}/{rid}")
    page.wait_for_selector("#viewer-frame")
    page.locator("#viewer-frame").scroll_into_view_if_needed()
    frame = page.frame_locator("#viewer-frame")
    frame.locator("canvas").first.wait_for(timeout=60_000)
    time.sleep(3.0)  # scene built, playing
    viewer = next(f for f in page.frames if "/bioplan/" in f.url)
    raf = viewer.evaluate(
        """(ms) => new Promise(resolve => {
            let n = 0; const t0 = performance.now();
            const step = () => { n++; if (performance.now() - t0 < ms) requestAnimationFrame(step);
                                 else resolve(n * 1000 / (performance.now() - t0)); };
            requestAnimationFrame(step);
        })""",
        1000 * seconds,
    )
    t_end = time.perf_counter()
    window = [t for t in frames if t >= t_end - seconds]
    gaps = sorted(b - a for a, b in itertools.pairwise(window))
    sessions = json.load(urllib.request.urlopen(f"{url}/api/viewer/sessions", timeout=10))
    context.close()
    return {
        "comparison": f"{kind}/{rid}",
        # While the robots move (the loop holds its last pose 0.6 s, sending nothing).
        "pose_updates_per_s_moving": 1.0 / gaps[len(gaps) // 2] if gaps else 0.0,
        "websocket_messages_per_s_overall": len(window) / seconds,
        "raf_fps_in_viewer": raf,
        "server_pose_updates_per_s": [s["fps"] for s in sessions],
    }


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--minutes", type=float, default=10.0, help="long recording length")
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    args = parser.parse_args()
    if not CHROMIUM.is_file():
        print(f"Chromium not found at {CHROMIUM}", file=sys.stderr)
        return 2
    from playwright.sync_api import sync_playwright

    from app.viewer.demo_seed import DEMO_MUSCLES, synthetic_curls_csv

    out: dict[str, Any] = {"machine": {"cpus": os.cpu_count(), "load": os.getloadavg()[0]}}
    with tempfile.TemporaryDirectory(prefix="bioplan-bench-") as tmp:
        server = LiveServer(Path(tmp) / "data")
        try:
            server.wait_ready()
            lifts = max(1, round(args.minutes * 60.0 / 4.9))
            t = time.perf_counter()
            data = synthetic_curls_csv(lifts=lifts, rate=2000.0, seed=1)
            generate = time.perf_counter() - t
            t = time.perf_counter()
            rid = upload_csv(server.url, "long_session.csv", data, DEMO_MUSCLES)
            out["long_recording"] = {
                "minutes": args.minutes,
                "rate_hz": 2000.0,
                "megabytes": len(data) / 1e6,
                "generate_s": generate,
                "upload_and_parse_s": time.perf_counter() - t,
            }
            out["long_recording"]["analysis"] = analyse(server.url, rid)
            ids = {j["kind"]: j["id"] for j in server.api("/api/jobs?limit=50")["items"]}
            with sync_playwright() as p:
                browser = p.chromium.launch(executable_path=str(CHROMIUM), args=CHROMIUM_ARGS)
                try:
                    out["first_load"] = first_load(browser, server.url, args.repeat)
                    out["detail_10min"] = detail_page(browser, server.url, rid, args.repeat)
                    out["playback"] = playback(
                        browser, server.url, "simulation", ids["simulation"], 5.0
                    )
                finally:
                    browser.close()
        finally:
            server.stop()
    if args.json:
        print(json.dumps(out, indent=2))
        return 0
    m, fl, d, pb = out["machine"], out["first_load"], out["detail_10min"], out["playback"]
    lr = out["long_recording"]
    print(f"machine: {m['cpus']} CPUs, load {m['load']:.2f}")
    print(
        f"first page load (cold, {fl['repeat']}x): ready {fl['ready_s_median']:.3f} s median, "
        f"{fl['ready_s_max']:.3f} s max; load event {fl['load_event_s_median']:.3f} s"
    )
    print(
        f"{lr['minutes']:g}-minute 2 kHz recording ({lr['megabytes']:.0f} MB CSV, upload+parse "
        f"{lr['upload_and_parse_s']:.1f} s, analysis job {lr['analysis']['job_run_s']:.1f} s): "
        f"detail page ({d['repeat']}x, median) EMG plot drawn in {d['emg_plot_s']:.2f} s, "
        f"complete with the analysis overlays ({d['lifts']} lifts) in {d['complete_s']:.2f} s "
        f"(max {d['complete_s_max']:.2f} s)"
    )
    print(
        f"viewer playback ({pb['comparison']}): {pb['pose_updates_per_s_moving']:.1f} pose "
        f"updates/s received in the browser while moving "
        f"({pb['websocket_messages_per_s_overall']:.1f}/s overall, with the end-of-loop holds), "
        f"canvas {pb['raf_fps_in_viewer']:.1f} fps (requestAnimationFrame, software WebGL), "
        f"server {[round(f, 1) for f in pb['server_pose_updates_per_s']]}"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
