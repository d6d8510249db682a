"""`wait` on both clients: follows the event stream, resumes after a drop with ``Last-Event-ID``, draws a bar."""

from __future__ import annotations

import asyncio
import io
import json
from typing import Any

import httpx
import pytest

from metairl_client import AsyncClient, Client, JobState

BASE = "http://metairl.test"
AT = "2026-01-05T10:05:0{}Z"


def job(status: str, step: int | None = None) -> dict[str, Any]:
    """A job resource of attempt 1."""
    progress = {"step": step, "max_steps": 10} if step is not None else None
    return {
        "id": "job_1",
        "status": status,
        "progress": progress,
        "error": None,
        "attempts": 1,
        "updated_at": AT.format(0),
    }


def sse(*events: tuple[int, str, dict[str, Any]]) -> httpx.Response:
    """An event-stream answer of (id, name, data) messages, with a keep-alive comment and a retry hint."""
    text = ": keep-alive\n\nretry: 1000\n\n" + "".join(
        f"id: {i}\nevent: {name}\ndata: {json.dumps(data)}\n\n" for i, name, data in events
    )
    return httpx.Response(200, text=text, headers={"content-type": "text/event-stream"})


class Server:
    """A job that runs to step 4, then the stream drops; the resumed stream brings step 8 and success."""

    def __init__(self) -> None:
        self.streams: list[str | None] = []
        self.done = False

    def __call__(self, request: httpx.Request) -> httpx.Response:
        if request.url.path.endswith("/events"):
            self.streams.append(request.headers.get("Last-Event-ID"))
            if len(self.streams) == 1:
                return sse(
                    (1, "status", {"attempt": 1, "status": "running", "at": AT.format(1)}),
                    (2, "progress", {"attempt": 1, "step": 4, "max_steps": 10}),
                )
            self.done = True
            return sse(
                (3, "progress", {"attempt": 1, "step": 8, "max_steps": 10}),
                (4, "status", {"attempt": 1, "status": "succeeded", "at": AT.format(2)}),
            )
        return httpx.Response(200, json=job("succeeded", 10) if self.done else job("running", 4))


def wait_sync(server: Server, bar: io.StringIO) -> JobState:
    """`Client.wait` against the server."""
    with Client(httpx.Client(transport=httpx.MockTransport(server), base_url=BASE)) as lab:
        return lab.wait("job_1", stream=bar)


def wait_async(server: Server, bar: io.StringIO) -> JobState:
    """`AsyncClient.wait` against the server."""

    async def run() -> JobState:
        async with AsyncClient(
            httpx.AsyncClient(transport=httpx.MockTransport(server), base_url=BASE)
        ) as lab:
            return await lab.wait("job_1", stream=bar)

    return asyncio.run(run())


@pytest.mark.parametrize("wait", [wait_sync, wait_async], ids=["sync", "async"])
def test_wait_follows_the_stream_and_resumes_after_the_last_event(wait: Any) -> None:
    server, bar = Server(), io.StringIO()
    state = wait(server, bar)
    assert (state.status, state.step) == ("succeeded", 10)
    assert server.streams == [None, "2"]
    assert "job_1 running" in bar.getvalue() and "8/10" in bar.getvalue()
