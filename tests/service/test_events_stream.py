"""`GET /v1/jobs/{id}/events` as Server-Sent Events: replay and end, resume with Last-Event-ID, other labs, keep-alive,
slots, and the end of a stream when its API process shuts down."""

from __future__ import annotations

import contextlib
import json
import os
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import httpx
import pytest
from fastapi import FastAPI
from fastapi.testclient import TestClient

from service.api.app import create_app
from service.jobs.transitions import claim, transition
from service.settings import Settings
from service.store.models.base import utcnow
from service.store.models.job_status import JobStatus
from service.store.models.jobs import JobEvent
from tests.served import free_port
from tests.service.helpers import created, queued_job
from tests.service.live import serving

SSE = {"Accept": "text/event-stream"}
REPO = Path(__file__).resolve().parents[2]


def finished_job(app: FastAPI, client: TestClient, auth: dict[str, str]) -> str:
    """A job that was claimed, reported two progress points and succeeded (written as the worker would)."""
    job_id = queued_job(client, auth)
    with app.state.sessionmaker() as session:
        attempt = claim(session, job_id)
        assert attempt == 1
        for step in (10, 20):
            progress = {"step": step, "max_steps": 20, "loss": 1.0 / step, "irl_loss": 1.0 / step}
            session.add(
                JobEvent(
                    job_id=job_id,
                    at=utcnow(),
                    kind="progress",
                    attempt=attempt,
                    **progress,
                    sharing_loss=0.0,
                    elapsed_s=0.1 * step,
                )
            )
        transition(session, job_id, JobStatus.RUNNING, JobStatus.SUCCEEDED, message="finished after 20 steps")
        session.commit()
    return job_id


def parse_sse(text: str) -> list[dict[str, Any]]:
    """The messages of an SSE body: each with its ``id``, ``event`` and parsed ``data`` (comments dropped)."""
    messages = []
    for block in text.split("\n\n"):
        fields: dict[str, Any] = {}
        for line in block.splitlines():
            if not line or line.startswith(":"):
                continue
            name, _, value = line.partition(":")
            fields[name] = value.removeprefix(" ")
        if "data" in fields:
            fields["data"] = json.loads(fields["data"])
            messages.append(fields)
    return messages


def test_a_finished_jobs_stream_replays_every_event_and_ends(
    app: FastAPI, client: TestClient, auth: dict[str, str]
) -> None:
    job_id = finished_job(app, client, auth)
    response = client.get(f"/v1/jobs/{job_id}/events", headers=auth | SSE)
    assert response.status_code == 200, response.text
    assert response.headers["content-type"].startswith("text/event-stream")
    assert "retry: " in response.text
    messages = parse_sse(response.text)
    kinds = [(m["event"], m["data"].get("status"), m["data"].get("step")) for m in messages]
    assert kinds == [
        ("status", "queued", None),
        ("status", "running", None),
        ("progress", None, 10),
        ("progress", None, 20),
        ("status", "succeeded", None),
    ]
    assert [int(m["id"]) for m in messages] == [m["data"]["id"] for m in messages]
    # The same events as the JSON list, which stays the default without the Accept header.
    listed = created(client.get(f"/v1/jobs/{job_id}/events", headers=auth), 200)["data"]
    assert [e["id"] for e in listed] == [m["data"]["id"] for m in messages]
    assert messages[1]["data"] == {k: v for k, v in listed[1].items() if v is not None}


def test_last_event_id_resumes_after_that_event(
    app: FastAPI, client: TestClient, auth: dict[str, str]
) -> None:
    job_id = finished_job(app, client, auth)
    every = parse_sse(client.get(f"/v1/jobs/{job_id}/events", headers=auth | SSE).text)
    first_progress = next(m for m in every if m["event"] == "progress")
    resumed = client.get(
        f"/v1/jobs/{job_id}/events", headers=auth | SSE | {"Last-Event-ID": first_progress["id"]}
    )
    rest = parse_sse(resumed.text)
    assert [m["id"] for m in rest] == [m["id"] for m in every if int(m["id"]) > int(first_progress["id"])]
    assert rest[0]["event"] == "progress" and rest[-1]["data"]["status"] == "succeeded"
    # After the terminal event there is nothing left: the stream ends at once, empty.
    after_end = client.get(
        f"/v1/jobs/{job_id}/events", headers=auth | SSE | {"Last-Event-ID": every[-1]["id"]}
    )
    assert after_end.status_code == 200 and parse_sse(after_end.text) == []


def test_another_labs_job_stream_is_404(
    app: FastAPI, client: TestClient, auth: dict[str, str], auth_b: dict[str, str]
) -> None:
    job_id = finished_job(app, client, auth)
    response = client.get(f"/v1/jobs/{job_id}/events", headers=auth_b | SSE)
    assert response.status_code == 404
    assert response.headers["content-type"].startswith("application/problem+json")


def test_a_running_jobs_stream_delivers_new_events_and_ends_at_the_final_status(
    app: FastAPI, client: TestClient, auth: dict[str, str]
) -> None:
    """The stream stays open on a running job and ends once a later write finishes it."""
    import threading
    import time

    job_id = queued_job(client, auth)

    def finish_later() -> None:
        time.sleep(1.0)
        with app.state.sessionmaker() as session:
            claim(session, job_id)
            session.commit()
        time.sleep(0.5)
        with app.state.sessionmaker() as session:
            transition(
                session, job_id, JobStatus.RUNNING, JobStatus.CANCELLED, message="cancelled on request"
            )
            session.commit()

    writer = threading.Thread(target=finish_later)
    writer.start()
    started = time.monotonic()
    messages = parse_sse(client.get(f"/v1/jobs/{job_id}/events", headers=auth | SSE).text)
    writer.join()
    assert time.monotonic() - started >= 1.0
    assert [m["data"]["status"] for m in messages] == ["queued", "running", "cancelled"]


def test_client_wait_follows_the_stream_and_falls_back_to_polling(
    app: FastAPI, client: TestClient, auth: dict[str, str]
) -> None:
    import io
    import threading
    import time

    import httpx

    from metairl_client import Client

    job_id = queued_job(client, auth)

    def finish_later() -> None:
        time.sleep(1.0)
        with app.state.sessionmaker() as session:
            attempt = claim(session, job_id)
            session.add(
                JobEvent(
                    job_id=job_id,
                    at=utcnow(),
                    kind="progress",
                    attempt=attempt,
                    step=5,
                    max_steps=10,
                    loss=1.0,
                    irl_loss=1.0,
                    sharing_loss=0.0,
                    elapsed_s=0.5,
                )
            )
            session.commit()
        time.sleep(0.5)
        with app.state.sessionmaker() as session:
            transition(
                session, job_id, JobStatus.RUNNING, JobStatus.FAILED, values={"error": "no"}, message="no"
            )
            session.commit()

    requests: list[str] = []
    client.headers.update(auth)
    client.event_hooks["request"].append(lambda r: requests.append(f"{r.method} {r.url.path}"))
    writer = threading.Thread(target=finish_later)
    writer.start()
    bar = io.StringIO()
    state = Client(client).wait(job_id, poll_s=0.1, stream=bar)
    writer.join()
    assert (state.status, state.error) == ("failed", "no")
    assert "5/10" in bar.getvalue()
    # One request for the stream, one before and one after it: no polling.
    assert requests == [f"GET /v1/jobs/{job_id}", f"GET /v1/jobs/{job_id}/events", f"GET /v1/jobs/{job_id}"]

    # A server without the stream (the events route answers JSON) is polled instead.
    polls = iter(["queued", "running", "succeeded"])

    def old_server(request: httpx.Request) -> httpx.Response:
        if request.url.path.endswith("/events"):
            return httpx.Response(200, json={"data": [], "has_more": False, "next_cursor": None})
        return httpx.Response(
            200, json={"id": "job_1", "status": next(polls), "progress": None, "error": None}
        )

    mocked = Client(httpx.Client(transport=httpx.MockTransport(old_server), base_url="http://metairl.test"))
    assert mocked.wait("job_1", poll_s=0.01, progress=False).status == "succeeded"


def test_client_wait_on_a_running_job_does_not_draw_the_history_its_snapshot_already_shows() -> None:
    from metairl_client import JobState

    snapshot = JobState(
        "job_x", "running", 337, 1000, None, attempt=2, updated_at=datetime(2026, 1, 5, 10, 5, tzinfo=UTC)
    )
    before, after = "2026-01-05T10:04:59Z", "2026-01-05T10:05:01Z"
    history: list[tuple[str, dict[str, Any]]] = [
        ("status", {"attempt": 1, "status": "running", "at": after}),  # an earlier attempt
        ("progress", {"attempt": 1, "step": 900}),
        ("status", {"attempt": 2, "status": "queued", "at": before}),  # this attempt, before the snapshot
        ("progress", {"attempt": 2, "step": 12}),
        ("progress", {"attempt": 2, "step": 337}),
    ]
    assert all(snapshot.already_shows(kind, data) for kind, data in history)
    news: list[tuple[str, dict[str, Any]]] = [
        ("progress", {"attempt": 2, "step": 338}),
        ("status", {"attempt": 2, "status": "succeeded", "at": after}),
        ("status", {"attempt": 3, "status": "running", "at": after}),  # a retry after this snapshot
        ("progress", {"attempt": 3, "step": 1}),
    ]
    assert not any(snapshot.already_shows(kind, data) for kind, data in news)


def running_job(app: FastAPI, client: TestClient, auth: dict[str, str]) -> str:
    """A job a worker claimed and that has not ended (its stream stays open)."""
    job_id = queued_job(client, auth)
    with app.state.sessionmaker() as session:
        claim(session, job_id)
        session.commit()
    return str(job_id)


@contextlib.contextmanager
def small_pool_app(settings: Settings, **overrides: Any) -> Iterator[FastAPI]:
    """The app on a PostgreSQL pool of 2 connections (no overflow) waited for at most 2 s, polling fast."""
    values = {"db_pool_size": 2, "db_max_overflow": 0, "db_pool_timeout_s": 2.0, "events_poll_s": 0.1}
    app = create_app(settings.model_copy(update=values | overrides))
    try:
        yield app
    finally:
        app.state.engine.dispose()


@contextlib.contextmanager
def open_streams(
    http: httpx.Client, url: str, n: int, auth: dict[str, str]
) -> Iterator[list[httpx.Response]]:
    """`n` event streams of `url` held open (their headers received) until the block ends."""
    with contextlib.ExitStack() as stack:
        yield [stack.enter_context(http.stream("GET", url, headers=auth | SSE)) for _ in range(n)]


def test_open_event_streams_hold_no_database_connection(
    backend: str, settings: Settings, api_key: str
) -> None:
    if backend != "postgres":
        pytest.skip("the connection pool is PostgreSQL's")
    auth = {"Authorization": f"Bearer {api_key}"}
    with small_pool_app(settings) as app, TestClient(app) as client:
        job_id = running_job(app, client, auth)
        with (
            serving(app) as url,
            httpx.Client(base_url=url, timeout=10) as http,
            open_streams(http, f"/v1/jobs/{job_id}/events", 6, auth) as streams,
        ):
            assert [s.status_code for s in streams] == [200] * 6
            for _ in range(5):
                started = time.monotonic()
                assert http.get("/v1/mdps", headers=auth).status_code == 200
                assert time.monotonic() - started < 1.0


def test_a_key_holds_at_most_the_configured_number_of_streams(
    settings: Settings, api_key: str, api_key_b: str
) -> None:
    auth, auth_b = {"Authorization": f"Bearer {api_key}"}, {"Authorization": f"Bearer {api_key_b}"}
    app = create_app(settings.model_copy(update={"events_max_streams_per_key": 2, "events_poll_s": 0.1}))
    try:
        with TestClient(app) as client:
            job_id = running_job(app, client, auth)
            other_job = running_job(app, client, auth_b)
            with serving(app) as url, httpx.Client(base_url=url, timeout=10) as http:
                path = f"/v1/jobs/{job_id}/events"
                with open_streams(http, path, 2, auth):
                    refused = http.get(path, headers=auth | SSE)
                    assert refused.status_code == 429 and int(refused.headers["retry-after"]) >= 1
                    assert "METAIRL_EVENTS_MAX_STREAMS_PER_KEY" in refused.json()["detail"]
                    with open_streams(http, f"/v1/jobs/{other_job}/events", 1, auth_b) as other:
                        assert other[0].status_code == 200
                deadline = time.monotonic() + 10
                while True:  # the closed streams give their slots back once the server notices
                    with http.stream("GET", path, headers=auth | SSE) as again:
                        if again.status_code == 200:
                            break
                    assert time.monotonic() < deadline, "the closed streams' slots were not given back"
                    time.sleep(0.1)
    finally:
        app.state.engine.dispose()


def test_a_request_finding_every_connection_busy_is_503(
    backend: str, settings: Settings, api_key: str
) -> None:
    if backend != "postgres":
        pytest.skip("the connection pool is PostgreSQL's")
    auth = {"Authorization": f"Bearer {api_key}"}
    with small_pool_app(settings, db_pool_timeout_s=0.5) as app, TestClient(app) as client:
        with app.state.engine.connect(), app.state.engine.connect():
            response = client.get("/v1/mdps", headers=auth)
        assert response.status_code == 503 and response.headers["retry-after"] == "1"
        assert response.headers["content-type"].startswith("application/problem+json")
        assert client.get("/v1/mdps", headers=auth).status_code == 200


def test_a_quiet_stream_sends_keep_alive_comments_and_ends_after_its_longest_time(
    settings: Settings, api_key: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A running job's stream stays open without events, with comment lines, until ``events_stream_max_s``."""
    monkeypatch.setattr("service.api.sse.KEEPALIVE_S", 0.2)
    auth = {"Authorization": f"Bearer {api_key}"}
    app = create_app(settings.model_copy(update={"events_stream_max_s": 1.0, "events_poll_s": 0.1}))
    try:
        with TestClient(app) as client:
            job_id = running_job(app, client, auth)
            started = time.monotonic()
            response = client.get(f"/v1/jobs/{job_id}/events", headers=auth | SSE)
            took = time.monotonic() - started
    finally:
        app.state.engine.dispose()
    assert response.status_code == 200 and 1.0 <= took < 5.0
    assert response.text.count(": keep-alive\n\n") >= 3
    assert [m["data"]["status"] for m in parse_sse(response.text)] == ["queued", "running"]


def test_an_api_process_shutting_down_ends_its_open_streams_complete_and_exits_at_once(
    app: FastAPI, client: TestClient, auth: dict[str, str], settings: Settings
) -> None:
    job_id = running_job(app, client, auth)
    port = free_port()
    env = os.environ | {
        "METAIRL_DATABASE_URL": settings.resolved_database_url,
        "METAIRL_DATA_DIR": str(settings.data_dir),
    }
    command = [
        "uvicorn",
        "--factory",
        "service.api.app:create_app",
        "--port",
        str(port),
        "--log-level",
        "warning",
    ]
    server = subprocess.Popen([sys.executable, "-m", *command], cwd=REPO, env=env)
    try:
        url = f"http://127.0.0.1:{port}"
        deadline = time.monotonic() + 30
        while server.poll() is None and time.monotonic() < deadline:
            with contextlib.suppress(httpx.TransportError):
                if httpx.get(f"{url}/healthz").status_code == 200:
                    break
            time.sleep(0.1)
        with httpx.stream("GET", f"{url}/v1/jobs/{job_id}/events", headers=auth | SSE, timeout=5) as stream:
            lines = stream.iter_lines()
            assert next(lines) == "retry: 2000"  # the stream is open
            server.send_signal(signal.SIGTERM)
            sent = time.monotonic()
            rest = list(lines)  # a body cut off, or a stream left open past the timeout, raises here
        server.wait(timeout=10)
        assert time.monotonic() - sent < 5
        assert [m["data"]["status"] for m in parse_sse("\n".join(rest))] == ["queued", "running"]
    finally:
        if server.poll() is None:
            server.kill()
