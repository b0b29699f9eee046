"""Robot logs through the service: upload, validation and identification of 20 s of a 7-joint
arm logged at 1 kHz (the log of ``benchmarks/identify.py``), in-process with the real app.

Timed: the upload (the log read in the parse sandbox, matched, validated, then stored), the
validation endpoint (``GET /api/robot-logs/{id}/validation``: read again, filtered, inverse
dynamics, the plotted series), and an identification job from submission to its stored robot
version. The validation is answered synchronously; this says what that costs a request.

Run ``python benchmarks/robot_logs_api.py [--repeat N]``; prints one JSON object.
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

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    from benchmarks.identify import build
    from tests.utils.api import make_client, wait_job

    with tempfile.TemporaryDirectory() as tmp, make_client(Path(tmp) / "app") as client:
        nominal, log_path = build(Path(tmp))
        r = client.post(
            "/api/robots",
            data={"name": "arm7"},
            files={"urdf": ("arm7.urdf", nominal.read_bytes())},
        )
        assert r.status_code == 201, r.text
        data = log_path.read_bytes()
        upload_s, validate_s, identify_s = [], [], []
        log_id = 0
        for _ in range(args.repeat):
            start = time.perf_counter()
            r = client.post(
                "/api/robot-logs", data={"robot": "arm7"}, files={"file": ("log.csv", data)}
            )
            upload_s.append(time.perf_counter() - start)
            assert r.status_code == 201, r.text
            log_id = r.json()["id"]
            start = time.perf_counter()
            r = client.get(f"/api/robot-logs/{log_id}/validation")
            validate_s.append(time.perf_counter() - start)
            assert r.status_code == 200, r.text
        for k in range(args.repeat):
            start = time.perf_counter()
            r = client.post("/api/identifications", json={"log_ids": [log_id], "version": f"v{k}"})
            assert r.status_code == 202, r.text
            job = wait_job(client, r.json()["id"], timeout=600)
            identify_s.append(time.perf_counter() - start)
            assert job["state"] == "succeeded", job
        print(
            json.dumps(
                {
                    "log_bytes": len(data),
                    "upload_s": upload_s,
                    "upload_median_s": statistics.median(upload_s),
                    "validation_s": validate_s,
                    "validation_median_s": statistics.median(validate_s),
                    "identify_job_s": identify_s,
                    "identify_job_median_s": statistics.median(identify_s),
                    "load_average": os.getloadavg(),
                },
                indent=1,
            )
        )


if __name__ == "__main__":
    main()
