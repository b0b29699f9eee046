"""The 3-D viewer with the recorded human and two robots, in a real browser (target >= 30 fps).

A real ``bioplan serve --demo`` (its plan and simulation were planned with the demo analysis'
template, so the viewer shows the recorded human beside both robots). The viewer alone is
opened in headless Chromium (Debian's, SwiftShader WebGL) at 640x400 and at a 400x700 phone
size, and the frames its canvas presents are counted while the comparison plays (frames with
draw calls, and those that show new poses), median of ``--runs`` fresh tabs, beside the floor of
the same browser at the same moment (a bare viser scene with one moving frame at 640x400).

    .venv/bin/python benchmarks/bench_viewer.py [--runs 5] [--seconds 4] [--json]
        [--screenshot DIR]
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import tempfile
import urllib.request
from pathlib import Path
from typing import Any

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from benchmarks.bench_frontend import _empty_viser, _frame_rates  # noqa: E402
from tests.utils.browser import CHROMIUM, CHROMIUM_ARGS  # noqa: E402
from tests.utils.server import Server  # noqa: E402

SIZES = {"640x400": (640, 400), "400x700": (400, 700)}


def _sessions(url: str) -> list[dict[str, Any]]:
    with urllib.request.urlopen(f"{url}/api/viewer/sessions", timeout=10) as response:
        sessions: list[dict[str, Any]] = json.load(response)
    return sessions


def _screenshot(browser: Any, url: str, size: tuple[int, int], path: Path) -> None:
    import time

    context = browser.new_context(viewport={"width": size[0], "height": size[1]})
    page = context.new_page()
    page.goto(url)
    page.locator("canvas").first.wait_for(timeout=60_000)
    time.sleep(5.0)
    page.screenshot(path=str(path))
    context.close()


def measure(
    browser: Any, url: str, kind: str, rid: int, *, runs: int, seconds: float
) -> dict[str, Any]:
    """Median canvas frame rates of the viewer alone at each size, and the tabs' sessions."""
    with urllib.request.urlopen(f"{url}/api/viewer/comparisons/{kind}/{rid}") as response:
        alone_url = json.load(response)["viewer"]["url"]
    out: dict[str, Any] = {"comparison": f"{kind}/{rid}", "runs": runs, "sizes": {}}
    for name, size in SIZES.items():
        results = [_frame_rates(browser, alone_url, size, seconds) for _ in range(runs)]
        out["sizes"][name] = {
            key: statistics.median(r[key] for r in results)
            for key in ("drawn", "fresh", "raf", "pose_updates_per_s", "load")
        } | {"all_drawn": [round(r["drawn"], 1) for r in results]}
        out["renderer"] = results[0]["renderer"]
    # The floor in the same browser at the same moment: a bare viser scene, one moving frame.
    floor = [_empty_viser(browser, SIZES["640x400"], seconds) for _ in range(runs)]
    out["floor_empty_viser_640x400"] = statistics.median(r["drawn"] for r in floor)
    out["alone_url"] = alone_url
    return out


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--runs", type=int, default=5, help="fresh tabs per size (median)")
    parser.add_argument("--seconds", type=float, default=4.0, help="counting window per tab")
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    parser.add_argument("--screenshot", type=Path, help="also save a screenshot per size here")
    args = parser.parse_args()
    if not CHROMIUM.is_file():
        print(f"Chromium not found at {CHROMIUM}", file=sys.stderr)
        return 2
    from playwright.sync_api import sync_playwright

    machine = {"cpus": os.cpu_count(), "load": os.getloadavg()[0]}
    with tempfile.TemporaryDirectory(prefix="bioplan-bench-viewer-") as tmp:
        server = Server(Path(tmp) / "data", demo=True, viewer=True)
        try:
            server.start(timeout=600)
            ids = {j["kind"]: j["id"] for j in server.get("/api/jobs?limit=50")["items"]}
            with sync_playwright() as p:
                browser = p.chromium.launch(executable_path=str(CHROMIUM), args=CHROMIUM_ARGS)
                try:
                    result = measure(
                        browser, server.url, "simulation", ids["simulation"],
                        runs=args.runs, seconds=args.seconds,
                    )  # fmt: skip
                    if args.screenshot is not None:
                        args.screenshot.mkdir(parents=True, exist_ok=True)
                        for name, size in SIZES.items():
                            shot = args.screenshot / f"viewer-{name}.png"
                            _screenshot(browser, result["alone_url"], size, shot)
                    sessions = _sessions(server.url)
                finally:
                    browser.close()
        finally:
            server.stop()
    result["sessions"] = sessions
    if args.json:
        print(json.dumps({"machine": machine, "viewer": result}, indent=2))
        return 0
    print(f"machine: {machine['cpus']} CPUs, load {machine['load']:.2f}; {result['renderer']}")
    for name, v in result["sizes"].items():
        print(
            f"viewer {result['comparison']} with the human and two robots at {name}: canvas "
            f"{v['drawn']:.1f} fps drawn, {v['fresh']:.1f} with new poses (rAF {v['raf']:.1f}, "
            f"poses received {v['pose_updates_per_s']:.1f}/s; median of {result['runs']}: "
            f"{v['all_drawn']}; load {v['load']:.1f})"
        )
    print(f"floor: a bare viser scene at 640x400 {result['floor_empty_viser_640x400']:.1f} fps")
    humans = sum(bool(s.get("human")) for s in sessions)
    print(f"tabs still open: {len(sessions)}, with the human: {humans}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
