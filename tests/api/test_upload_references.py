"""An upload can never make the server read its own files (MAT 7.3 / HDF5 references).

Before the fix, a MAT 7.3 file whose dataset kept its raw data in an external file (any path
on the server) was stored, and ``GET /api/recordings/{id}/signals`` served that file's bytes
as samples: ``/etc/passwd``, the database, ``/proc/self/environ`` with the API token.
"""

from __future__ import annotations

from pathlib import Path

from tests.utils.api import TestClient, assert_problem
from tests.utils.mat73 import SECRET, external_storage, write_mat73, write_secret


def test_mat73_with_external_storage_is_refused_and_nothing_is_stored(
    client: TestClient, tmp_path: Path
) -> None:
    secret = write_secret(tmp_path)
    path = write_mat73(tmp_path / "session.mat", external_storage(secret))
    r = client.post("/api/recordings", files=[("files", ("session.mat", path.read_bytes()))])
    body = assert_problem(r, 422, file="session.mat")
    assert body["detail"].startswith("session.mat: dataset '/EMG' keeps its data in an external")
    assert SECRET.decode() not in r.text and "s3cr3t" not in r.text
    assert str(tmp_path) not in r.text  # the server's paths are not shown either
    assert client.get("/api/recordings").json()["total"] == 0
    blobs = list((tmp_path / "data" / "blobs").rglob("*"))
    assert [b for b in blobs if b.is_file()] == []
