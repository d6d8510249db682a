"""Webhooks sent by a real worker to a real HTTP receiver: signed per the Standard Webhooks spec (verified
with the `standardwebhooks` package), and retried with backoff while the receiver is down."""

from __future__ import annotations

import contextlib
import json
import secrets
import threading
import time
from collections.abc import Callable, Iterator
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path
from typing import Any

import pytest
from fastapi.testclient import TestClient
from standardwebhooks import Webhook as Verifier

from metairl_cli.keys import create_key
from service.api.app import create_app
from service.settings import Settings
from tests.jobs.conftest import FAST, Workers
from tests.jobs.helpers import ENDLESS, QUICK, demonstrated_tasks, ring_tasks, submit, wait_for
from tests.served import free_port
from tests.service.helpers import created

pytestmark = [pytest.mark.worker, pytest.mark.slow]


class Received:
    """What a receiver got: (headers, body) per request."""

    def __init__(self) -> None:
        self.requests: list[tuple[dict[str, str], bytes]] = []
        self.lock = threading.Lock()


@contextlib.contextmanager
def receiver(port: int) -> Iterator[Received]:
    """An HTTP server on 127.0.0.1:``port`` (a thread) answering 204 to every POST and recording it."""
    got = Received()

    class Handler(BaseHTTPRequestHandler):
        def do_POST(self) -> None:
            body = self.rfile.read(int(self.headers["content-length"]))
            with got.lock:
                got.requests.append(({k.lower(): v for k, v in self.headers.items()}, body))
            self.send_response(204)
            self.end_headers()

        def log_message(self, *_: Any) -> None:
            pass

    server = ThreadingHTTPServer(("127.0.0.1", port), Handler)
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    try:
        yield got
    finally:
        server.shutdown()
        server.server_close()


@pytest.fixture(scope="module")
def hooked(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[TestClient, dict[str, str]]]:
    """The embedded backend with one real worker, loopback webhooks allowed and quick retries."""
    root = tmp_path_factory.mktemp("webhooks")
    settings = Settings(
        data_dir=root / "var",
        queue_name=f"metairl-hooks-{secrets.token_hex(4)}",
        webhook_allow_private=True,
        webhook_poll_s=0.2,
        webhook_backoff_s=0.5,
        webhook_timeout_s=2.0,
        **FAST,  # type: ignore[arg-type]
    )
    workers = Workers(settings, Path(root))
    app = create_app(settings)
    try:
        with TestClient(app) as client, app.state.sessionmaker() as session:
            auth = {"Authorization": f"Bearer {create_key(session, f'hooks-{secrets.token_hex(3)}')}"}
            workers.start()
            yield client, auth
    finally:
        workers.kill_all()
        app.state.engine.dispose()


def eventually(check: Callable[[], Any], *, timeout: float = 60.0) -> Any:
    """Call ``check`` until it returns something truthy; fail after ``timeout`` seconds."""
    deadline = time.monotonic() + timeout
    while not (result := check()):
        assert time.monotonic() < deadline, "not within the time allowed"
        time.sleep(0.2)
    return result


def test_a_finished_job_is_delivered_signed(hooked: tuple[TestClient, dict[str, str]]) -> None:
    client, auth = hooked
    port = free_port()
    with receiver(port) as got:
        hook = created(
            client.post(
                "/v1/webhooks",
                json={"url": f"http://127.0.0.1:{port}/hook", "events": ["job.succeeded"]},
                headers=auth,
            )
        )
        demonstrator_id, _ = demonstrated_tasks(client, auth, n_tasks=1)
        job = wait_for(client, auth, submit(client, auth, demonstrator_id, QUICK)["id"])
        assert job["status"] == "succeeded"
        eventually(lambda: got.requests)
        time.sleep(0.5)  # nothing else arrives
        [(headers, body)] = got.requests
    payload = Verifier(hook["secret"]).verify(body, headers)
    assert payload["type"] == "job.succeeded" and payload["data"]["id"] == job["id"]
    assert payload["data"]["status"] == "succeeded" and payload["data"]["best_step"] == job["best_step"]
    assert headers["webhook-signature"].startswith("v1,") and headers["content-type"] == "application/json"
    [delivery] = created(client.get(f"/v1/webhooks/{hook['id']}", headers=auth), 200)["deliveries"]
    assert delivery["id"] == headers["webhook-id"]
    assert (
        delivery["status"],
        delivery["attempts"],
        delivery["last_status_code"],
        delivery["last_error"],
    ) == (
        "delivered",
        1,
        204,
        None,
    )
    assert json.loads(body)["data"] == created(client.get(f"/v1/jobs/{job['id']}", headers=auth), 200) | {
        "updated_at": json.loads(body)["data"]["updated_at"]
    }


def test_a_receiver_that_is_down_gets_the_event_once_it_is_up(
    hooked: tuple[TestClient, dict[str, str]],
) -> None:
    client, auth = hooked
    port = free_port()  # nothing listens here yet
    hook = created(client.post("/v1/webhooks", json={"url": f"http://127.0.0.1:{port}/hook"}, headers=auth))
    demonstrator_id, _ = ring_tasks(client, auth)
    job = submit(client, auth, demonstrator_id, ENDLESS)  # long enough to be cancelled before it ends
    created(client.post(f"/v1/jobs/{job['id']}/cancel", headers=auth), 202)
    wait_for(client, auth, job["id"])

    def failed_twice() -> dict[str, Any] | None:
        deliveries = created(client.get(f"/v1/webhooks/{hook['id']}", headers=auth), 200)["deliveries"]
        return deliveries[0] if deliveries and deliveries[0]["attempts"] >= 2 else None

    down = eventually(failed_twice)
    assert down["status"] == "pending" and down["type"] == "job.cancelled"
    assert down["last_status_code"] is None and "Connect" in down["last_error"]
    assert down["next_attempt_at"] > down["last_attempt_at"]

    with receiver(port) as got:
        eventually(lambda: got.requests, timeout=30)
        delivered = eventually(
            lambda: [
                d
                for d in created(client.get(f"/v1/webhooks/{hook['id']}", headers=auth), 200)["deliveries"]
                if d["status"] == "delivered"
            ]
        )[0]
        headers, body = got.requests[0]
    assert delivered["attempts"] >= 3 and delivered["last_error"] is None
    payload = Verifier(hook["secret"]).verify(body, headers)
    assert (payload["type"], payload["data"]["id"], payload["data"]["status"]) == (
        "job.cancelled",
        job["id"],
        "cancelled",
    )
