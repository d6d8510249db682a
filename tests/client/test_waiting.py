"""`wait` on both clients: follows the event stream, resumes after a drop with ``Last-Event-ID``, draws a bar."""

from __future__ import annotations

import asyncio
import io
import json
import time
from collections.abc import AsyncIterator, Iterator
from typing import Any

import httpx
import pytest

from metairl_client import AsyncClient, Client, JobState, NotFoundError, _waiting
from metairl_client._waiting import LAST_STRETCH_S, Waiter

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


def keep_alives(*, asynchronous: bool, every_s: float = 0.02, for_s: float = 3.0) -> Any:
    """A quiet stream's body: a retry hint, then a keep-alive comment every ``every_s`` for ``for_s``."""
    chunks = [b"retry: 1000\n\n"] + [b": keep-alive\n\n"] * round(for_s / every_s)

    def body() -> Iterator[bytes]:
        for chunk in chunks:
            time.sleep(every_s)
            yield chunk

    async def abody() -> AsyncIterator[bytes]:
        for chunk in chunks:
            await asyncio.sleep(every_s)
            yield chunk

    return abody() if asynchronous else body()


class QueuedServer:
    """A job that stays queued: its stream sends keep-alives only (or is refused with ``stream_status``)."""

    def __init__(
        self, *, asynchronous: bool, stream_status: int = 200, finish_after_polls: int | None = None
    ):
        self.asynchronous, self.stream_status = asynchronous, stream_status
        self.finish_after_polls = finish_after_polls
        self.stream_timeouts: list[dict[str, float | None]] = []
        self.polls = 0

    def __call__(self, request: httpx.Request) -> httpx.Response:
        if request.url.path.endswith("/events"):
            self.stream_timeouts.append(request.extensions["timeout"])
            if self.stream_status != 200:
                return httpx.Response(
                    self.stream_status, json={"status": self.stream_status, "title": "Busy"}
                )
            content = keep_alives(asynchronous=self.asynchronous)
            return httpx.Response(200, content=content, headers={"content-type": "text/event-stream"})
        self.polls += 1
        done = self.finish_after_polls is not None and self.polls > self.finish_after_polls
        return httpx.Response(200, json=job("succeeded", 10) if done else job("queued"))


def run_wait(server: QueuedServer, *, timeout: float = 60.0, **options: Any) -> JobState:
    """``wait`` of the client kind the server serves, with ``options``; the clients' timeout ``timeout``."""
    if server.asynchronous:

        async def run() -> JobState:
            http = httpx.AsyncClient(transport=httpx.MockTransport(server), base_url=BASE, timeout=timeout)
            async with AsyncClient(http) as lab:
                return await lab.wait("job_1", progress=False, **options)

        return asyncio.run(run())
    http = httpx.Client(transport=httpx.MockTransport(server), base_url=BASE, timeout=timeout)
    with Client(http) as lab:
        return lab.wait("job_1", progress=False, **options)


@pytest.mark.parametrize("asynchronous", [False, True], ids=["sync", "async"])
@pytest.mark.parametrize("last_stretch_s", [0.0, LAST_STRETCH_S], ids=["streaming", "polling-at-the-end"])
def test_wait_raises_at_its_timeout_while_the_stream_sends_only_keep_alives(
    asynchronous: bool, last_stretch_s: float, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(_waiting, "LAST_STRETCH_S", last_stretch_s)
    server = QueuedServer(asynchronous=asynchronous)
    started = time.monotonic()
    with pytest.raises(TimeoutError, match=r"job_1 is still queued after 0\.3 s"):
        run_wait(server, timeout_s=0.3, poll_s=0.05)
    assert time.monotonic() - started < 1.5  # the stream would have kept it for 3 s


@pytest.mark.parametrize("asynchronous", [False, True], ids=["sync", "async"])
def test_the_stream_read_timeout_is_cut_to_the_time_left(
    asynchronous: bool, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(_waiting, "LAST_STRETCH_S", 0.0)
    server = QueuedServer(asynchronous=asynchronous)
    with pytest.raises(TimeoutError):
        run_wait(server, timeout=60.0, timeout_s=0.2)
    first = server.stream_timeouts[0]
    assert first["read"] is not None and 0 < first["read"] <= 0.2
    assert first["connect"] == 60.0  # the rest of the client's timeout is kept


def test_the_stream_follows_the_timeout_of_with_options(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(_waiting, "LAST_STRETCH_S", 0.0)
    server = QueuedServer(asynchronous=False)
    http = httpx.Client(transport=httpx.MockTransport(server), base_url=BASE, timeout=60.0)
    with Client(http) as lab, pytest.raises(TimeoutError):
        lab.with_options(timeout_s=5.0).wait("job_1", progress=False, timeout_s=0.2)
    assert server.stream_timeouts[0]["connect"] == 5.0


@pytest.mark.parametrize("asynchronous", [False, True], ids=["sync", "async"])
@pytest.mark.parametrize("status", [429, 503])
def test_a_refused_stream_falls_back_to_polling(asynchronous: bool, status: int) -> None:
    server = QueuedServer(asynchronous=asynchronous, stream_status=status, finish_after_polls=2)
    state = run_wait(server, poll_s=0.01)
    assert state.status == "succeeded" and len(server.stream_timeouts) == 1 and server.polls == 3


def test_a_stream_refused_for_another_reason_raises_its_error() -> None:
    server = QueuedServer(asynchronous=False, stream_status=404)
    with pytest.raises(NotFoundError):
        run_wait(server)


def test_the_bar_clock_runs_from_the_start_of_the_wait() -> None:
    bar = io.StringIO()
    with Waiter("job_1", timeout_s=None, progress=True, stream=bar) as waiter:
        waiter.show(JobState.from_json(job("queued")))
        time.sleep(0.05)
        waiter.show(JobState.from_json(job("running", 5)))
        # The first step count arrives with its total: the bar's rate is over the whole wait, not over the
        # instant since the total became known (thousands of steps per second).
        assert waiter.bar.format_dict["elapsed"] >= 0.05 and waiter.bar.total == 10
    assert "5/10" in bar.getvalue()


def test_the_bar_of_a_fit_that_stopped_early_ends_full() -> None:
    bar = io.StringIO()
    with Waiter("job_1", timeout_s=None, progress=True, stream=bar) as waiter:
        waiter.show(JobState.from_json(job("running", 4)))
        waiter.show(JobState.from_json(job("succeeded", 4)))  # 4 of max_steps 10: the fit converged
    assert "4/10" in bar.getvalue() and "100%" in bar.getvalue().splitlines()[-1].split("\r")[-1]
