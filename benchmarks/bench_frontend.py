"""Dashboard benchmarks in a real browser (Debian's Chromium, headless, SwiftShader WebGL).

1. First page load on loopback, cold cache: navigation to the Recordings page until its list is
   filled in (target < 1 s), and the DOM ``load`` event.
2. Recording detail of a 10-minute 2 kHz session (four EMG sites and two goniometers, 1.2 M
   samples per channel), once its analysis job has run (the job stores the overlays): time from
   navigation until the EMG plot is drawn, and until the page is complete with the analysis
   overlays (envelopes, onsets, angles and velocities, the lifts table) (target < 2 s); median
   of ``--repeat`` fresh tabs. The analysis job's own run time is reported too.
3. Viewer playback measured in the browser (target >= 30 fps): pose updates per second that
   reach the page over viser's websocket while a comparison plays, and the frames the WebGL
   canvas presents (frames with draw calls, and those showing new poses) in the Compare page's
   iframe at 1280x800, in the viewer alone at smaller sizes, and the floors of the same browser
   (a plain page, a bare viser scene); median of ``--runs`` fresh tabs each.

    .venv/bin/python benchmarks/bench_frontend.py [--minutes 10] [--json]
    .venv/bin/python benchmarks/bench_frontend.py --only playback [--runs 3]

The server is a real ``bioplan serve --demo`` (``tests/utils/server.py``) with its 3-D viewer.
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

from tests.utils.browser import CHROMIUM, CHROMIUM_ARGS  # noqa: E402
from tests.utils.server import Server, free_port  # noqa: E402


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


#: Injected into every frame before its own scripts. Counts requestAnimationFrame callbacks,
#: frames in which WebGL drew (any draw call between two callbacks: a frame the canvas
#: presented), and of those the frames drawn after viser's websocket worker delivered new data
#: since the previous drawn frame (new poses made visible).
FRAME_COUNTER = """(() => {
  if (window.__frames) return;
  const s = window.__frames = {raf: 0, drawn: 0, fresh: 0, drew: false, data: false};
  for (const C of [window.WebGL2RenderingContext, window.WebGLRenderingContext]) {
    if (!C) continue;
    for (const n of ["drawElements", "drawArrays", "drawElementsInstanced",
                     "drawArraysInstanced", "drawRangeElements"]) {
      const f = C.prototype[n];
      if (f) C.prototype[n] = function (...a) { s.drew = true; return f.apply(this, a); };
    }
  }
  const W = window.Worker;
  if (W) window.Worker = class extends W {
    constructor(...a) { super(...a); this.addEventListener("message", () => { s.data = true; }); }
  };
  const tick = () => {
    s.raf++;
    if (s.drew) { s.drawn++; if (s.data) { s.fresh++; s.data = false; } }
    s.drew = false;
    requestAnimationFrame(tick);
  };
  requestAnimationFrame(tick);
})();"""

#: Rates of the counters above over ``ms`` milliseconds, and the WebGL renderer's name.
FRAME_RATES = """async (ms) => {
  const s = window.__frames, a = {...s}, t0 = performance.now();
  await new Promise(r => setTimeout(r, ms));
  const dt = (performance.now() - t0) / 1000;
  const gl = document.createElement("canvas").getContext("webgl2");
  const info = gl && gl.getExtension("WEBGL_debug_renderer_info");
  return {raf: (s.raf - a.raf) / dt, drawn: (s.drawn - a.drawn) / dt,
          fresh: (s.fresh - a.fresh) / dt, dpr: devicePixelRatio,
          renderer: info ? gl.getParameter(info.UNMASKED_RENDERER_WEBGL) : "unknown"};
}"""


def _frame_rates(
    browser: Any, url: str, viewport: tuple[int, int], seconds: float, *, iframe: bool = False
) -> dict[str, Any]:
    """Open ``url`` in a fresh tab; the frame rates of its viewer (in the Compare page's iframe
    when ``iframe``) while the robots move, and the pose messages the websocket received."""
    context = browser.new_context(viewport={"width": viewport[0], "height": viewport[1]})
    context.add_init_script(FRAME_COUNTER)
    page = context.new_page()
    received: list[float] = []

    def on_socket(ws: Any) -> None:
        if "/bioplan/" in ws.url:
            ws.on("framereceived", lambda _: received.append(time.perf_counter()))

    page.on("websocket", on_socket)
    page.goto(url)
    target = page
    if iframe:
        page.wait_for_selector("#viewer-frame")
        page.locator("#viewer-frame").scroll_into_view_if_needed()  # viser skips hidden canvases
        page.frame_locator("#viewer-frame").locator("canvas").first.wait_for(timeout=60_000)
        target = next(f for f in page.frames if "/bioplan/" in f.url)
    else:
        page.locator("canvas").first.wait_for(timeout=60_000)
    time.sleep(4.0)  # scene built, playing, viser's adaptive pixel ratio settled
    start = time.perf_counter()
    rates = target.evaluate(FRAME_RATES, 1000 * seconds)
    window = [t for t in received if t >= start]
    gaps = sorted(b - a for a, b in itertools.pairwise(window))
    context.close()
    return {
        **rates,
        # While the robots move (the loop holds its last pose 0.6 s, sending nothing).
        "pose_updates_per_s": 1.0 / gaps[len(gaps) // 2] if gaps else 0.0,
        "messages_per_s": len(window) / seconds,
        "load": os.getloadavg()[0],
    }


def _medians(runs: list[dict[str, Any]]) -> dict[str, Any]:
    keys = ("raf", "drawn", "fresh", "pose_updates_per_s", "messages_per_s", "load")
    return {k: statistics.median(r[k] for r in runs) for k in keys} | {"runs": len(runs)}


def _empty_viser(browser: Any, viewport: tuple[int, int], seconds: float) -> dict[str, Any]:
    """A bare viser scene whose one frame moves at 60 Hz: the viewer's own floor cost."""
    import contextlib
    import threading

    import viser

    with contextlib.redirect_stdout(sys.stderr):  # viser's banner would spoil --json
        server = viser.ViserServer(host="127.0.0.1", port=free_port(), verbose=False)
    frame = server.scene.add_frame("/moving", axes_length=0.2)
    stop = threading.Event()

    def move() -> None:
        for k in itertools.count():
            if stop.wait(1 / 60):
                return
            frame.position = (0.1 * (k % 60) / 60, 0.0, 0.0)

    mover = threading.Thread(target=move, daemon=True)
    mover.start()
    try:
        return _frame_rates(browser, f"http://127.0.0.1:{server.get_port()}/", viewport, seconds)
    finally:
        stop.set()
        mover.join()
        with contextlib.redirect_stdout(sys.stderr):
            server.stop()


def playback(
    browser: Any, url: str, kind: str, rid: int, seconds: float, runs: int = 3
) -> dict[str, Any]:
    """The viewer's frame rates in the browser while a comparison plays, median of ``runs``.

    Measured in the Compare page's iframe at 1280x800 (what a user sees), in the viewer alone at
    smaller viewports and a lower pixel ratio (where software WebGL can keep up), and against
    two floors in the same browser: a plain page's requestAnimationFrame rate and a bare viser
    scene with one moving frame.
    """
    compare = [
        _frame_rates(browser, f"{url}/#/compare/{kind}/{rid}", (1280, 800), seconds, iframe=True)
        for _ in range(runs)
    ]
    sessions = json.load(urllib.request.urlopen(f"{url}/api/viewer/sessions", timeout=10))
    viewer = json.load(urllib.request.urlopen(f"{url}/api/viewer/comparisons/{kind}/{rid}"))
    alone_url = viewer["viewer"]["url"]
    variants = {
        "1280x800": ((1280, 800), ""),
        "1280x800 fixedDpr=0.5": ((1280, 800), "&fixedDpr=0.5"),
        "640x400": ((640, 400), ""),
        "320x200": ((320, 200), ""),
    }
    alone = {
        name: _medians(
            [_frame_rates(browser, alone_url + query, size, seconds) for _ in range(runs)]
        )
        for name, (size, query) in variants.items()
    }
    plain = browser.new_context(viewport={"width": 1280, "height": 800})
    plain.add_init_script(FRAME_COUNTER)
    page = plain.new_page()
    page.set_content("<html><body>plain</body></html>")
    plain_raf = page.evaluate(FRAME_RATES, 1000 * seconds)["raf"]
    plain.close()
    empty = {
        f"{w}x{h}": _medians([_empty_viser(browser, (w, h), seconds) for _ in range(runs)])
        for w, h in ((1280, 800), (640, 400))
    }
    m = _medians(compare)
    return {
        "comparison": f"{kind}/{rid}",
        "renderer": compare[0]["renderer"],
        "viewport": "1280x800, Compare page iframe",
        "runs": runs,
        "pose_updates_per_s_moving": m["pose_updates_per_s"],
        "websocket_messages_per_s_overall": m["messages_per_s"],
        "raf_fps_in_viewer": m["raf"],
        # Frames the canvas drew, and those that showed new poses.
        "canvas_fps_in_viewer": m["drawn"],
        "new_pose_fps_in_viewer": m["fresh"],
        "load_during": m["load"],
        "server_pose_updates_per_s": [s["fps"] for s in sessions],
        "viewer_alone": alone,
        "floor_plain_page_raf": plain_raf,
        "floor_empty_viser": empty,
    }


def playback_lines(pb: dict[str, Any]) -> list[str]:
    """The benchmark's printed lines for ``playback()``."""
    lines = [
        f"viewer playback ({pb['comparison']}, {pb['viewport']}, {pb['renderer']}, median of "
        f"{pb['runs']}, load {pb['load_during']:.1f}): {pb['pose_updates_per_s_moving']:.1f} pose "
        f"updates/s received while moving ({pb['websocket_messages_per_s_overall']:.1f}/s "
        f"overall); canvas drew {pb['canvas_fps_in_viewer']:.1f} fps, "
        f"{pb['new_pose_fps_in_viewer']:.1f} with new poses (rAF {pb['raf_fps_in_viewer']:.1f}); "
        f"server {[round(f, 1) for f in pb['server_pose_updates_per_s']]}",
        "  viewer alone: "
        + "; ".join(
            f"{name} {v['drawn']:.1f} fps ({v['fresh']:.1f} new poses)"
            for name, v in pb["viewer_alone"].items()
        ),
        f"  floors: plain page rAF {pb['floor_plain_page_raf']:.1f}; bare viser scene "
        + "; ".join(f"{name} {v['drawn']:.1f} fps" for name, v in pb["floor_empty_viser"].items()),
    ]
    return lines


def playback_only(args: argparse.Namespace) -> int:
    """``--only playback``: the demo data and the viewer benchmark, nothing else."""
    from playwright.sync_api import sync_playwright

    machine = {"cpus": os.cpu_count(), "load": os.getloadavg()[0]}
    with tempfile.TemporaryDirectory(prefix="bioplan-bench-") as tmp:
        server = Server(Path(tmp) / "data", demo=True, viewer=True)
        try:
            server.start(timeout=600)
            ids = {j["kind"]: j["id"] for j in server.get("/api/jobs?limit=50")["items"]}
            with sync_playwright() as p:
                browser = p.chromium.launch(executable_path=str(CHROMIUM), args=CHROMIUM_ARGS)
                try:
                    pb = playback(
                        browser, server.url, "simulation", ids["simulation"], 4.0, args.runs
                    )
                finally:
                    browser.close()
        finally:
            server.stop()
    if args.json:
        print(json.dumps({"machine": machine, "playback": pb}, indent=2))
    else:
        print(f"machine: {machine['cpus']} CPUs, load {machine['load']:.2f}")
        print("\n".join(playback_lines(pb)))
    return 0


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--minutes", type=float, default=10.0, help="long recording length")
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    parser.add_argument("--only", choices=("playback",), help="run only this benchmark")
    parser.add_argument("--runs", type=int, default=3, help="fresh tabs per playback variant")
    args = parser.parse_args()
    if not CHROMIUM.is_file():
        print(f"Chromium not found at {CHROMIUM}", file=sys.stderr)
        return 2
    if args.only == "playback":
        return playback_only(args)
    from playwright.sync_api import sync_playwright

    from app.services import DEMO_MUSCLES, synthetic_curls_csv

    out: dict[str, Any] = {"machine": {"cpus": os.cpu_count(), "load": os.getloadavg()[0]}}
    with tempfile.TemporaryDirectory(prefix="bioplan-bench-") as tmp:
        server = Server(Path(tmp) / "data", demo=True, viewer=True)
        try:
            server.start(timeout=600)
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
            ids = {j["kind"]: j["id"] for j in server.get("/api/jobs?limit=50")["items"]}
            with sync_playwright() as p:
                browser = p.chromium.launch(executable_path=str(CHROMIUM), args=CHROMIUM_ARGS)
                try:
                    out["first_load"] = first_load(browser, server.url, args.repeat)
                    out["detail_10min"] = detail_page(browser, server.url, rid, args.repeat)
                    out["playback"] = playback(
                        browser, server.url, "simulation", ids["simulation"], 4.0, args.runs
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
    print("\n".join(playback_lines(pb)))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
