"""A broker restart that loses a queued job's message: the job is sent again and runs.

The test starts its own ``redis-server`` (no persistence, a free port) so that it can restart it without
touching the machine's shared Redis; the worker is a real ``metairl worker`` process.
"""

from __future__ import annotations

import secrets
import shutil
import subprocess
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
import redis
from fastapi.testclient import TestClient

from metairl_cli.keys import create_key
from service.api.app import create_app
from service.jobs.queue import CeleryJobQueue
from service.settings import Settings
from tests.jobs.conftest import FAST, Workers
from tests.jobs.helpers import QUICK, all_events, demonstrated_tasks, submit, wait_for
from tests.served import free_port
from worker.reaper import RESENT

pytestmark = [pytest.mark.redis, pytest.mark.worker, pytest.mark.slow]


class RedisServer:
    """A ``redis-server`` of this test's own, on a free port, that keeps nothing across a restart."""

    def __init__(self, folder: Path):
        self.folder, self.port = folder, free_port()
        self.url = f"redis://127.0.0.1:{self.port}/0"
        self.process: subprocess.Popen[bytes] | None = None

    def start(self) -> None:
        """Start it and wait until it answers PING."""
        self.process = subprocess.Popen(
            [
                "redis-server",
                "--port",
                str(self.port),
                "--bind",
                "127.0.0.1",
                "--save",
                "",
                "--appendonly",
                "no",
            ],
            cwd=self.folder,
            stdout=subprocess.DEVNULL,
        )
        deadline = time.monotonic() + 10
        while True:
            try:
                if redis.Redis(port=self.port).ping():
                    return
            except redis.ConnectionError:
                assert time.monotonic() < deadline, "own redis-server did not answer in 10 s"
                time.sleep(0.05)

    def stop(self) -> None:
        """Stop it (SIGTERM); what it held is gone."""
        if self.process is not None:
            self.process.terminate()
            self.process.wait(timeout=10)
            self.process = None


@pytest.fixture
def own_redis(tmp_path: Path) -> Iterator[RedisServer]:
    """A running redis-server of the test's own; stopped at the end."""
    if shutil.which("redis-server") is None:
        pytest.skip("no redis-server on PATH")
    server = RedisServer(tmp_path)
    server.start()
    try:
        yield server
    finally:
        server.stop()


def test_job_whose_message_a_redis_restart_lost_is_sent_again_and_runs(
    tmp_path: Path, own_redis: RedisServer
) -> None:
    settings = Settings(
        data_dir=tmp_path / "var",
        broker_url=own_redis.url,
        queue_name=f"metairl-test-{secrets.token_hex(4)}",
        **FAST,  # type: ignore[arg-type]
    )
    app = create_app(settings)
    workers = Workers(settings, tmp_path)
    try:
        with TestClient(app) as client, app.state.sessionmaker() as session:
            auth = {"Authorization": f"Bearer {create_key(session, 'restart')}"}
            demonstrator_id, _ = demonstrated_tasks(client, auth, 1)
            job_id = submit(client, auth, demonstrator_id, QUICK)["id"]
            queue = CeleryJobQueue(settings)
            assert queue.waiting() == 1  # no worker yet: the message waits in Redis

            own_redis.stop()
            own_redis.start()  # a restart without persistence: the message is lost
            assert queue.waiting() == 0

            workers.start()  # its reaper finds the job queued with an empty queue and sends it again
            job = wait_for(client, auth, job_id, timeout=60)
            assert job["status"] == "succeeded" and job["attempts"] == 1
            resent = [e for e in all_events(client, auth, job_id) if (e["message"] or "").startswith(RESENT)]
            assert len(resent) == 1
    finally:
        workers.kill_all()
        app.state.engine.dispose()
