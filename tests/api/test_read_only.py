"""A read-only data directory is the server's condition, said in one line, never a traceback.

Issue 14 item 14: ``bioplan serve`` on a read-only data directory exited with a 134-line
traceback, and a DELETE on a data directory that had become read-only answered 500. The data
directory is made read-only for real: a read-only bind mount in a user namespace
(``unshare -rm``), so the tests need no root and skip where user namespaces are disabled.
"""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from tests.utils.server import free_port

UNSHARE = shutil.which("unshare")
BIOPLAN = str(Path(sys.executable).with_name("bioplan"))


def _read_only_mounts_work(tmp_path: Path) -> bool:
    if UNSHARE is None:
        return False
    probe = tmp_path / "probe"
    probe.mkdir()
    script = (
        f"mount --bind {probe} {probe} && mount -o remount,bind,ro {probe} && ! touch {probe}/x"
    )
    done = subprocess.run([UNSHARE, "-rm", "sh", "-c", script], capture_output=True, timeout=60)
    return done.returncode == 0


@pytest.fixture
def read_only_mounts(tmp_path: Path) -> None:
    if not _read_only_mounts_work(tmp_path):
        pytest.skip("no read-only bind mounts here: `unshare -rm` (user namespaces) unavailable")


@pytest.mark.usefixtures("read_only_mounts")
def test_serve_on_a_read_only_data_directory_is_one_line(tmp_path: Path) -> None:
    data = tmp_path / "data"
    data.mkdir()
    port = free_port()
    script = (
        f"mount --bind {data} {data} && mount -o remount,bind,ro {data} && "
        f"exec {BIOPLAN} serve --data-dir {data} --port {port}"
    )
    done = subprocess.run(
        [UNSHARE, "-rm", "sh", "-c", script], capture_output=True, text=True, timeout=120
    )
    assert done.returncode == 2, done.stderr
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1, done.stderr
    assert str(data) in lines[0] and "read-only" in lines[0] and "--data-dir" in lines[0]
    assert "Traceback" not in done.stderr and done.stdout == ""


# Runs inside the namespace: a real server, one upload, then the data directory turns
# read-only under it (as when a disk is remounted read-only after errors); prints what each
# request answered as one JSON object.
_DRIVER = textwrap.dedent(
    """
    import concurrent.futures, json, subprocess, sys, time
    import httpx

    bioplan, data, port = sys.argv[1], sys.argv[2], sys.argv[3]
    server = subprocess.Popen([bioplan, "serve", "--data-dir", data, "--port", port],
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    out = {}
    try:
        with httpx.Client(base_url=f"http://127.0.0.1:{port}", timeout=60) as c:
            deadline = time.monotonic() + 120
            while True:
                try:
                    if c.get("/api/health").status_code == 200:
                        break
                except httpx.TransportError:
                    pass
                if time.monotonic() > deadline:
                    raise SystemExit("the server did not answer")
                time.sleep(0.2)
            csv = b"t,EMG1\\n" + b"".join(f"{i / 1000},{i % 7}\\n".encode() for i in range(3000))
            up = c.post("/api/recordings", files={"files": ("emg.csv", csv)},
                        data={"emg_rate": "1000"})
            rid = up.json()["id"]
            fid = up.json()["files"][0]["id"]
            # A read-only view stacked on the folder: the server's open database stays
            # writable, every new file operation there fails with EROFS.
            subprocess.run(["mount", "--bind", data, data], check=True)
            subprocess.run(["mount", "-o", "remount,bind,ro", data], check=True)
            gone = c.delete(f"/api/recordings/{rid}")
            other = csv.replace(b",6\\n", b",5\\n")  # new bytes: a new blob to write
            upload = c.post("/api/recordings", files={"files": ("b.csv", other)},
                            data={"emg_rate": "1000"})
            out["delete"] = [gone.status_code, gone.json()]
            out["upload"] = [upload.status_code, upload.json()]
            out["get"] = c.get(f"/api/recordings/{rid}").status_code
            out["raw"] = c.get(f"/api/recordings/{rid}/files/{fid}").content == csv
            # Reads at once: the pool opens connections while the disk is read-only, and
            # SQLite opens those read-only.
            with concurrent.futures.ThreadPoolExecutor(6) as pool:
                url = f"http://127.0.0.1:{port}/api/recordings"
                reads = pool.map(lambda _: httpx.get(url, timeout=60).status_code,
                                 range(24))
                out["reads"] = sorted(set(reads))
            # Lazily: connections opened through the read-only view keep it alive until
            # they close; the server must replace them now that the disk is writable.
            subprocess.run(["umount", "-l", data], check=True)
            out["writes_after"] = sorted({
                c.patch(f"/api/recordings/{rid}", json={"label": f"n{i}", "analyse": False})
                .status_code for i in range(12)
            })
            out["total"] = c.get("/api/recordings").json()["total"]
            out["delete_again"] = c.delete(f"/api/recordings/{rid}").status_code
            out["get_again"] = c.get(f"/api/recordings/{rid}").status_code
    finally:
        server.terminate()
        server.wait(60)
    print(json.dumps(out))
    """
)


@pytest.mark.usefixtures("read_only_mounts")
def test_a_data_directory_turned_read_only_is_507_and_nothing_changes(tmp_path: Path) -> None:
    data = tmp_path / "data"
    data.mkdir()
    done = subprocess.run(
        [UNSHARE, "-rm", sys.executable, "-c", _DRIVER, BIOPLAN, str(data), str(free_port())],
        capture_output=True, text=True, timeout=600,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr[-3000:]
    out = json.loads(done.stdout)
    status, problem = out["delete"]
    assert status == 507, problem
    assert "read-only" in problem["detail"] and "nothing was changed" in problem["detail"]
    assert str(data) not in json.dumps(out)  # no server paths in answers
    assert out["upload"][0] == 507 and "read-only" in out["upload"][1]["detail"]
    assert out["get"] == 200 and out["raw"] is True  # the recording and its bytes are intact
    assert out["total"] == 1  # the refused upload left nothing
    assert out["reads"] == [200]  # reads go on while the disk is read-only
    # Once it is writable again every write succeeds, on whichever pooled connection: one that
    # SQLite opened read-only meanwhile is replaced, not kept failing until a restart.
    assert out["writes_after"] == [200]
    assert out["delete_again"] == 204 and out["get_again"] == 404


# Runs inside the namespace: two pooled connections, the second opened while the file is on a
# read-only mount; once the mount is gone, a write on each.
_POOL_DRIVER = textwrap.dedent(
    """
    import json, subprocess, sys
    from sqlalchemy import text
    from app.db.session import make_engine

    data = sys.argv[1]
    engine = make_engine(f"sqlite:///{data}/pool.db")
    with engine.begin() as conn:
        conn.execute(text("CREATE TABLE t (x INTEGER)"))
    first = engine.connect()
    subprocess.run(["mount", "--bind", data, data], check=True)
    subprocess.run(["mount", "-o", "remount,bind,ro", data], check=True)
    second = engine.connect()  # the pool opens it now: SQLite opens it read-only
    first.close(), second.close()
    subprocess.run(["umount", "-l", data], check=True)
    out = []
    held = [engine.connect(), engine.connect()]  # both pooled connections at once
    for conn in held:
        try:
            conn.execute(text("INSERT INTO t VALUES (1)"))
            conn.commit()
            out.append("written")
        except Exception as exc:
            out.append(str(exc.__cause__ or exc).splitlines()[0])
    print(json.dumps(out))
    """
)


@pytest.mark.usefixtures("read_only_mounts")
def test_a_connection_opened_read_only_is_replaced_once_writable(tmp_path: Path) -> None:
    """SQLite opens a file it cannot write read-only and keeps it so: such a pooled
    connection answered every later write with "readonly database" (a 507) until a restart,
    though the disk was writable again (found when CI's busy machine opened one)."""
    data = tmp_path / "data"
    data.mkdir()
    done = subprocess.run(
        [UNSHARE, "-rm", sys.executable, "-c", _POOL_DRIVER, str(data)],
        capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr[-3000:]
    assert json.loads(done.stdout) == ["written", "written"]
