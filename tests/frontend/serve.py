"""Run the dashboard for the browser tests and the benchmark: ``python -m tests.frontend.serve``.

A local app factory (``create_app`` + ``attach_dashboard``) on a data folder, with one uvicorn
worker; ``--demo`` seeds the demo recording and comparison first. Prints ``READY <port>`` when
the server accepts requests.
"""

from __future__ import annotations

import argparse
import logging
from pathlib import Path

import uvicorn

from app.config import Settings
from app.main import create_app
from app.viewer import attach_dashboard, seed_demo


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--data-dir", type=Path, required=True)
    parser.add_argument("--port", type=int, required=True)
    parser.add_argument("--viewer-port", type=int, required=True)
    parser.add_argument("--demo", action="store_true")
    args = parser.parse_args()
    logging.basicConfig(level=logging.WARNING)
    settings = Settings(data_dir=args.data_dir, viewer_port=args.viewer_port, max_workers=2)
    if args.demo:
        seed_demo(settings)
    app = create_app(settings)
    attach_dashboard(app, settings)
    uvicorn.run(app, host="127.0.0.1", port=args.port, workers=1, log_level="warning")


if __name__ == "__main__":
    main()
