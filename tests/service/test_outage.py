"""A database outage: the API runs on a PostgreSQL of its own, which is stopped and started again.

While it is down, `/v1` requests answer 503 problem+json with `Retry-After` (never 500), `/readyz` 503 and
`/healthz` 200; once it is back, requests succeed again without restarting the API, and no upload was left
half-written. The test starts its own server (`initdb` into a temporary folder, its own free port) so that
it never stops the machine's shared PostgreSQL; as root it runs the server as the `postgres` user.
"""

from __future__ import annotations

import contextlib
import os
import pwd
import shutil
import socket
import subprocess
import tempfile
import threading
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from fastapi.testclient import TestClient

from metairl_cli.keys import create_key
from service.api.app import create_app
from service.settings import Settings
from tests.service.helpers import add_demonstrations, created, make_task

TRAJECTORIES = [{"states": [0, 1, 2], "actions": [1, 1]}, {"states": [2, 1], "actions": [0, 0]}]


def _bindir() -> Path | None:
    """Where initdb and pg_ctl are (``pg_config --bindir``), or None without a PostgreSQL install."""
    pg_config = shutil.which("pg_config")
    if pg_config is None:
        return None
    folder = Path(subprocess.run([pg_config, "--bindir"], capture_output=True, text=True).stdout.strip())
    return folder if (folder / "initdb").exists() and (folder / "pg_ctl").exists() else None


def _free_port() -> int:
    """A TCP port nobody listens on right now."""
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        port: int = sock.getsockname()[1]
        return port


class OwnPostgres:
    """A throwaway PostgreSQL cluster in `folder` on `port`, run as the current user or, as root, `postgres`."""

    def __init__(self, bindir: Path, folder: Path, port: int, run_as: str | None):
        self.bindir, self.folder, self.port, self.run_as = bindir, folder, port, run_as
        self.data = folder / "data"
        self.url = f"postgresql+psycopg://postgres@127.0.0.1:{port}/postgres"

    def _run(self, *args: str) -> None:
        command = [str(self.bindir / args[0]), *args[1:]]
        if self.run_as:
            command = ["runuser", "-u", self.run_as, "--", *command]
        done = subprocess.run(command, capture_output=True, text=True, timeout=60)
        assert done.returncode == 0, f"{args[0]} failed: {done.stdout}\n{done.stderr}"

    def init(self) -> None:
        self._run("initdb", "-D", str(self.data), "-U", "postgres", "-A", "trust", "--no-sync")

    def start(self) -> None:
        options = f"-p {self.port} -k {self.folder} -c listen_addresses=127.0.0.1 -c fsync=off"
        self._run(
            "pg_ctl", "-D", str(self.data), "-o", options, "-l", str(self.folder / "log"), "-w", "start"
        )

    def stop(self, mode: str = "fast") -> None:
        self._run("pg_ctl", "-D", str(self.data), "-m", mode, "-w", "stop")


@pytest.fixture
def own_postgres() -> Iterator[OwnPostgres]:
    """A running PostgreSQL of this test's own, removed afterwards."""
    bindir = _bindir()
    if bindir is None:
        pytest.skip("no PostgreSQL server binaries (pg_config --bindir has no initdb and pg_ctl)")
    run_as = None
    if os.geteuid() == 0:  # initdb refuses to run as root
        if shutil.which("runuser") is None:
            pytest.skip("running as root and runuser is missing, so initdb cannot run as another user")
        try:
            user = pwd.getpwnam("postgres")
        except KeyError:
            pytest.skip("running as root and there is no postgres user to run initdb as")
        run_as = "postgres"
    folder = Path(tempfile.mkdtemp(prefix="metairl-outage-"))
    if run_as:
        os.chown(folder, user.pw_uid, user.pw_gid)
    server = OwnPostgres(bindir, folder, _free_port(), run_as)
    try:
        server.init()
        server.start()
        yield server
        with contextlib.suppress(AssertionError):
            server.stop("immediate")
    finally:
        shutil.rmtree(folder, ignore_errors=True)


def _is_unavailable(response: Any) -> None:
    """`response` is the 503 problem of a database outage, with Retry-After."""
    assert response.status_code == 503, (response.status_code, response.text)
    assert response.headers["content-type"] == "application/problem+json", response.headers
    assert response.json()["type"] == "/problems/database-unavailable", response.text
    assert int(response.headers["retry-after"]) >= 1


def test_a_database_outage_is_503_with_retry_after_and_the_api_recovers_by_itself(
    own_postgres: OwnPostgres, tmp_path: Path
) -> None:
    app = create_app(Settings(data_dir=tmp_path / "var", database_url=own_postgres.url))
    with app.state.sessionmaker() as session:
        auth = {"Authorization": f"Bearer {create_key(session, 'lab-outage')}"}
    try:
        with TestClient(app, raise_server_exceptions=False) as client:
            task = make_task(client, auth)
            add_demonstrations(client, auth, task["id"], TRAJECTORIES)
            job = created(
                client.post("/v1/jobs", json={"demonstrator_id": task["demonstrator_id"]}, headers=auth), 202
            )
            created(
                client.get(f"/v1/jobs/{job['id']}", headers=auth), 200
            )  # pools a connection of the async path

            # Uploads run in a loop while the server is stopped without a clean shutdown.
            statuses: list[int] = []
            stop_uploading = threading.Event()

            def upload() -> None:
                while not stop_uploading.is_set():
                    response = client.post(
                        f"/v1/tasks/{task['id']}/demonstrations",
                        json={"trajectories": TRAJECTORIES},
                        headers=auth,
                    )
                    statuses.append(response.status_code)

            uploader = threading.Thread(target=upload)
            uploader.start()
            try:
                while len(statuses) < 3:
                    threading.Event().wait(0.05)
                own_postgres.stop("immediate")
                threading.Event().wait(0.5)
            finally:
                stop_uploading.set()
                uploader.join(30)
            assert set(statuses) <= {201, 503}, statuses
            assert statuses[-1] == 503, statuses

            # Down: every kind of request is a 503 problem, the probes say so.
            for method, path, body, extra in [
                ("GET", "/v1/demonstrators", None, {}),
                ("GET", f"/v1/tasks/{task['id']}", None, {}),
                ("POST", "/v1/demonstrators", {"name": "p"}, {}),
                ("POST", "/v1/demonstrators", {"name": "p"}, {"Idempotency-Key": "outage-1"}),
                ("DELETE", f"/v1/tasks/{task['id']}", None, {}),
                ("GET", f"/v1/jobs/{job['id']}", None, {}),  # the async path (asyncpg)
                ("GET", "/v1/rewards/rwd_none?format=npy", None, {}),
            ]:
                _is_unavailable(client.request(method, path, json=body, headers=auth | extra))
            assert client.get("/readyz").status_code == 503
            assert client.get("/healthz").status_code == 200

            # Back: the same app answers again, without a restart.
            own_postgres.start()
            assert client.get("/readyz").status_code == 200
            created(client.get("/v1/demonstrators", headers=auth), 200)
            assert created(client.get(f"/v1/jobs/{job['id']}", headers=auth), 200)["id"] == job["id"]
            replayed = client.post(
                "/v1/demonstrators", json={"name": "p"}, headers=auth | {"Idempotency-Key": "outage-1"}
            )
            assert replayed.status_code == 201, replayed.text
            names = [d["name"] for d in created(client.get("/v1/demonstrators", headers=auth), 200)["data"]]
            assert names.count("p") == 1, names  # the 503 POSTs stored nothing

            # No half-written upload: every stored batch is whole, and every 201 was stored.
            page = created(client.get(f"/v1/tasks/{task['id']}/demonstrations?limit=100", headers=auth), 200)
            assert not page["has_more"]
            batches = page["data"]
            assert all(b["n_trajectories"] == 2 and b["n_steps"] == 4 for b in batches), batches
            ok = 1 + statuses.count(201)  # at most one more: a commit whose reply was lost in the stop
            assert ok <= len(batches) <= ok + 1, (len(batches), statuses)
    finally:
        app.state.engine.dispose()
