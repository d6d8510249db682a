"""Sending webhook deliveries in-process (no worker process): one lab's slow receiver does not delay another
lab's delivery; the address a name resolves to is checked and pinned for each request; a delivery whose job
was deleted is never sent."""

from __future__ import annotations

import contextlib
import socket
import threading
import time
from collections.abc import Callable, Iterator
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from typing import Any

import pytest
from fastapi import FastAPI
from fastapi.testclient import TestClient
from sqlalchemy import select

from metairl_cli.keys import create_key
from service.api.app import create_app
from service.jobs import webhooks as webhook_targets
from service.settings import Settings
from service.store.models.webhooks import WebhookDelivery
from tests.service.helpers import add_demonstrations, created, make_task
from worker.webhooks import Deliverer

SLOW_S = 3.0
"""How long the slow receiver takes to answer each delivery."""


@contextlib.contextmanager
def receiver(delay_s: float = 0.0) -> Iterator[tuple[int, list[tuple[float, dict[str, str]]]]]:
    """An HTTP server on a loopback port answering 204 to every POST after `delay_s`: (port, [(arrival time,
    headers)])."""
    got: list[tuple[float, dict[str, str]]] = []

    class Handler(BaseHTTPRequestHandler):
        def do_POST(self) -> None:
            self.rfile.read(int(self.headers["content-length"]))
            time.sleep(delay_s)
            got.append((time.monotonic(), {k.lower(): v for k, v in self.headers.items()}))
            self.send_response(204)
            self.end_headers()

        def log_message(self, *_: Any) -> None:
            pass

    server = ThreadingHTTPServer(("127.0.0.1", 0), Handler)
    server.daemon_threads = True
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    try:
        yield server.server_address[1], got
    finally:
        server.shutdown()
        server.server_close()


@pytest.fixture
def hook_app(settings: Settings, empty_database_url: str) -> Iterator[FastAPI]:
    """The app with loopback webhook targets allowed and short delivery timings, on a database of its own
    (its sending threads write deliveries while the test runs: they must not share the session's SQLite file)."""
    app = create_app(
        settings.model_copy(
            update={
                "database_url": empty_database_url,
                "webhook_allow_private": True,
                "webhook_poll_s": 0.05,
                "webhook_timeout_s": 2 * SLOW_S,
            }
        )
    )
    yield app
    app.state.engine.dispose()


def lab(app: FastAPI, name: str) -> dict[str, str]:
    """Authorization headers of a new lab."""
    with app.state.sessionmaker() as session:
        return {"Authorization": f"Bearer {create_key(session, name)}"}


def cancelled_job(client: TestClient, auth: dict[str, str]) -> str:
    """A queued job of a new task, cancelled at once (its lab's webhooks get ``job.cancelled``); its id."""
    task = make_task(client, auth)
    add_demonstrations(client, auth, task["id"])
    job = created(
        client.post("/v1/jobs", json={"demonstrator_id": task["demonstrator_id"]}, headers=auth), 202
    )
    created(client.post(f"/v1/jobs/{job['id']}/cancel", headers=auth), 202)
    return str(job["id"])


@contextlib.contextmanager
def delivering(app: FastAPI) -> Iterator[Deliverer]:
    """A running `Deliverer` on the app's database and settings, stopped afterwards."""
    deliverer = Deliverer(app.state.sessionmaker, app.state.settings)
    deliverer.start()
    try:
        yield deliverer
    finally:
        deliverer.stop()
        deliverer.join(timeout=10)


def eventually(check: Callable[[], Any], *, timeout: float) -> Any:
    """Call ``check`` until it returns something truthy; fail after ``timeout`` seconds."""
    deadline = time.monotonic() + timeout
    while not (result := check()):
        assert time.monotonic() < deadline, "not within the time allowed"
        time.sleep(0.05)
    return result


def test_a_slow_receiver_of_one_lab_does_not_delay_another_labs_delivery(hook_app: FastAPI) -> None:
    slow_lab, quick_lab = lab(hook_app, "slow-lab"), lab(hook_app, "quick-lab")
    with TestClient(hook_app) as client, receiver(SLOW_S) as (slow_port, _), receiver() as (port, got):
        for k in range(10):
            created(
                client.post(
                    "/v1/webhooks", json={"url": f"http://127.0.0.1:{slow_port}/{k}"}, headers=slow_lab
                )
            )
        created(
            client.post("/v1/webhooks", json={"url": f"http://127.0.0.1:{port}/quick"}, headers=quick_lab)
        )
        cancelled_job(client, slow_lab)
        cancelled_job(client, quick_lab)
        with delivering(hook_app):
            started = time.monotonic()
            arrived = eventually(lambda: got, timeout=4 * SLOW_S)[0][0]
            delay = arrived - started
    assert delay < SLOW_S, f"the quick lab's delivery took {delay:.2f} s behind the slow lab's receiver"


def test_the_address_is_checked_and_pinned_for_each_request(
    settings: Settings, monkeypatch: pytest.MonkeyPatch
) -> None:
    """``hook.test`` rebinds: its first lookup of a send gives the receiver's address (taken as public here),
    any later one 127.0.0.2 (taken as private); the send must connect where the check looked."""
    answers: list[str] = []
    looked_up: list[str] = []
    real = socket.getaddrinfo

    def resolver(host: str, port: Any, *args: Any, **kwargs: Any) -> list[Any]:
        if host != "hook.test":
            return real(host, port, *args, **kwargs)
        looked_up.append(answers[0] if answers else "127.0.0.2")
        address = answers.pop(0) if answers else "127.0.0.2"
        return [(socket.AF_INET, socket.SOCK_STREAM, 6, "", (address, port))]

    monkeypatch.setattr(socket, "getaddrinfo", resolver)
    monkeypatch.setattr(webhook_targets, "private_address", lambda address: address != "127.0.0.1")
    app = create_app(settings.model_copy(update={"webhook_poll_s": 0.05, "webhook_timeout_s": 5.0}))
    auth = lab(app, "pinned-lab")
    try:
        with TestClient(app) as client, receiver() as (port, got):
            answers[:] = ["127.0.0.1"]
            hook = created(
                client.post("/v1/webhooks", json={"url": f"http://hook.test:{port}/h"}, headers=auth)
            )
            answers[:] = ["127.0.0.1"]
            looked_up.clear()
            delivered_job = cancelled_job(client, auth)
            with delivering(app):
                headers = eventually(lambda: got, timeout=10)[0][1]
            assert headers["host"] == f"hook.test:{port}" and looked_up == ["127.0.0.1"]

            refused_job = cancelled_job(client, auth)  # the name now resolves to a refused address only
            with delivering(app):
                deliveries = eventually(
                    lambda: [
                        d
                        for d in created(client.get(f"/v1/webhooks/{hook['id']}", headers=auth), 200)[
                            "deliveries"
                        ]
                        if d["job_id"] == refused_job and d["attempts"]
                    ],
                    timeout=10,
                )
            assert (
                "special-use" in deliveries[0]["last_error"]
                and len(got) == 1
                and delivered_job != refused_job
            )
    finally:
        app.state.engine.dispose()


def test_a_deleted_jobs_pending_delivery_is_never_sent(hook_app: FastAPI) -> None:
    auth = lab(hook_app, "deleting-lab")
    with TestClient(hook_app) as client, receiver() as (port, got):
        created(client.post("/v1/webhooks", json={"url": f"http://127.0.0.1:{port}/h"}, headers=auth))
        job_id = cancelled_job(client, auth)
        assert client.delete(f"/v1/jobs/{job_id}", headers=auth).status_code == 204
        with hook_app.state.sessionmaker() as session:
            assert (
                session.execute(select(WebhookDelivery).where(WebhookDelivery.job_id == job_id)).first()
                is None
            )
        with delivering(hook_app):
            time.sleep(0.5)
    assert got == []
